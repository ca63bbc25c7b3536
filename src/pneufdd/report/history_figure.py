"""Figure of the fault history: each leak's size and cost over time."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

from pneufdd.report.plain_text import plain_text

__all__ = ["history_figure"]


@plain_text
def history_figure(report: Sequence[dict[str, Any]], path: Path) -> Path:
    """Draw leak flow [SLPM] and annual cost [$/yr] over time for every machine's leaks.

    ``report`` is the ``machines`` list of ``pneufdd history --json``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_flow, ax_cost) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    drawn = 0
    for entry in report:
        for leak in entry["leaks"]:
            points = [s for s in leak["sizes"] if s["flow_slpm"] is not None]
            if not points:
                continue
            times = [datetime.fromisoformat(s["time"]) for s in points]
            label = f"{entry['machine']} {leak['location']} ({leak['state']})"
            ax_flow.plot(times, [s["flow_slpm"] for s in points], "o-", label=label)
            ax_cost.plot(times, [s["annual_cost"] or 0.0 for s in points], "o-", label=label)
            if leak.get("repaired_at"):
                ax_flow.axvline(datetime.fromisoformat(leak["repaired_at"]), ls=":", c="grey")
            drawn += 1
    ax_flow.set_ylabel("leak flow [SLPM]")
    ax_cost.set_ylabel("annual cost [$/yr]")
    ax_cost.set_xlabel("time (UTC)")
    if drawn:
        ax_flow.legend(fontsize=8)
    else:
        ax_flow.text(0.5, 0.5, "no leaks recorded", transform=ax_flow.transAxes, ha="center")
    fig.autofmt_xdate()
    fig.tight_layout()
    from pneufdd.report.figures import save_figure

    save_figure(fig, path, dpi=fig.dpi)  # atomically: a link is replaced, not written through
    return path
