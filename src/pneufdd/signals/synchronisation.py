"""Synchronisation of cycles step by step (section 5.3.1.1, Figs. 5.6 -> 5.7).

A leak slows the motions it affects, and since every step waits for the previous
one's switches, the lag accumulates along the cycle: averaged raw data of a leaky
run drift away from the reference, and the difference of step 3 even turns negative
(Fig. 5.6). Cutting each cycle at its own step starts (the valve firings found by
:mod:`pneufdd.signals.segmentation`) aligns step j of every cycle with step j of the
reference and removes the accumulated lag (Fig. 5.7). Optionally, each step is
resampled to the reference's duration (time normalisation), so that every cycle
contributes the same number of samples to each step.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.segmentation import Cycle

__all__ = ["align_cycles", "reference_lengths", "sample_bounds", "synchronise"]


def _analog(recording: Recording, channel: str) -> tuple[FloatArray, float, float]:
    recording.require([channel], "synchronisation")
    ch = recording.info(channel)
    return np.asarray(ch.values, dtype=np.float64), ch.rate_hz, ch.t0


def _check(cycles: Sequence[Cycle]) -> int:
    if not cycles:
        raise InputError(describe("cycles", "none", "at least one cycle"))
    p = len(cycles[0].steps)
    if any(len(c.steps) != p for c in cycles):
        raise InputError(
            describe("cycles", "cycles with different step counts", "complete cycles only")
        )
    return p


def sample_bounds(cycles: Sequence[Cycle], fs: float, t0: float = 0.0) -> tuple[IntArray, IntArray]:
    """Sample index of every step's start and end on a channel's time base.

    Step ``[start_s, end_s)`` maps to samples ``ceil((start_s - t0) fs)`` up to (not
    including) ``ceil((end_s - t0) fs)``: the first sample at or after each edge.

    Returns
    -------
    start, end : ndarray of int, shape (cycles, steps)
    """
    p = _check(cycles)
    s = np.array([[st.start_s for st in c.steps] for c in cycles]).reshape(len(cycles), p)
    e = np.array([[st.end_s for st in c.steps] for c in cycles]).reshape(len(cycles), p)
    return (
        np.ceil((s - t0) * fs - 1e-9).astype(np.int64),
        np.ceil((e - t0) * fs - 1e-9).astype(np.int64),
    )


def reference_lengths(cycles: Sequence[Cycle], fs: float) -> IntArray:
    """Median length of each step over the reference cycles [samples]."""
    s, e = sample_bounds(cycles, fs)
    lengths: IntArray = np.asarray(np.round(np.median(e - s, axis=0)), dtype=np.int64)
    return lengths


def _gather(x: FloatArray, start: IntArray, length: IntArray, width: int) -> FloatArray:
    idx = start[:, None] + np.arange(width)[None, :]
    valid = (np.arange(width)[None, :] < length[:, None]) & (idx >= 0) & (idx < x.size)
    out = np.full(idx.shape, np.nan)
    out[valid] = x[idx[valid]]
    return out


def _resample(x: FloatArray, start: IntArray, length: IntArray, n_out: int) -> FloatArray:
    """Linear resampling of ``x[start:start+length]`` to ``n_out`` samples per row."""
    u = np.linspace(0.0, 1.0, n_out)[None, :]
    pos = u * np.maximum(length - 1, 0)[:, None]
    i = np.floor(pos).astype(np.int64)
    frac = pos - i
    lo = np.clip(start[:, None] + i, 0, x.size - 1)
    hi = np.clip(lo + 1, 0, x.size - 1)
    hi = np.where(i + 1 < length[:, None], hi, lo)
    out = x[lo] * (1.0 - frac) + x[hi] * frac
    out[(length < 1) | (start + length > x.size)] = np.nan
    return np.asarray(out, dtype=np.float64)


def synchronise(
    recording: Recording,
    channel: str,
    cycles: Sequence[Cycle],
    lengths: npt.ArrayLike | None = None,
) -> list[FloatArray]:
    """Cut every cycle into its steps, each aligned at its own start (Fig. 5.7).

    Parameters
    ----------
    recording : Recording
        The recording the cycles were found in.
    channel : str
        Analog channel to cut.
    cycles : sequence of Cycle
        Complete cycles (same number of steps).
    lengths : array_like of int, optional
        Time normalisation: resample step j of every cycle to ``lengths[j]`` samples
        (e.g. :func:`reference_lengths` of the reference run). Without it the steps
        keep their own lengths and are padded with NaN to the longest.

    Returns
    -------
    list of ndarray
        One ``(cycles, samples)`` array per step, in the channel's unit.

    Examples
    --------
    >>> from pneufdd.signals.segmentation import Cycle, RecordedStep as Step
    >>> rec = Recording.from_arrays({"Q": np.arange(10.0)}, 10.0, units={"Q": "kg/s"})
    >>> cyc = [Cycle(1, (Step(1, 0.0, 0.3, ("U_X_A",)), Step(2, 0.3, 0.5, ("U_X_B",)))),
    ...        Cycle(2, (Step(1, 0.5, 0.7, ("U_X_A",)), Step(2, 0.7, 1.0, ("U_X_B",))))]
    >>> [s.tolist() for s in synchronise(rec, "Q", cyc)][1]
    [[3.0, 4.0, nan], [7.0, 8.0, 9.0]]
    """
    x, fs, t0 = _analog(recording, channel)
    start, end = sample_bounds(cycles, fs, t0)
    length = end - start
    out = []
    if lengths is None:
        for j in range(start.shape[1]):
            out.append(_gather(x, start[:, j], length[:, j], int(length[:, j].max())))
        return out
    n_ref = np.asarray(lengths, dtype=np.int64)
    if n_ref.shape != (start.shape[1],) or np.any(n_ref < 1):
        raise InputError(
            describe("lengths", n_ref.tolist(), f"{start.shape[1]} positive sample counts")
        )
    for j in range(start.shape[1]):
        out.append(_resample(x, start[:, j], length[:, j], int(n_ref[j])))
    return out


def align_cycles(recording: Recording, channel: str, cycles: Sequence[Cycle]) -> FloatArray:
    """Raw cycles aligned at their first step only (no synchronisation, Fig. 5.6).

    Returns
    -------
    ndarray, shape (cycles, samples)
        Each row starts at its cycle's first valve firing; NaN-padded.
    """
    x, fs, t0 = _analog(recording, channel)
    start, end = sample_bounds(cycles, fs, t0)
    length = end[:, -1] - start[:, 0]
    return _gather(x, start[:, 0], length, int(length.max()))
