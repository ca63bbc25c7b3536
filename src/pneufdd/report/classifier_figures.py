"""Figures of the dissertation's classifiers: the vectorized map and the sign table.

- :func:`vector_map_figure`: Fig. 5.18 - air of the extend and the retract stroke,
  each normalised by its leak-free value, one cluster per leak, and for each
  combined leak the vector sum of its single leaks drawn from the leak-free point
  (eq. 5.23) next to where the combination really lies;
- :func:`sign_table_figure`: a learned sign table beside Table 4.5.

Both return a matplotlib Figure (Agg backend); save it with ``fig.savefig``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from pneufdd.report.plain_text import plain_text

__all__ = ["sign_table_figure", "vector_map_figure"]


@plain_text
def vector_map_figure(
    normalised: pd.DataFrame,
    vectors: Mapping[str, Sequence[float]],
    axes: tuple[str, str],
    title: str = "Vectorized map (Fig. 5.18)",
) -> Figure:
    """Scatter of the normalised cycles with leak vectors and vector sums (eq. 5.23).

    Parameters
    ----------
    normalised : pandas.DataFrame
        The two axis columns (normalised, leak-free = 1) and ``label`` per cycle.
    vectors : mapping
        Single-leak label -> its vector (centre minus leak-free point) [-].
    axes : tuple of str
        The two axis columns.
    title : str
        Figure title.
    """
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    labels = sorted(set(normalised["label"]), key=lambda s: ("+" in s, s != "none", s))
    cmap = plt.get_cmap("tab20")
    origin = normalised.loc[normalised["label"] == "none", list(axes)].mean().to_numpy()
    for i, label in enumerate(labels):
        part = normalised[normalised["label"] == label]
        marker = "x" if "+" in label else "o"
        ax.scatter(
            part[axes[0]], part[axes[1]], s=14, marker=marker, color=cmap(i % 20), label=label
        )
    start = (float(origin[0]), float(origin[1]))
    for vec in vectors.values():
        tip = (start[0] + float(vec[0]), start[1] + float(vec[1]))
        ax.annotate("", tip, start, arrowprops={"arrowstyle": "->", "color": "0.3"})
    for label in labels:
        if "+" not in label:
            continue
        total = np.sum([np.asarray(vectors[p], dtype=float) for p in label.split("+")], axis=0)
        centre = normalised.loc[normalised["label"] == label, list(axes)].mean().to_numpy()
        tip = (start[0] + float(total[0]), start[1] + float(total[1]))
        ax.annotate("", tip, start, arrowprops={"arrowstyle": "->", "color": "red", "ls": "--"})
        ax.plot(*zip(origin + total, centre, strict=True), color="red", lw=0.8, ls=":")
    ax.set_xlabel(f"{axes[0]} / leak-free value [-]")
    ax.set_ylabel(f"{axes[1]} / leak-free value [-]")
    ax.set_title(title + "\nred dashed: vector sum of the single leaks (eq. 5.23)", fontsize=10)
    ax.legend(fontsize=6, ncol=2, loc="best")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


@plain_text
def sign_table_figure(
    learned: Mapping[str, str], published: Mapping[str, str], title: str = "Sign table"
) -> Figure:
    """Learned signs beside Table 4.5 (+ red, - blue, 0 white, ? grey)."""
    rows = list(published)
    n = max(len(v) for v in published.values())
    colour = {"+": 1.0, "-": -1.0, "0": 0.0}
    fig, axes = plt.subplots(1, 2, figsize=(11, 2.8), sharey=True)
    for ax, (name, table) in zip(
        axes, (("learned from simulated runs", learned), ("Table 4.5", published)), strict=True
    ):
        grid = np.full((len(rows), n), np.nan)
        for r, row in enumerate(rows):
            for c, ch in enumerate(table.get(row, "?" * n)):
                grid[r, c] = colour.get(ch, np.nan)
                ax.text(c, r, ch, ha="center", va="center", fontsize=10)
        ax.imshow(np.ma.masked_invalid(grid), cmap="bwr", vmin=-1.5, vmax=1.5)
        ax.set_xticks(range(n), [str(i + 1) for i in range(n)])
        ax.set_yticks(range(len(rows)), rows)
        ax.set_xlabel("Table 4.4 feature")
        ax.set_title(name, fontsize=10)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig
