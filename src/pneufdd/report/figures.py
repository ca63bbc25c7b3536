"""Figures of the diagnosis report, rendered with matplotlib's Agg backend to PNG bytes.

- :func:`step_flow_figure`: per-step reference vs run mean of a channel and their
  difference (the style of Figs. 5.4-5.9, one value per step after lag removal);
- :func:`step_trace_figure`: step-aligned reference and run traces of the most
  affected steps and their difference (Figs. 5.7-5.9);
- :func:`band_figure`: the threshold band mean +/- eps sigma over the aligned cycle
  with the run's cycles (Fig. 5.13);
- :func:`statistic_figure`: the per-cycle statistic against its threshold.
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
from matplotlib.figure import Figure

from pneufdd.array_types import FloatArray
from pneufdd.files import atomic_target
from pneufdd.physics.units import kg_s_to_slpm, pa_to_psig
from pneufdd.report.plain_text import plain_text

__all__ = [
    "band_figure",
    "display_values",
    "save_figure",
    "statistic_figure",
    "step_flow_figure",
    "step_trace_figure",
    "to_png",
]


def display_values(values: npt.ArrayLike, unit: str) -> tuple[FloatArray, str]:
    """Convert SI values to the units an engineer reads: SLPM for flow, psig for pressure.

    Examples
    --------
    >>> v, u = display_values([0.001294 / 60.0 * 1000.0], "kg/s")
    >>> round(float(v[0]), 6), u
    (1000.0, 'SLPM')
    """
    arr = np.asarray(values, dtype=np.float64)
    if unit == "kg/s":
        return np.asarray(kg_s_to_slpm(arr), dtype=np.float64), "SLPM"
    if unit == "Pa":
        return np.asarray(pa_to_psig(arr), dtype=np.float64), "psig"
    if unit == "m":
        return arr * 1e3, "mm"
    return arr, unit


def display_delta(values: npt.ArrayLike, unit: str) -> tuple[FloatArray, str]:
    """Like :func:`display_values` for differences (no gauge offset)."""
    arr = np.asarray(values, dtype=np.float64)
    if unit == "Pa":
        return arr / 6894.757293168361, "psi"
    return display_values(arr, unit)


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
    """Render ``fig`` to PNG bytes and close it."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return buffer.getvalue()


@plain_text
def step_flow_figure(channel: str, unit: str, reference: FloatArray, run: FloatArray) -> Figure:
    """Per-step mean of ``channel``: reference, run and run minus reference.

    Parameters
    ----------
    channel : str
        Channel name.
    unit : str
        SI unit of the values.
    reference, run : ndarray, shape (n_steps,)
        Mean over the step, averaged over cycles [unit].
    """
    steps = np.arange(1, reference.size + 1)
    ref, label = display_values(reference, unit)
    new, _ = display_values(run, unit)
    diff, dlabel = display_delta(run - reference, unit)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
    top.step(steps, ref, where="mid", ls="--", color="tab:blue", label="reference")
    top.step(steps, new, where="mid", color="tab:red", label="run")
    top.set_ylabel(f"{channel} step mean [{label}]")
    top.legend(loc="upper right")
    bottom.bar(steps, diff, color="tab:green")
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_ylabel(f"run - reference [{dlabel}]")
    bottom.set_xlabel("step (each aligned at its own start, section 5.3.1.1)")
    fig.suptitle(f"{channel}: per-step comparison (style of Figs. 5.4-5.9)")
    return fig


@plain_text
def step_trace_figure(
    channel: str,
    unit: str,
    steps: Sequence[int],
    reference: Sequence[FloatArray],
    run: Sequence[FloatArray],
    rate_hz: float,
) -> Figure:
    """Step-aligned mean traces of a few steps with their difference (Figs. 5.7-5.9).

    Parameters
    ----------
    steps : sequence of int
        1-based step numbers.
    reference, run : sequence of ndarray
        Mean trace of each step from its start [unit].
    rate_hz : float
        Sample rate of the traces [Hz].
    """
    n = max(len(steps), 1)
    fig, axes = plt.subplots(1, n, figsize=(4 * n, 3.5), squeeze=False)
    for ax, step, ref, new in zip(axes[0], steps, reference, run, strict=False):
        t = np.arange(ref.size) / rate_hz
        r, label = display_values(ref, unit)
        x, _ = display_values(new, unit)
        d, _ = display_delta(new - ref, unit)
        ax.plot(t, r, "--", color="tab:blue", label="reference")
        ax.plot(t, x, color="tab:red", label="run")
        ax.plot(t, d, color="tab:green", label="difference")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(f"step {step}")
        ax.set_xlabel("time from step start [s]")
        ax.set_ylabel(f"{channel} [{label}]")
    axes[0][0].legend(loc="best", fontsize="small")
    fig.suptitle(f"{channel}: most affected steps after lag removal")
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
    fig, ax = plt.subplots(figsize=(10, 3.8))
    ax.fill_between(t, lo, hi, color="tab:blue", alpha=0.25, label=f"mean +/- {eps:g} sigma")
    ax.plot(t, m, color="tab:blue", lw=0.8, label="reference mean")
    for i, cycle in enumerate(np.atleast_2d(run)):
        c, _ = display_values(cycle, unit)
        ax.plot(t, c, color="tab:red", lw=0.5, alpha=0.6, label="run cycles" if i == 0 else None)
    for off in offsets[1:-1]:
        ax.axvline(off / rate_hz, color="0.85", lw=0.4, zorder=0)
    ax.set_xlabel("aligned cycle time (steps concatenated, each from its own start) [s]")
    ax.set_ylabel(f"{channel} [{label}]")
    ax.set_title(f"{channel}: threshold band of eq. 5.21 (style of Fig. 5.13)")
    ax.legend(loc="upper right", fontsize="small")
    return fig


@plain_text
def statistic_figure(
    scores: FloatArray, threshold: float, run_score: float, run_threshold: float
) -> Figure:
    """Per-cycle statistic against the per-cycle and run thresholds."""
    cycles = np.arange(1, scores.size + 1)
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.bar(cycles, scores, color=np.where(scores > threshold, "tab:red", "tab:gray"))
    ax.axhline(threshold, color="tab:red", ls="--", label="per-cycle threshold")
    ax.axhline(run_score, color="tab:blue", label="run statistic")
    ax.axhline(run_threshold, color="tab:blue", ls=":", label="run threshold")
    ax.set_yscale("log")
    ax.set_xlabel("cycle of the run")
    ax.set_ylabel("statistic T [-]")
    ax.set_title("Per-cycle distance with supply fluctuation projected out")
    ax.legend(loc="best", fontsize="small")
    return fig
