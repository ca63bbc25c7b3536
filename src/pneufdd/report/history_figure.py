"""Figure of the fault history: each leak's size and cost over time, on honest axes.

Leak flow and cost are ratio quantities: both axes start at zero and reach the larger
of 1.15 x the largest value and a physical floor (:func:`pneufdd.report.axes.ratio_range`),
so a leak that drifts by 3 % is drawn as a 3 % change, never auto-scaled into a steep
fall. Repairs are vertical lines; the machines and the time span head the figure.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

from pneufdd.report.axes import COST_FLOOR, FLOW_FLOOR_SLPM, ratio_range
from pneufdd.report.plain_text import plain_text, printable

__all__ = ["history_figure"]


@plain_text
def history_figure(report: Sequence[dict[str, Any]], path: Path) -> Path:
    """Draw leak flow [SLPM] and annual cost [$/yr] over time for every machine's leaks.

    ``report`` is the ``machines`` list of ``pneufdd history --json``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pneufdd.report.figures import WIDTH_IN, save_figure

    fig, (ax_flow, ax_cost) = plt.subplots(2, 1, figsize=(WIDTH_IN, 7), sharex=True)
    drawn, flows, costs, times_all = 0, [], [], []
    for entry in report:
        for leak in entry["leaks"]:
            points = [s for s in leak["sizes"] if s["flow_slpm"] is not None]
            if not points:
                continue
            times = [datetime.fromisoformat(s["time"]) for s in points]
            label = _cut(printable(f"{entry['machine']} {leak['location']} ({leak['state']})"))
            flow = [s["flow_slpm"] for s in points]
            cost = [s["annual_cost"] or 0.0 for s in points]
            (line,) = ax_flow.plot(times, flow, "o-", label=label)
            ax_cost.plot(times, cost, "o-", color=line.get_color())
            if leak.get("repaired_at"):
                when = datetime.fromisoformat(leak["repaired_at"])
                for ax in (ax_flow, ax_cost):
                    ax.axvline(when, ls=":", color=line.get_color())
                times_all.append(when)
            flows += flow
            costs += cost
            times_all += times
            drawn += 1
    ax_flow.set_ylim(*ratio_range(flows, FLOW_FLOOR_SLPM))
    ax_cost.set_ylim(*ratio_range(costs, COST_FLOOR))
    ax_flow.set_ylabel("leak flow while pressurised [SLPM]")
    ax_cost.set_ylabel("annual cost [$/yr]")
    ax_cost.set_xlabel("time (UTC); dotted: repaired")
    if drawn:
        ax_flow.legend(
            loc="lower left", bbox_to_anchor=(0.0, 1.01), ncol=3, frameon=False, fontsize=8
        )
    else:
        ax_flow.text(0.5, 0.5, "no leaks recorded", transform=ax_flow.transAxes, ha="center")
    names = _cut(printable(", ".join(str(e["machine"]) for e in report)), 120) or "no machine"
    span = (
        f"{min(times_all):%Y-%m-%d %H:%M} .. {max(times_all):%Y-%m-%d %H:%M} UTC"
        if times_all
        else "no size estimates"
    )
    fig.suptitle(
        f"Leak sizes and costs over time (axes from zero)\n{names} | {span}", fontsize="medium"
    )
    fig.autofmt_xdate()
    with warnings.catch_warnings():  # long names: the layout is as tight as it can be
        warnings.filterwarnings("ignore", "Tight layout not applied", UserWarning)
        fig.tight_layout()
    save_figure(fig, path, dpi=fig.dpi)  # atomically: a link is replaced, not written through
    return path


def _cut(text: str, limit: int = 60) -> str:
    """``text`` cut to ``limit`` characters (a 10,000-character machine name in a legend)."""
    return text if len(text) <= limit else f"{text[: limit - 3]}..."
