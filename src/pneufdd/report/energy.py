"""The energy report (``pneufdd energy --report``): self-contained HTML, figures as PNG.

Where the air goes (a stacked bar per actuator, leak and ejector: stroke, dead volume,
tube), the pressure against cycle time and air with the chosen set point, and the
measures ranked by their saving a year. Every text from data is HTML-escaped.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from pneufdd import __version__
from pneufdd.energy.analysis import EnergyAnalysis
from pneufdd.energy.breakdown import AirBreakdown, group_of, kind_of
from pneufdd.energy.changes import bar_g
from pneufdd.energy.pressure import SetPointSearch
from pneufdd.files import write_text_atomic
from pneufdd.report.figures import to_png
from pneufdd.report.html import _STYLE, _e, _fmt, _img
from pneufdd.report.plain_text import plain_text

__all__ = ["breakdown_figure", "pressure_figure", "render_energy_report", "write_energy_report"]

_KIND_COLOURS = {
    "stroke": "#2f6db5",
    "dead volume": "#f0a030",
    "tube": "#9bc2e6",
    "leak": "#d62728",
    "vacuum": "#7f7f7f",
}
_SCRIPT = (
    "<script>window.addEventListener('load',function(){var n=0;"
    "document.querySelectorAll('img').forEach(function(i){if(i.naturalWidth>0){n++;"
    "i.dataset.rendered=i.naturalWidth+'x'+i.naturalHeight;}});"
    "document.body.dataset.figuresRendered=n;});</script>"
)


@plain_text
def breakdown_figure(breakdown: AirBreakdown) -> Figure:
    """Air per cycle of each actuator, leak and ejector, stacked by kind [g]."""
    groups: list[str] = []
    for name in breakdown.components:
        group = group_of(name)
        if group != "storage" and group not in groups:
            groups.append(group)
    groups.sort(key=lambda g: -sum(
        v for c, v in zip(breakdown.components, breakdown.air_kg, strict=True) if group_of(c) == g
    ))  # fmt: skip
    fig, ax = plt.subplots(figsize=(8.0, 0.45 * len(groups) + 1.6))
    left = np.zeros(len(groups))
    for kind, colour in _KIND_COLOURS.items():
        values = np.array(
            [
                sum(
                    1e3 * float(v)
                    for c, v in zip(breakdown.components, breakdown.air_kg, strict=True)
                    if group_of(c) == g and kind_of(c) == kind
                )
                for g in groups
            ]
        )
        if np.any(values > 0):
            ax.barh(groups, values, left=left, color=colour, label=kind)
            left += values
    for y, total in enumerate(left):
        cost = breakdown.money(total * 1e-3).cost
        ax.text(total, y, f" {total:.2f} g  ({cost:,.0f} $/yr)", va="center", fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("air per cycle [g]")
    ax.set_xlim(0, max(float(left.max()), 1e-9) * 1.45)
    title = f"Where the air goes: {breakdown.explained_kg * 1e3:.2f} g per cycle"
    if math.isfinite(breakdown.measured_kg):
        title += (
            f" (meter {breakdown.measured_kg * 1e3:.2f} g, "
            f"twin {breakdown.twin_total_kg * 1e3:.2f} g)"
        )
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


@plain_text
def pressure_figure(search: SetPointSearch) -> Figure:
    """Cycle time and air per cycle against the set point; the chosen point marked."""
    points = [p for p in search.curve if math.isfinite(p.cycle_time_s)]
    fig, ax = plt.subplots(figsize=(8.0, 4.0))
    x = np.array([bar_g(p.psig) for p in points])
    cycle = np.array([p.cycle_time_s for p in points])
    ok = np.array([p.feasible for p in points])
    ax.plot(x, cycle, color="#2f6db5", lw=1.2)
    ax.scatter(x[ok], cycle[ok], color="#2f6db5", label="does the job", zorder=3)
    ax.scatter(x[~ok], cycle[~ok], facecolors="none", edgecolors="#d62728", label="fails", zorder=3)
    best = bar_g(search.min_psig)
    ax.axvline(best, color="#2ca02c", ls="--", lw=1)
    ax.annotate(
        f"lowest: {best:.2f} bar(g)\n{search.best.cycle_time_s:.2f} s",
        (best, search.best.cycle_time_s), textcoords="offset points", xytext=(8, 12), fontsize=8,
    )  # fmt: skip
    ax.axvline(bar_g(search.now_psig), color="#555555", ls=":", lw=1)
    ax.set_xlabel("regulator set point [bar(g)]")
    ax.set_ylabel("cycle time [s]", color="#2f6db5")
    air = ax.twinx()
    air.plot(x, [1e3 * p.supply_kg for p in points], color="#f0a030", marker=".", lw=1)
    air.set_ylabel("air per cycle [g]", color="#f0a030")
    limit = f", limited by {search.limiting_actuator}" if search.limiting_actuator else ""
    ax.set_title(
        f"Set point: now {bar_g(search.now_psig):.2f}, lowest {best:.2f} bar(g){limit}", fontsize=10
    )
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return fig


def _measures_table(analysis: EnergyAnalysis) -> str:
    rows = []
    for i, m in enumerate(analysis.measures, start=1):
        cycle = m.cycle_after_s - m.cycle_before_s
        status = "yes" if m.feasible else "no"
        rows.append(
            f"<tr class='{'ok' if m.feasible else 'leak'}'><td>{i}</td>"
            f"<td class='l'>{_e(m.name)}</td><td>{status}</td>"
            f"<td>{_fmt(m.saving_per_year, 0)}</td><td>{_fmt(m.kwh_per_year, 0)}</td>"
            f"<td>{_fmt(m.saving.air_m3_anr, 0)}</td><td>{_fmt(1e3 * cycle, 0)}</td>"
            f"<td class='l'>{_e(m.what)}</td><td class='l'>{_e(m.reason)}. {_e(m.note)}</td></tr>"
        )
    return (
        "<table id='measures'><tr><th>#</th><th class='l'>measure</th><th>does the job</th>"
        "<th>saving [$/yr]</th><th>energy [kWh/yr]</th><th>air [m&sup3; ANR/yr]</th>"
        "<th>cycle time change [ms]</th><th class='l'>what to change</th>"
        "<th class='l'>the twin's verdict</th></tr>" + "".join(rows) + "</table>"
    )


def _breakdown_table(breakdown: AirBreakdown) -> str:
    rows = []
    total = breakdown.explained_kg
    for name, value, twin in zip(
        breakdown.components, breakdown.air_kg, breakdown.twin_kg, strict=True
    ):
        rows.append(
            f"<tr><td class='l'>{_e(name)}</td><td>{_fmt(1e3 * value, 3)}</td>"
            f"<td>{_fmt(100 * value / total if total else math.nan, 1)}</td>"
            f"<td>{_fmt(1e3 * twin, 3)}</td>"
            f"<td>{_fmt(breakdown.money(float(value)).cost, 0)}</td></tr>"
        )
    standby = breakdown.standby_money
    rows.append(
        "<tr><td class='l'>standby (stopped, air on: "
        f"{_fmt(breakdown.settings.hours_standstill, 0)} h/yr)"
        f"</td><td colspan='3'>{_fmt(1e3 * standby.mass_flow_kg_s, 4)} g/s</td>"
        f"<td>{_fmt(standby.cost, 0)}</td></tr>"
    )
    return (
        "<table id='breakdown'><tr><th class='l'>component</th><th>air [g/cycle]</th>"
        "<th>share [%]</th><th>twin alone [g/cycle]</th><th>cost [$/yr]</th></tr>"
        + "".join(rows)
        + "</table>"
    )


def _leak_list(breakdown: AirBreakdown) -> str:
    items = [f"{k['location']} {k['orifice_mm']:.2f} mm ({k['source']})" for k in breakdown.leaks]
    return ", ".join(items) or "none"


def render_energy_report(analysis: EnergyAnalysis, runs: str = "") -> str:
    """The complete HTML document of an energy analysis."""
    search = analysis.search
    b = analysis.breakdown
    cost = analysis.settings.cost
    headline = (
        f"<div class='verdict ok'>Lowest set point that does the job: "
        f"<span id='min-pressure'>{bar_g(search.min_psig):.2f}</span> bar(g) "
        f"(now {bar_g(search.now_psig):.2f}); limiting actuator: "
        f"<span id='limiting'>{_e(search.limiting_actuator or 'none found')}</span>; "
        f"saving {_fmt(analysis.set_point.saving_per_year, 0)} $/yr</div>"
    )
    measured = (
        f"{_fmt(1e3 * b.measured_kg, 3)} g (meter)" if math.isfinite(b.measured_kg) else "no meter"
    )
    summary = (
        "<table>"
        f"<tr><th class='l'>machine (twin)</th><td class='l'>{_e(analysis.machine.title)}</td></tr>"
        f"<tr><th class='l'>recordings</th><td class='l'>{_e(runs or 'n/a')}</td></tr>"
        f"<tr><th class='l'>cycles, cycle time</th><td class='l'>{b.cycles}, "
        f"{_fmt(b.cycle_time_s, 3)} s</td></tr>"
        f"<tr><th class='l'>supply air per cycle</th><td class='l'>{measured}; twin "
        f"{_fmt(1e3 * b.twin_total_kg, 3)} g; split from the {_e(b.source)}</td></tr>"
        f"<tr><th class='l'>leaks in the twin</th><td class='l'>"
        f"{_e(_leak_list(b))}</td></tr>"
        f"<tr><th class='l'>economics (eq. 1.1)</th><td class='l'>{_fmt(cost.hours, 0)} h/yr, "
        f"{cost.price_per_kwh:g} $/kWh, {cost.kw_per_100_cfm:g} kW per 100 cfm</td></tr>"
        "</table>"
    )
    notes = "".join(f"<p class='note'>{_e(n)}</p>" for n in analysis.notes)
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    title = f"pneufdd energy report: {analysis.machine.name}"
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{_e(title)}</title><style>{_STYLE}</style></head><body>"
        f"<h1>{_e(title)}</h1>{headline}{notes}"
        f"<h2>Where the air goes</h2>"
        f"{_img(to_png(breakdown_figure(b)), 'air per cycle by actuator')}"
        f"{_breakdown_table(b)}"
        f"<h2>The lowest pressure that still does the job</h2>"
        f"{_img(to_png(pressure_figure(search)), 'set point against cycle time')}"
        f"<h2>Measures, ranked by saving a year</h2>{_measures_table(analysis)}"
        f"<h2>Inputs</h2>{summary}"
        f"<p><small>pneufdd {_e(__version__)}, {_e(stamp)}. Methods: docs/energy.md.</small></p>"
        f"{_SCRIPT}</body></html>\n"
    )


def write_energy_report(
    path: str | Path, analysis: EnergyAnalysis, runs: str = "", overwrite: bool = True
) -> Path:
    """Render the report and write it to ``path`` atomically."""
    return write_text_atomic(Path(path), render_energy_report(analysis, runs), overwrite)
