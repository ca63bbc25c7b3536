"""Figures of the diagnosis report, rendered with matplotlib's Agg backend to PNG bytes.

- :func:`step_flow_figure`: per-step reference vs run mean of a channel and their
  difference (the style of Figs. 5.4-5.9, one value per step after lag removal);
- :func:`step_trace_figure`: step-aligned reference and run traces of the most
  affected steps and their difference (Figs. 5.7-5.9);
- :func:`band_figure`: the threshold band mean +/- eps sigma over the aligned cycle
  with the run's cycles (Fig. 5.13);
- :func:`statistic_figure`: the per-cycle statistic against its threshold.

Every figure is as wide as the page (:data:`WIDTH_IN` at :data:`PNG_DPI`), keeps its
legend above the axes (never over the data), counts cycles and steps in integers,
names each step with the actuators it moves (:func:`pneufdd.report.steps.step_labels`),
carries the machine, run and date (``context``), shows one unit family per axis
(SLPM and bar(g), differences in mbar on their own axis) and follows the axis rules of
:mod:`pneufdd.report.axes`.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator, NullFormatter

from pneufdd.array_types import FloatArray
from pneufdd.files import atomic_target
from pneufdd.physics.units import kg_s_to_slpm, pa_to_bar_gauge
from pneufdd.report.axes import difference_range, ratio_range, score_range
from pneufdd.report.plain_text import plain_text

__all__ = [
    "PNG_DPI",
    "WIDTH_IN",
    "band_figure",
    "display_values",
    "save_figure",
    "statistic_figure",
    "step_flow_figure",
    "step_trace_figure",
    "to_png",
]


WIDTH_IN = 12.0
"""Width of every report figure [in]: 1080 px at :data:`PNG_DPI`, the page's width."""
PNG_DPI = 90.0
"""Resolution of the report's PNG figures [1/in]."""


def display_values(values: npt.ArrayLike, unit: str) -> tuple[FloatArray, str]:
    """Convert SI values to the units an engineer reads: SLPM for flow, bar(g) for pressure.

    One unit family on every page: metric (SLPM at 0 degC, 1013 mbar; bar gauge over
    101,325 Pa; mm).

    Examples
    --------
    >>> v, u = display_values([0.001294 / 60.0 * 1000.0], "kg/s")
    >>> round(float(v[0]), 6), u
    (1000.0, 'SLPM')
    >>> v, u = display_values([701325.0], "Pa")
    >>> round(float(v[0]), 6), u
    (6.0, 'bar(g)')
    """
    arr = np.asarray(values, dtype=np.float64)
    if unit == "kg/s":
        return np.asarray(kg_s_to_slpm(arr), dtype=np.float64), "SLPM"
    if unit == "Pa":
        return np.asarray(pa_to_bar_gauge(arr), dtype=np.float64), "bar(g)"
    if unit == "m":
        return arr * 1e3, "mm"
    return arr, unit


def display_delta(values: npt.ArrayLike, unit: str) -> tuple[FloatArray, str]:
    """Like :func:`display_values` for differences (no gauge offset; pressure in mbar).

    Examples
    --------
    >>> v, u = display_delta([250.0], "Pa")
    >>> float(v[0]), u
    (2.5, 'mbar')
    """
    arr = np.asarray(values, dtype=np.float64)
    if unit == "Pa":
        return arr / 100.0, "mbar"
    return display_values(arr, unit)


def _legend_above(ax: Axes, ncol: int = 4) -> None:
    """The legend in one row above the axes: never over the data."""
    ax.legend(
        loc="lower left",
        bbox_to_anchor=(0.0, 1.01),
        ncol=ncol,
        frameon=False,
        fontsize="small",
        borderaxespad=0.0,
    )


def _title(fig: Figure, title: str, context: str) -> None:
    """Title, and the machine, run and date under it (on every figure)."""
    fig.suptitle(f"{title}\n{context}" if context else title, fontsize="medium")


def _step_ticks(ax: Axes, labels: Sequence[str], n: int) -> None:
    """Integer step ticks named with their actuators (every k-th when there are many)."""
    positions = np.arange(1, n + 1)
    names = list(labels) if len(labels) == n else [str(i) for i in positions]
    every = max(1, int(np.ceil(n / 40)))
    ax.set_xticks(positions[::every])
    ax.set_xticklabels(names[::every], rotation=90, fontsize="x-small")
    ax.set_xlim(0.4, n + 0.6)


