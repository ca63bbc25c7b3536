"""The dashboard's charts as Plotly figures, on the axis rules of the report (:mod:`.axes`).

Each function returns the figure as Plotly JSON (``figure.to_json()``) that the page
draws with the plotly.js bundled in the installed ``plotly`` package. Like the report's
matplotlib figures: legends above the plot, integer cycle counts, times in UTC, one unit
per axis, ratio quantities from zero (:func:`~pneufdd.report.axes.ratio_range`), scores
on a log axis with their threshold (:func:`~pneufdd.report.axes.score_range`), the
machine and date in the title.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from pneufdd.report.axes import FLOW_FLOOR_SLPM, ratio_range, score_range

__all__ = ["diagnosis_statistic_figure", "leak_trend_figure", "score_figure"]

_LEGEND = {"orientation": "h", "x": 0.0, "xanchor": "left", "y": 1.02, "yanchor": "bottom"}
_MARGIN = {"l": 70, "r": 20, "t": 90, "b": 50}


def _when(t: float) -> datetime:
    return datetime.fromtimestamp(t, UTC)


def _json(fig: Any) -> str:
    return str(fig.to_json())


def _ok(x: Any) -> bool:
    return isinstance(x, int | float) and math.isfinite(x)


def _legend_entry(fig: Any, name: str, style: Mapping[str, Any], **where: int) -> None:
    """A legend entry without data for a line or band drawn as a shape (``add_hline``,
    ``add_vrect``), which plotly leaves out of the legend: ``style`` is the trace's
    ``mode`` and its ``line`` or ``marker``; ``where`` the subplot's ``row`` and ``col``."""
    import plotly.graph_objects as go

    fig.add_trace(go.Scatter(x=[None], y=[None], name=name, **style), **where)


