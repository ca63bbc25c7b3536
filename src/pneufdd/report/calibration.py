"""HTML report of a calibration: parameters, before/after table and figure against the data."""

from __future__ import annotations

import base64
import html
import math

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from pneufdd import __version__
from pneufdd.calibration.calibrate import CalibrationResult, Evidence
from pneufdd.report.figures import to_png
from pneufdd.report.plain_text import plain_text

__all__ = ["calibration_figure", "render_calibration_report"]

_STYLE = """
body{font-family:system-ui,Helvetica,Arial,sans-serif;margin:2em;max-width:1100px;color:#222}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.3em .6em;
text-align:right}th{background:#f0f0f0}td.l,th.l{text-align:left}img{max-width:100%}
.note{color:#7a4b00}
"""


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


def _f(x: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:,.{digits}f}"


@plain_text
def calibration_figure(result: CalibrationResult) -> Figure:
    """Per-step supply air, duration and supply pressure: recordings, before, after."""
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    steps = np.arange(1, result.measured.duration_s.size + 1)
    rows: list[tuple[str, float, str]] = [
        ("supply_air_kg", 1e3 / 1.294, "supply air per step [SL]"),
        ("duration_s", 1e3, "step duration [ms]"),
        ("supply_pressure_pa", 1e-5, "mean P_In [bar abs]"),
    ]
    for ax, (key, scale, label) in zip(axes, rows, strict=True):
        for evidence, style, name in (
            (result.measured, "ko", "recordings"),
            (result.simulated_before, "x", "twin before"),
            (result.simulated_after, ".-", "twin after"),
        ):
            values: np.ndarray = getattr(evidence, key)
            ax.plot(steps, values * scale, style, label=name, markersize=4)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("step")
    fig.tight_layout()
    return fig


def _table(m: Evidence, before: Evidence, after: Evidence) -> str:
    head = (
        "<tr><th>step</th><th>air rec [SL]</th><th>before</th><th>after</th>"
        "<th>duration rec [ms]</th><th>before</th><th>after</th>"
        "<th>P_In rec [bar(g)]</th><th>before</th><th>after</th></tr>"
    )
    rows = []
    for j in range(m.duration_s.size):
        cells = [str(j + 1)]
        for e in (m, before, after):
            cells.append(_f(e.supply_air_kg[j] * 1e3 / 1.294, 3))
        for e in (m, before, after):
            cells.append(_f(e.duration_s[j] * 1e3, 0))
        for e in (m, before, after):
            cells.append(_f((e.supply_pressure_pa[j] - 101325.0) / 1e5, 3))
        rows.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    return "<table>" + head + "".join(rows) + "</table>"


def render_calibration_report(result: CalibrationResult, description: str, sources: str) -> str:
    """A self-contained HTML page: what was fitted, how well, and what was not informed."""
    summary = result.fit_summary()
    params = "".join(
        f"<tr><td class='l'>{_e(p.name)}</td><td class='l'>{_e(p.describe())}</td>"
        f"<td>{_f(p.prior_sigma, 2)}</td></tr>"
        for p in result.estimates
    )
    png = base64.b64encode(to_png(calibration_figure(result))).decode("ascii")
    uninformed = ", ".join(result.not_informed) or "none"
    friction = "".join(
        f"<tr><td class='l'>{_e(f.actuator)}</td><td>{f.strokes}</td>"
        f"<td>{_f(f.static_friction_n, 1)} +- {_f(f.static_friction_std_n, 1)}</td>"
        f"<td>{_f(f.coulomb_friction_n, 1)} +- {_f(f.coulomb_friction_std_n, 1)}</td>"
        f"<td>{_f(f.viscous_friction_n_s_m, 1)}"
        f"{'' if f.viscous_fitted else ' (Cvf/Fcf of the description)'}</td></tr>"
        for f in result.friction
    )
    paths = "".join(
        f"<tr><td class='l'>{_e(p.actuator)}</td><td>{_e(', '.join(p.lines))}</td>"
        f"<td>{p.points}</td><td>{_f(p.path_cv, 3)} +- {_f(p.path_cv_std, 3)}</td></tr>"
        for p in result.paths
    )
    paths_section = (
        "<h2>Fill paths identified from the line flows (section 4.2.1, eq. 4.6)</h2>"
        "<p class='note'>Valve and tube in series, from P_In, the line pressure and the "
        "line flow with the zero-flow correction; the twin's valve Cv is set so that, "
        "in series with its tube, it gives this.</p>"
        "<table><tr><th class='l'>actuator</th><th>lines</th><th>samples</th>"
        f"<th>valve + tube Cv</th></tr>{paths}</table>"
        if paths
        else ""
    )
    friction_section = (
        "<h2>Friction identified from the strokes (eqs. 4.15-4.16)</h2>"
        "<p class='note'>Where both line pressures and the position are recorded; at the "
        "areas of the starting description (a fitted size scales them).</p>"
        "<table><tr><th class='l'>actuator</th><th>strokes</th><th>Fsf [N]</th>"
        f"<th>Fcf [N]</th><th>Cvf [N s/m]</th></tr>{friction}</table>"
        if friction
        else ""
    )
    fit_rows = "".join(
        f"<tr><td class='l'>{_e(k)}</td><td>{_f(v, 2)}</td></tr>" for k, v in summary.items()
    ) + "".join(
        f"<tr><td class='l'>weighted misfit, {_e(k.replace('_', ' '))}</td><td>{_f(v, 1)}</td></tr>"
        for k, v in result.weighted_misfit().items()
    )
    return f"""<!DOCTYPE html><html><head><meta charset="utf-8">
<title>pneufdd calibration of {_e(result.before.name)}</title><style>{_STYLE}</style></head><body>
<h1>Calibration of {_e(result.before.name)}</h1>
<p>Starting description: <b>{_e(description)}</b>. Leak-free recordings: {_e(sources)}
({result.measured.cycles} complete cycles). Twin runs: {result.evaluations}.
Weighted misfit (sum of squares) {_f(result.cost_before, 1)} before,
{_f(result.cost_after, 1)} after. pneufdd {_e(__version__)}.</p>
<h2>How well the twin fits</h2><table><tr><th class='l'>median over steps</th><th>value</th></tr>
{fit_rows}</table>
<h2>Parameters</h2>
<p class="note">Not informed by these recordings, left at the description's value:
{_e(uninformed)}.</p>
<table><tr><th class='l'>parameter</th><th class='l'>change (+- 1 standard error)</th>
<th>prior sigma</th></tr>{params}</table>
{friction_section}
{paths_section}
<h2>Per step, recordings against the twin before and after</h2>
<figure><img alt="per-step air, durations and pressures" src="data:image/png;base64,{png}"></figure>
{_table(result.measured, result.simulated_before, result.simulated_after)}
</body></html>
"""