@plain_text
def save_figure(fig: Figure, path: Path, dpi: float = 110.0) -> Path:
    """Save ``fig`` to ``path`` atomically (a link there is replaced, never written through).

    The format follows the file's extension (PNG without one); the figure is closed.
    """
    try:
        with atomic_target(path) as tmp:
            fig.savefig(tmp, format=path.suffix[1:].lower() or "png", dpi=dpi)
    finally:
        plt.close(fig)
    return path


@plain_text
def to_png(fig: Figure) -> bytes:
    """Render ``fig`` to PNG bytes at :data:`PNG_DPI` and close it."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=PNG_DPI, bbox_inches="tight")
    plt.close(fig)
    return buffer.getvalue()


@plain_text
def step_flow_figure(
    channel: str,
    unit: str,
    reference: FloatArray,
    run: FloatArray,
    labels: Sequence[str] = (),
    reference_std: FloatArray | None = None,
    context: str = "",
) -> Figure:
    """Per-step mean of ``channel``: reference, run and run minus reference.

    Parameters
    ----------
    channel : str
        Channel name.
    unit : str
        SI unit of the values.
    reference, run : ndarray, shape (n_steps,)
        Mean over the step, averaged over cycles [unit].
    labels : sequence of str
        Step labels (:func:`~pneufdd.report.steps.step_labels`).
    reference_std : ndarray, shape (n_steps,), optional
        Spread of the reference's step means [unit]: the difference axis spans at
        least three of them each way (:func:`~pneufdd.report.axes.difference_range`).
    context : str
        Machine, run and date, shown under the title.
    """
    n = reference.size
    steps = np.arange(1, n + 1)
    ref, label = display_values(reference, unit)
    new, _ = display_values(run, unit)
    diff, dlabel = display_delta(run - reference, unit)
    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(WIDTH_IN, 6.5), sharex=True, height_ratios=(3, 2)
    )
    top.step(steps, ref, where="mid", ls="--", color="tab:blue", label="reference")
    top.step(steps, new, where="mid", color="tab:red", label="run")
    top.set_ylabel(f"{channel} step mean [{label}]")
    if unit == "kg/s":  # a flow is a ratio quantity: its axis starts at zero
        top.set_ylim(*ratio_range([*ref, *new], floor=1.0))
    _legend_above(top)
    bottom.bar(steps, diff, color="tab:green", label="run - reference")
    bottom.axhline(0.0, color="k", lw=0.5)
    spread = None if reference_std is None else display_delta(reference_std, unit)[0]
    bottom.set_ylim(*difference_range(diff, [] if spread is None else spread))
    bottom.set_ylabel(f"run - reference [{dlabel}]")
    bottom.set_xlabel("step: number and actuators moved (+ extend/advance, - retract)")
    _step_ticks(bottom, labels, n)
    _title(fig, f"{channel}: per-step comparison (style of Figs. 5.4-5.9)", context)
    fig.tight_layout()
    return fig


@plain_text
def step_trace_figure(
    channel: str,
    unit: str,
    steps: Sequence[int],
    reference: Sequence[FloatArray],
    run: Sequence[FloatArray],
    rate_hz: float,
    labels: Sequence[str] = (),
    context: str = "",
) -> Figure:
    """Step-aligned mean traces of a few steps above their difference (Figs. 5.7-5.9).

    Parameters
    ----------
    steps : sequence of int
        1-based step numbers.
    reference, run : sequence of ndarray
        Mean trace of each step from its start [unit].
    rate_hz : float
        Sample rate of the traces [Hz].
    labels : sequence of str
        Labels of all steps of the cycle (the drawn ones are picked by number).
    """
    n = max(len(steps), 1)
    fig, axes = plt.subplots(
        2, n, figsize=(WIDTH_IN, 5.5), squeeze=False, sharex="col", height_ratios=(3, 2)
    )
    for k, (step, ref, new) in enumerate(zip(steps, reference, run, strict=False)):
        top, bottom = axes[0][k], axes[1][k]
        t = np.arange(ref.size) / rate_hz
        r, label = display_values(ref, unit)
        x, _ = display_values(new, unit)
        d, dlabel = display_delta(new - ref, unit)
        top.plot(t, r, "--", color="tab:blue", label="reference")
        top.plot(t, x, color="tab:red", label="run")
        bottom.plot(t, d, color="tab:green", label="run - reference")
        bottom.axhline(0.0, color="k", lw=0.5)
        bottom.set_ylim(*difference_range(d))
        name = labels[step - 1] if 0 < step <= len(labels) else f"{step}"
        bottom.set_xlabel(f"step {name}: time from its start [s]")
        top.set_ylabel(f"{channel} [{label}]")
        bottom.set_ylabel(f"difference [{dlabel}]")
    _legend_above(axes[0][0], ncol=2)
    _legend_above(axes[1][0], ncol=1)
    _title(fig, f"{channel}: most affected steps after lag removal", context)
    fig.tight_layout()
    return fig


@plain_text
def band_figure(
    channel: str,
    unit: str,
    mean: FloatArray,
    std: FloatArray,
    eps: float,
    run: FloatArray,
    rate_hz: float,
    offsets: npt.NDArray[np.int64],
    context: str = "",
) -> Figure:
    """Reference band ``mean +/- eps std`` and the run's cycles (Fig. 5.13).

    Parameters
    ----------
    mean, std : ndarray, shape (n_samples,)
        Per-sample reference statistics of eq. 5.21 [unit].
    eps : float
        Band width [-].
    run : ndarray, shape (n_cycles, n_samples)
        The run's aligned cycles [unit].
    offsets : ndarray of int
        Step boundaries in samples.
    """
    t = np.arange(mean.size) / rate_hz
    m, label = display_values(mean, unit)
    lo, _ = display_values(mean - eps * std, unit)
    hi, _ = display_values(mean + eps * std, unit)
    fig, ax = plt.subplots(figsize=(WIDTH_IN, 4.2))
    ax.fill_between(t, lo, hi, color="tab:blue", alpha=0.25, label=f"mean +/- {eps:g} sigma")
    ax.plot(t, m, color="tab:blue", lw=0.8, label="reference mean")
    for i, cycle in enumerate(np.atleast_2d(run)):
        c, _ = display_values(cycle, unit)
        ax.plot(t, c, color="tab:red", lw=0.5, alpha=0.6, label="run cycles" if i == 0 else None)
    for off in offsets[1:-1]:
        ax.axvline(off / rate_hz, color="0.85", lw=0.4, zorder=0)
    ax.set_xlabel("aligned cycle time (steps concatenated, each from its own start) [s]")
    ax.set_ylabel(f"{channel} [{label}]")
    ax.set_xlim(0.0, float(t[-1]) if t.size else 1.0)
    _legend_above(ax)
    _title(fig, f"{channel}: threshold band of eq. 5.21 (style of Fig. 5.13)", context)
    fig.tight_layout()
    return fig


@plain_text
def statistic_figure(
    scores: FloatArray,
    threshold: float,
    run_score: float,
    run_threshold: float,
    context: str = "",
) -> Figure:
    """Per-cycle statistic against the per-cycle and run thresholds (log axis, integer cycles)."""
    cycles = np.arange(1, scores.size + 1)
    fig, ax = plt.subplots(figsize=(WIDTH_IN, 3.8))
    ax.bar(cycles, scores, color=np.where(scores > threshold, "tab:red", "tab:gray"))
    ax.axhline(threshold, color="tab:red", ls="--", label="per-cycle threshold")
    ax.axhline(run_score, color="tab:blue", label="run statistic")
    ax.axhline(run_threshold, color="tab:blue", ls=":", label="run threshold")
    ax.set_yscale("log")
    low, high = score_range([*scores, run_score, run_threshold], threshold)
    ax.set_ylim(10.0**low, 10.0**high)
    # plain numbers: figures draw no mathtext (report/plain_text.py), so no 10^k labels
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlim(0.4, scores.size + 0.6)
    ax.set_xlabel("cycle of the run")
    ax.set_ylabel("statistic T [-]")
    _legend_above(ax)
    _title(fig, "Per-cycle distance with supply fluctuation projected out", context)
    fig.tight_layout()
    return fig
