"""Ensemble statistics over repeated cycles (eq. 5.21) and the averaging window (4.4.1).

For signal type i and sample j of a (synchronised) step, over N cycles:

.. math::

    \\bar S_{i,j} = E\\{S_{i,j}\\}, \\qquad
    \\bar\\sigma_{i,j}^2 = E\\{[S_{i,j} - \\bar S_{i,j}]^2\\}    \\qquad (5.21)

Steps of different cycles have different lengths: they are aligned at the step
start and each sample's statistics use the cycles that cover it (their number is
reported as ``count``), ignoring NaN gaps. Section 5.3.1 averages 100 cycles;
section 4.4.1 keeps only the last five minutes of a run because the house-air supply
fluctuates at first: :func:`select_window` picks cycles by such a window.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.segmentation import Cycle
from pneufdd.signals.synchronisation import synchronise

__all__ = [
    "DEFAULT_WINDOW_S",
    "Ensemble",
    "ensemble",
    "reference_averages",
    "select_window",
    "step_ensembles",
]


DEFAULT_WINDOW_S = 300.0
"""Averaging window of section 4.4.1: the last five minutes of a run [s]."""


@dataclass(frozen=True)
class Ensemble:
    """Per-sample mean, standard deviation and number of contributing cycles.

    Attributes
    ----------
    mean : ndarray
        Mean over cycles, in the signal's unit (NaN where no cycle covers a sample).
    std : ndarray
        Standard deviation over cycles (population, ``ddof`` as requested).
    count : ndarray of int
        Number of cycles with a valid value at each sample.
    """

    mean: FloatArray
    std: FloatArray
    count: npt.NDArray[np.int64]


def ensemble(stack: npt.ArrayLike, ddof: int = 0) -> Ensemble:
    """Mean and standard deviation over the first axis (cycles), NaN-aware (eq. 5.21).

    Parameters
    ----------
    stack : array_like, shape (cycles, samples)
        Cycles aligned sample by sample; NaN marks missing samples.
    ddof : int
        Delta degrees of freedom of the standard deviation (0: the expectation
        of eq. 5.21; 1: the unbiased sample estimate).

    Returns
    -------
    Ensemble

    Examples
    --------
    >>> e = ensemble([[1.0, 2.0, np.nan], [3.0, 4.0, 5.0]])
    >>> e.mean.tolist(), e.std.tolist(), e.count.tolist()
    ([2.0, 3.0, 5.0], [1.0, 1.0, 0.0], [2, 2, 1])
    """
    a = np.asarray(stack, dtype=np.float64)
    if a.ndim != 2:
        raise InputError(describe("stack shape", a.shape, "(cycles, samples)"))
    valid = np.isfinite(a)
    count = valid.sum(axis=0).astype(np.int64)
    z = np.where(valid, a, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, z.sum(axis=0) / np.maximum(count, 1), np.nan)
        dev = np.where(valid, a - mean[None, :], 0.0)
        dof = count - ddof
        var = np.where(dof > 0, (dev**2).sum(axis=0) / np.maximum(dof, 1), np.nan)
    return Ensemble(mean, np.sqrt(var), count)


def select_window(
    cycles: Sequence[Cycle], window_s: float | None = DEFAULT_WINDOW_S, which: str = "last"
) -> tuple[Cycle, ...]:
    """Keep the cycles lying entirely in the first or last ``window_s`` of a run (4.4.1).

    Parameters
    ----------
    cycles : sequence of Cycle
        Candidate cycles (typically the complete ones).
    window_s : float or None
        Window length [s]; None keeps every cycle.
    which : {"last", "first"}
        Which end of the run the window sits at.

    Returns
    -------
    tuple of Cycle
    """
    if which not in ("last", "first"):
        raise InputError(describe("which", which, ["last", "first"]))
    cycles = tuple(cycles)
    if window_s is None or not cycles:
        return cycles
    if not window_s > 0:
        raise InputError(describe("window_s [s]", window_s, "> 0 or None"))
    if which == "last":
        edge = max(c.end_s for c in cycles) - window_s
        return tuple(c for c in cycles if c.start_s >= edge - 1e-9)
    edge = min(c.start_s for c in cycles) + window_s
    return tuple(c for c in cycles if c.end_s <= edge + 1e-9)


def step_ensembles(
    recording: Recording,
    channel: str,
    cycles: Sequence[Cycle],
    lengths: npt.ArrayLike | None = None,
    ddof: int = 0,
) -> list[Ensemble]:
    """Eq. 5.21 for every step of ``channel`` over the synchronised ``cycles``.

    Parameters
    ----------
    recording : Recording
        The recording the cycles were found in.
    channel : str
        Analog channel.
    cycles : sequence of Cycle
        Complete cycles (e.g. :func:`select_window` of ``Segmentation.complete``).
    lengths : array_like of int, optional
        Time normalisation to these step lengths [samples] (see
        :func:`pneufdd.signals.synchronisation.synchronise`).
    ddof : int
        Delta degrees of freedom of the standard deviation.

    Returns
    -------
    list of Ensemble
        One per step, in the channel's unit.
    """
    return [ensemble(s, ddof) for s in synchronise(recording, channel, cycles, lengths)]


def reference_averages(
    recording: Recording,
    channels: Sequence[str],
    cycles: Sequence[Cycle],
    window_s: float | None = DEFAULT_WINDOW_S,
    lengths: npt.ArrayLike | None = None,
    ddof: int = 0,
) -> dict[str, list[Ensemble]]:
    """Reference averages of section 5.3.1: per channel and step, eq. 5.21 over cycles.

    The cycles are first restricted to the averaging window of section 4.4.1 (the
    last ``window_s`` of the run; None keeps all), then synchronised step by step.

    Parameters
    ----------
    recording : Recording
        The reference (leak-free) run.
    channels : sequence of str
        Analog channels, e.g. the six signal types of eq. 5.21 (``P_DNC_A``,
        ``P_DNC_B``, ``Q_DNC_A``, ``Q_DNC_B``, ``Q_In``, ``P_In``).
    cycles : sequence of Cycle
        Complete cycles of the run.
    window_s : float or None
        Averaging window [s].
    lengths : array_like of int, optional
        Time normalisation to these step lengths [samples].
    ddof : int
        Delta degrees of freedom of the standard deviation.

    Returns
    -------
    dict of str to list of Ensemble
        Per channel, one :class:`Ensemble` per step.
    """
    chosen = select_window(cycles, window_s)
    if not chosen:
        raise InputError(
            describe("cycles in the averaging window", 0, f"at least one in the last {window_s} s")
        )
    return {ch: step_ensembles(recording, ch, chosen, lengths, ddof) for ch in channels}
