"""A self-contained HTML leak report: no external assets, figures as base64 PNG.

Every piece of text that comes from data (file names, channel and location names,
notes) is HTML-escaped.
"""

from __future__ import annotations

import base64
import html
import math
import warnings
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from pneufdd import __version__
from pneufdd.diagnosis.cost import COST_BASIS_AVERAGE
from pneufdd.diagnosis.engine import check_compatible
from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.features.step_table import StepTable
from pneufdd.files import write_text_atomic
from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.report.figures import (
    band_figure,
    statistic_figure,
    step_flow_figure,
    step_trace_figure,
    to_png,
)
from pneufdd.report.steps import step_labels

__all__ = ["render_report", "write_report"]

_STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em 2em;
color:#222}header.run{color:#555;font-size:.95em;border-bottom:1px solid #ddd;padding:.2em 0}
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.3em .6em;
text-align:right}th{background:#f0f0f0}td.l,th.l{text-align:left}
.verdict{font-size:1.2em;font-weight:bold;padding:.5em;border-radius:4px}
.leak{background:#fde2e1}.ok{background:#e1f5e4}figure{margin:1em 0}img{width:100%;height:auto}
@media print{header.run{position:fixed;top:0;left:0;right:0;background:#fff}
body{margin-top:2.5em}figure{break-inside:avoid}}
.note{color:#7a4b00}
"""


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


def _img(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<figure><img alt="{_e(alt)}" src="data:image/png;base64,{data}"></figure>'


def _description_line(reference: ReferenceModel) -> str:
    """Which description the reference used (its title says if and how it was calibrated)."""
    description = reference.description
    if description is None:
        return "none (leaks are detected, not located or sized)"
    return description.title


def _fmt(x: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:,.{digits}f}"


def _flow_channel(reference: ReferenceModel) -> str | None:
    for name in ("Q_In", *reference.channels):
        if name in reference.channels and reference.units[reference.channels.index(name)] == "kg/s":
            return name
    return reference.channels[0] if reference.channels else None


def _band_channel(reference: ReferenceModel) -> str | None:
    for name in ("P_DNC_A", "P_In", *reference.channels):
        if name in reference.channels:
            return name
    return None


def labels_of(reference: ReferenceModel) -> list[str]:
    """Step labels of the reference: number and the actuators each step moves."""
    description = reference.description
    names = [s.name for s in description.steps] if description is not None else []
    return step_labels(reference.sequence, names, reference.n_steps)


def _figures(
    reference: ReferenceModel, run: StepTable, diagnosis: Diagnosis, context: str
) -> list[str]:
    out: list[str] = []
    labels = labels_of(reference)
    if diagnosis.cycle_scores.size:
        out.append(
            _img(
                to_png(
                    statistic_figure(
                        diagnosis.cycle_scores,
                        diagnosis.cycle_threshold,
                        diagnosis.run_score,
                        diagnosis.run_threshold,
                        context=context,
                    )
                ),
                "per-cycle statistic",
            )
        )
    flow = _flow_channel(reference)
    if flow is not None:
        c = reference.channels.index(flow)
        unit = reference.units[c]
        n = reference.n_steps
        start = n + c * 3 * n  # the channel's step means in the feature vector
        ref_means = reference.detector.mean_[start : start + n]
        run_means = np.mean(run.features()[:, start : start + n], axis=0)
        spread = reference.detector.scale_[start : start + n]
        figure = step_flow_figure(flow, unit, ref_means, run_means, labels, spread, context)
        out.append(_img(to_png(figure), flow))
        if (
            reference.band_mean is not None
            and reference.trace_offsets is not None
            and run.traces is not None
            and run.traces.shape[2] == reference.band_mean.shape[1]
        ):
            offsets = reference.trace_offsets
            diff = np.abs(run_means - ref_means)
            top = sorted(int(j) for j in np.argsort(diff)[::-1][:3])
            ref_tr = [reference.band_mean[c, offsets[j] : offsets[j + 1]] for j in top]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # samples no cycle reaches
                run_mean = np.nanmean(run.traces[:, c, :], axis=0)
            run_tr = [run_mean[offsets[j] : offsets[j + 1]] for j in top]
            out.append(
                _img(
                    to_png(
                        step_trace_figure(
                            flow,
                            unit,
                            [j + 1 for j in top],
                            ref_tr,
                            run_tr,
                            reference.trace_rate_hz,
                            labels,
                            context,
                        )
                    ),
                    f"{flow} traces of the most affected steps",
                )
            )
    band = _band_channel(reference)
    if (
        band is not None
        and reference.band_mean is not None
        and reference.band_std is not None
        and reference.trace_offsets is not None
        and run.traces is not None
        and run.traces.shape[2] == reference.band_mean.shape[1]
    ):
        c = reference.channels.index(band)
        det = reference.band_detector(band)
        std = det.std_ if det is not None else reference.band_std[c]
        out.append(
            _img(
                to_png(
                    band_figure(
                        band,
                        reference.units[c],
                        reference.band_mean[c],
                        std,
                        reference.settings.band_eps,
                        run.traces[:, c, :],
                        reference.trace_rate_hz,
                        reference.trace_offsets,
                        context,
                    )
                ),
                f"threshold band of {band}",
            )
        )
    return out


def _slpm_range(low: float, high: float) -> str:
    return f"{_fmt(float(kg_s_to_slpm(low)), 1)}-{_fmt(float(kg_s_to_slpm(high)), 1)}"


def _leak_table(diagnosis: Diagnosis) -> str:
    if not diagnosis.leaks:
        return "<p>No leak located.</p>"
    rows = []
    rank = {index: place for place, index in enumerate(diagnosis.repair_order, start=1)}
    for i, leak in enumerate(diagnosis.leaks, start=1):
        group = ", ".join(str(x) for x in leak.ambiguity_group)
        rows.append(
            "<tr>"
            f"<td>{i}</td><td class='l'>{_e(leak.location)}</td><td class='l'>{_e(group)}</td>"
            f"<td>{_fmt(leak.flow_slpm, 1)}</td><td>{_slpm_range(*leak.mass_flow_interval)}</td>"
            f"<td>{_fmt(leak.average_flow_slpm, 1)}</td>"
            f"<td>{_fmt(leak.orifice_mm, 2)}</td>"
            f"<td>{_fmt(leak.annual_cost, 0)}</td><td>{_fmt(100 * leak.confidence, 0)} %</td>"
            f"<td>{rank.get(i - 1, '')}</td><td>{_fmt(leak.repair_cost, 0)}</td>"
            "</tr>"
        )
    s = diagnosis.settings
    continuous = [
        str(leak.location) for leak in diagnosis.leaks if leak.cost_basis != COST_BASIS_AVERAGE
    ]
    basis = (
        "<p><b>Costs assume continuous leakage at the nominal flow</b> for "
        f"{_e(', '.join(continuous))}: the reference holds no mean leak flows per cycle "
        "(rebuild it with signatures).</p>"
        if continuous
        else ""
    )
    totals = diagnosis.totals
    total_row = (
        "<tr><th colspan='3' class='l'>total</th>"
        + (
            f"<th>{_fmt(float(kg_s_to_slpm(totals.mass_flow)), 1)}</th>"
            f"<th>{_slpm_range(*totals.mass_flow_interval)}</th>"
            f"<th>{_fmt(float(kg_s_to_slpm(totals.average_mass_flow)), 1)}</th><th></th>"
            f"<th>{_fmt(diagnosis.total_annual_cost, 0)} "
            f"({_fmt(totals.annual_cost_interval[0], 0)}-"
            f"{_fmt(totals.annual_cost_interval[1], 0)})</th>"
            if totals is not None
            else f"<th colspan='5'></th><th>{_fmt(diagnosis.total_annual_cost, 0)}</th>"
        )
        + "<th colspan='3'></th></tr>"
    )
    return (
        "<table><tr><th>#</th><th class='l'>location</th><th class='l'>ambiguity group</th>"
        "<th>flow while pressurised [SLPM]</th><th>95 % interval [SLPM]</th>"
        "<th>average flow over the cycle [SLPM]</th>"
        "<th>equivalent orifice [mm]</th><th>annual cost [$]</th>"
        "<th>confidence</th><th>repair order</th><th>repair cost [$]</th></tr>"
        + "".join(rows)
        + total_row
        + "</table>"
        + basis
        + "<p><i>Flow while pressurised</i>: the leak flow while its line holds pressure, at "
        "the machine's supply pressure (what an ultrasonic leak detector finds; the "
        "orifice is computed from it). <i>Average flow</i>: the air the leak really loses, "
        "averaged over an operating cycle (a supply leak blows all the time; a leak on an "
        "actuator line only while that line is pressurised). "
        f"Annual cost by eq. 1.1 of the average flow over {_fmt(s.hours, 0)} operating "
        f"hours/year, at ${_fmt(s.price_per_kwh, 3)}/kWh and "
        f"{_fmt(s.kw_per_100_cfm, 1)} kW per 100 cfm; a line that stays pressurised while "
        "the machine stands idle leaks more than this. SLPM at 0 degC, 1013 mbar "
        "(1.294 kg/m<sup>3</sup>); orifice: sharp-edged (C<sub>d</sub> = 0.61), choked "
        "from the leak's nominal pressure. Intervals: 95 % from the fit; the total's from "
        "the leaks' joint covariance, so it can be narrower than its parts suggest (leaks "
        "the sensors cannot separate have a well determined sum). <i>Repair order</i>: "
        "most annual cost saved per repair dollar first; expected repair cost "
        f"${_fmt(s.repair_fitting, 0)} for a fitting, tube, hose or coupling, "
        f"${_fmt(s.repair_seal, 0)} for an actuator seal, which is taken to be "
        f"{_fmt(100 * s.seal_share, 0)} % of the leaks on a line whose actuator's seal "
        "vents to the atmosphere (docs/assumptions.md).</p>"
    )


def _remainder_section(diagnosis: Diagnosis) -> str:
    """What the leaks leave: the share explained and where a leak could still hide."""
    remainder = diagnosis.remainder
    if remainder is None:
        return "<p>No leak signatures: nothing can be said about leaks the run hides.</p>"
    intro = f"<p>{_e(diagnosis.summary())}.</p>"
    if remainder.reasons:
        intro += (
            "<p class='note'>More leaks may be present: "
            + "; ".join(_e(r) for r in remainder.reasons)
            + ".</p>"
        )
    rows = "".join(
        f"<tr><td class='l'>{_e(name)}</td><td>"
        + ("any size (the sensors barely see it)" if cap else _fmt(float(kg_s_to_slpm(flow)), 1))
        + "</td></tr>"
        for name, flow, cap in remainder.groups()
    )
    return (
        intro + "<p>For each location group without a reported leak (the supply; each actuator's "
        "two lines), the largest additional leak the run cannot rule out: a one-sided "
        f"{_fmt(100 * remainder.level, 0)} % bound, the reported leaks refit around it. "
        f"The reported leaks explain {_fmt(100 * remainder.explained, 0)} % of the "
        "weighted deviation.</p>"
        "<table><tr><th class='l'>location group</th><th>largest hidden leak [SLPM]</th></tr>"
        + rows
        + "</table>"
    )


def _findings_table(diagnosis: Diagnosis) -> str:
    """One row per finding: type, where, size in its unit, group, confidence, consequence."""
    if not diagnosis.findings:
        return "<p>No finding.</p>"
    rows = []
    for i, finding in enumerate(diagnosis.findings, start=1):
        group = " or ".join(m.describe() for m in finding.ambiguity_group)
        rows.append(
            "<tr>"
            f"<td>{i}</td><td class='l'>{_e(' or '.join(finding.types))}</td>"
            f"<td class='l'>{_e(finding.location)}</td>"
            f"<td>{_fmt(finding.size, 1)} {_e(finding.unit)}</td>"
            f"<td class='l'>{_e(group)}</td><td>{_fmt(100 * finding.confidence, 0)} %</td>"
            f"<td class='l'>{_e(finding.consequence())}</td>"
            "</tr>"
        )
    return (
        "<table><tr><th>#</th><th class='l'>type</th><th class='l'>location</th>"
        "<th>size</th><th class='l'>ambiguity group (may span types)</th>"
        "<th>confidence</th><th class='l'>consequence</th></tr>"
        + "".join(rows)
        + "</table><p>Leaks are costed by eq. 1.1 (table below); other faults state the "
        "change of the cycle time they cause per cycle, by the twin at the fitted size "
        "(docs/faults.md, Diagnosis of fault types). A throttle's size is the change of its "
        "Cv in %.</p>"
    )


def _supply_row(diagnosis: Diagnosis) -> str:
    """The eq. 4.19-4.21 supply check as a table row (empty without supply sensors)."""
    supply = diagnosis.supply
    if supply is None:
        return ""
    counts = ", ".join(f"{v}: {n}" for v, n in supply.cycles.items())
    return (
        "<tr><th class='l'>supply check, eq. 4.21 (a leak raises the supply flow and lowers "
        "the supply pressure; a flow rise with a pressure rise is the house air)</th>"
        f"<td>{_e(supply.verdict)} (cycles: {_e(counts)}); supply flow "
        f"{_fmt(float(kg_s_to_slpm(supply.flow_change)), 1)} SLPM, pressure "
        f"{_fmt(supply.pressure_change / 1e5, 3)} bar against the reference</td></tr>"
    )


def render_report(
    reference: ReferenceModel,
    run: StepTable,
    diagnosis: Diagnosis,
    title: str = "pneufdd leak report",
    run_name: str = "run",
    run_time: datetime | None = None,
) -> str:
    """Render the self-contained HTML report of one diagnosis.

    Parameters
    ----------
    reference : ReferenceModel
        The reference the run was diagnosed against.
    run : StepTable
        The run's cycles (for the figures).
    diagnosis : Diagnosis
        The result of :func:`~pneufdd.diagnosis.engine.diagnose`.
    title : str
        Page title.
    run_name : str
        Name of the run (e.g. its file), shown on the page.
    run_time : datetime, optional
        When the run was recorded (its start); with the machine and the run's name it
        heads the page and every figure (and every printed page).

    Returns
    -------
    str
        A complete HTML document.
    """
    run = check_compatible(reference, run)
    others = sum(finding.fault_type != "leak" for finding in diagnosis.findings)
    verdict = (
        f"<div class='verdict leak'>Leak detected: {len(diagnosis.leaks)} leak(s) located, "
        f"total {_fmt(diagnosis.total_annual_cost, 0)} $/year"
        + (
            "; more leaks may be present"
            if diagnosis.remainder is not None and diagnosis.remainder.more_leaks_possible
            else ""
        )
        + (f"; {others} other fault(s) found" if others else "")
        + "</div>"
        if diagnosis.detected
        else "<div class='verdict ok'>No leak detected</div>"
    )
    flagged = int(np.sum(diagnosis.cycle_scores > diagnosis.cycle_threshold))
    detection = (
        "<table>"
        f"<tr><th class='l'>cycles analysed</th><td>{diagnosis.cycles_analyzed}</td></tr>"
        f"<tr><th class='l'>run statistic ({reference.settings.run_statistic} T) / threshold"
        "</th>"
        f"<td>{_fmt(diagnosis.run_score, 3)} / {_fmt(diagnosis.run_threshold, 3)}</td></tr>"
        f"<tr><th class='l'>p-value of a leak-free run</th><td>{diagnosis.p_value:.3g}</td></tr>"
        f"<tr><th class='l'>cycles above the per-cycle threshold</th><td>{flagged}</td></tr>"
        f"<tr><th class='l'>cross-validated false-alarm rate per leak-free reference cycle"
        f"</th><td>{_fmt(100 * diagnosis.reference_false_alarm_rate, 2)} %</td></tr>"
        f"<tr><th class='l'>band method (eps = {_fmt(reference.settings.band_eps, 1)}, "
        f"n = {_fmt(100 * reference.settings.band_alarm_fraction, 1)} %): cycles flagged</th>"
        f"<td>{diagnosis.band_alarms if diagnosis.band_fraction.size else 'n/a'}</td></tr>"
        f"{_supply_row(diagnosis)}"
        "</table>"
    )
    ambiguous = [leak for leak in diagnosis.leaks if len(leak.ambiguity_group) > 1]
    ambiguity = (
        "<p>Each leak's <em>ambiguity group</em> lists the candidate locations whose leak "
        "signatures the available sensors cannot tell apart: swapping one for another "
        "changes the fit by less than the noise allows, or their weighted signatures are "
        "nearly collinear. The first member fits best, but a group of more than one member "
        "is not a confident location: inspect all of them. The confidence is the "
        "probability-like weight of the group times the fraction of the observed deviation "
        "that the leak model explains.</p>"
    )
    if ambiguous:
        ambiguity += (
            "<ul>"
            + "".join(
                f"<li>{_e(leak.location)}: cannot be told apart from "
                f"{_e(', '.join(str(x) for x in leak.ambiguity_group[1:]))} with sensors "
                f"{_e(', '.join(reference.channels) or 'digital only')}</li>"
                for leak in ambiguous
            )
            + "</ul>"
        )
    notes = "".join(f"<p class='note'>{_e(n)}</p>" for n in diagnosis.notes)
    sources = ", ".join(reference.sources) or "n/a"
    signature_locations = (
        ", ".join(str(x) for x in reference.signatures.locations)
        if reference.signatures
        else "none"
    )
    meta = (
        "<table>"
        f"<tr><th class='l'>machine</th><td class='l'>{_e(reference.machine)}</td></tr>"
        f"<tr><th class='l'>machine description</th><td class='l'>"
        f"{_e(_description_line(reference))}</td></tr>"
        f"<tr><th class='l'>run</th><td class='l'>{_e(run_name)}</td></tr>"
        f"<tr><th class='l'>reference</th><td class='l'>{reference.n_cycles} leak-free cycles "
        f"from {_e(sources)}</td></tr>"
        f"<tr><th class='l'>sensor set</th><td class='l'>"
        f"{_e(', '.join(reference.channels) or 'none')} + PLC digital signals</td></tr>"
        + _sensor_set_rows(diagnosis)
        + f"<tr><th class='l'>steps per cycle</th><td class='l'>{reference.n_steps}</td></tr>"
        f"<tr><th class='l'>leak signatures</th><td class='l'>"
        f"{_e(signature_locations)}"
        "</td></tr></table>"
    )
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    recorded = (
        run_time.astimezone(UTC).strftime("%Y-%m-%d %H:%M UTC")
        if run_time is not None
        else "date not recorded"
    )
    context = f"machine {reference.machine} | run {run_name} | recorded {recorded}"
    figures = "".join(_figures(reference, run, diagnosis, context))
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{_e(title)}</title><style>{_STYLE}</style></head><body>"
        f"<header class='run'>{_e(context)} | report {_e(stamp)}</header>"
        f"<h1>{_e(title)}</h1>{verdict}{notes}"
        f"<h2>Findings</h2>{_findings_table(diagnosis)}"
        f"<h2>Leaks, ranked by annual cost</h2>{_leak_table(diagnosis)}"
        f"<h2>What the leaks do not explain</h2>{_remainder_section(diagnosis)}"
        f"<h2>Ambiguity groups</h2>{ambiguity}"
        f"<h2>Detection</h2>{detection}"
        f"<h2>Figures</h2>{figures}"
        f"<h2>Inputs</h2>{meta}"
        f"<p><small>pneufdd {_e(__version__)}, {_e(stamp)}. Methods: docs/diagnosis.md."
        "</small></p></body></html>\n"
    )


def write_report(
    path: str | Path,
    reference: ReferenceModel,
    run: StepTable,
    diagnosis: Diagnosis,
    title: str = "pneufdd leak report",
    run_name: str = "run",
    overwrite: bool = True,
    run_time: datetime | None = None,
) -> Path:
    """Render the report and write it to ``path`` atomically."""
    return write_text_atomic(
        Path(path), render_report(reference, run, diagnosis, title, run_name, run_time), overwrite
    )


def _sensor_set_rows(diagnosis: Diagnosis) -> str:
    """What the sensor set can and cannot find (docs/sensor-sets.md), as table rows."""
    report = diagnosis.sensor_set
    if report is None:
        return ""
    return (
        f"<tr><th class='l'>sensor set kind</th><td class='l'>{_e(report.kind)}</td></tr>"
        f"<tr><th class='l'>it can</th><td class='l'>{_e(report.can)}</td></tr>"
        f"<tr><th class='l'>it cannot</th><td class='l'>{_e(report.cannot)}</td></tr>"
    )