def score_figure(
    cycles: Sequence[Mapping[str, Any]],
    cycle_threshold: float | None,
    cusum_threshold: float | None,
    gaps: Sequence[Mapping[str, Any]],
    title: str,
) -> str:
    """Per-cycle score (log axis, per-cycle threshold) above the CUSUM (decision threshold).

    ``cycles``: ``start`` [s since 1970-01-01 UTC], ``score``, ``cusum``; ``gaps``:
    ``start``, ``end`` (shaded in both panels: cycles skipped or lost).
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, vertical_spacing=0.08)
    times = [_when(c["start"]) for c in cycles]
    scores = [c["score"] if _ok(c["score"]) and c["score"] > 0 else None for c in cycles]
    fig.add_trace(
        go.Scatter(x=times, y=scores, mode="markers", name="cycle score T", marker={"size": 4}),
        row=1,
        col=1,
    )
    threshold = float(cycle_threshold) if cycle_threshold is not None else math.nan
    if math.isfinite(threshold):
        fig.add_hline(y=threshold, line_dash="dash", line_color="#d62728", row=1, col=1)
        style = {"mode": "lines", "line": {"dash": "dash", "color": "#d62728"}}
        _legend_entry(fig, "per-cycle threshold", style, row=1, col=1)
    low, high = score_range(scores, threshold)
    fig.update_yaxes(type="log", range=[low, high], title_text="score T [-]", row=1, col=1)
    cusum = [c["cusum"] if _ok(c["cusum"]) else None for c in cycles]
    fig.add_trace(
        go.Scatter(x=times, y=cusum, mode="lines", name="CUSUM", line={"color": "#1f77b4"}),
        row=2,
        col=1,
    )
    top = max([v for v in cusum if v is not None] or [0.0])
    if _ok(cusum_threshold):
        assert cusum_threshold is not None
        fig.add_hline(y=cusum_threshold, line_dash="dot", line_color="#d62728", row=2, col=1)
        style = {"mode": "lines", "line": {"dash": "dot", "color": "#d62728"}}
        _legend_entry(fig, "CUSUM decision threshold", style, row=2, col=1)
        top = max(top, cusum_threshold)
    fig.update_yaxes(
        range=[0.0, 1.15 * top if top > 0 else 1.0], title_text="CUSUM [-]", row=2, col=1
    )
    for gap in gaps:
        fig.add_vrect(
            x0=_when(gap["start"]),
            x1=_when(gap["end"]),
            fillcolor="#ff7f0e",
            opacity=0.25,
            line_width=0,
        )
    if gaps:
        style = {"mode": "markers", "marker": {"color": "#ff7f0e", "symbol": "square"}}
        _legend_entry(fig, "gap: cycles skipped or lost", style, row=2, col=1)
    fig.update_xaxes(title_text="cycle start (UTC)", row=2, col=1)
    fig.update_layout(title=title, legend=_LEGEND, margin=_MARGIN, height=520)
    return _json(fig)


def leak_trend_figure(trends: Sequence[Mapping[str, Any]], title: str) -> str:
    """Each leak's flow over time from zero; repairs as dotted lines.

    ``trends``: per leak ``location``, ``state``, ``repaired_at`` and ``sizes``
    (``time`` [s since 1970-01-01 UTC], ``flow_slpm``).
    """
    import plotly.graph_objects as go

    fig = go.Figure()
    flows: list[float] = []
    times: list[float] = []
    for leak in trends:
        points = [s for s in leak["sizes"] if _ok(s.get("flow_slpm"))]
        if not points:
            continue
        flow = [float(s["flow_slpm"]) for s in points]
        flows += flow
        times += [float(s["time"]) for s in points]
        fig.add_trace(
            go.Scatter(
                x=[_when(s["time"]) for s in points],
                y=flow,
                mode="lines+markers",
                name=f"{leak['location']} ({leak['state']})",
            )
        )
        if leak.get("repaired_at") is not None:
            fig.add_vline(
                x=_when(float(leak["repaired_at"])).timestamp() * 1000.0,
                line_dash="dot",
                line_color="#555",
            )
    fig.update_yaxes(
        range=list(ratio_range(flows, FLOW_FLOOR_SLPM)),
        title_text="leak flow while pressurised [SLPM]",
    )
    fig.update_xaxes(title_text="time (UTC); dotted: repaired")
    if times:
        # at least an hour wide: one estimate alone was drawn on a sub-millisecond axis
        middle, half = (
            (max(times) + min(times)) / 2.0,
            max((max(times) - min(times)) * 0.55, 1800.0),
        )
        fig.update_xaxes(range=[_when(middle - half), _when(middle + half)])
    fig.update_layout(title=title, legend=_LEGEND, margin=_MARGIN, height=360)
    return _json(fig)


def diagnosis_statistic_figure(detection: Mapping[str, Any], title: str) -> str:
    """The diagnosis's per-cycle statistic (bars, log axis) with its thresholds."""
    import plotly.graph_objects as go

    scores = [s if _ok(s) else None for s in detection.get("cycle_scores", [])]
    given: Any = detection.get("cycle_threshold")
    threshold = float(given) if _ok(given) else math.nan
    cycles = list(range(1, len(scores) + 1))
    colours = ["#d62728" if s is not None and s > threshold else "#7f7f7f" for s in scores]
    fig = go.Figure(go.Bar(x=cycles, y=scores, marker_color=colours, name="statistic T"))
    if math.isfinite(threshold):
        fig.add_hline(y=threshold, line_dash="dash", line_color="#d62728")
        style = {"mode": "lines", "line": {"dash": "dash", "color": "#d62728"}}
        _legend_entry(fig, "per-cycle threshold", style)
    low, high = score_range([s for s in scores if s is not None], threshold)
    fig.update_yaxes(type="log", range=[low, high], title_text="statistic T [-]")
    fig.update_xaxes(
        title_text="cycle of the window", tickmode="linear", dtick=1, range=[0.4, len(scores) + 0.6]
    )
    fig.update_layout(title=title, legend=_LEGEND, margin=_MARGIN, height=340)
    return _json(fig)
