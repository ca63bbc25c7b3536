"""Mean, minimum and maximum of sample windows of one channel, compiled.

The step summaries of a diagnosis (:func:`pneufdd.features.step_summaries.build_step_table`)
reduce every channel over every step window of every cycle. Done with NumPy it takes a
running sum over the whole channel, a stacked copy of the channels and two
``reduceat`` passes, all under Python's global interpreter lock; the simulation check
of a diagnosis summarises 25-50 simulated runs on two threads, and this part did not
run in parallel at all (measured, issue 13: 11 ms per four-cycle festo-dsd run on one
thread and on two). :func:`window_summaries` is the same arithmetic in one compiled
function that releases the lock.

Same values, bit for bit, as the NumPy expressions (``tests/test_signals_windows.py``
keeps them as the oracle): the running sum is sequential from the first sample, as
``numpy.cumsum`` is; a window's mean is the difference of two running sums divided by
its length; a minimum or maximum is NaN if the window holds one (``numpy.minimum``
propagates NaN).

Importing this module loads numba; callers import it when they summarise.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["window_summaries"]

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


@njit(cache=True, nogil=True)
def _running_sums_at(x: F64, at: I64, skip_nan: bool, out: F64) -> float:
    """Running sums ``x[0] + ... + x[at[j] - 1]`` into ``out[j]``; returns the total.

    ``at`` ascending. The sum is sequential from the first sample, as ``numpy.cumsum``
    is (NaN counted as 0 with ``skip_nan``); no array of all running sums is made.
    """
    acc = 0.0
    j = 0
    for k in range(x.size + 1):
        while j < at.size and at[j] == k:
            out[j] = acc
            j += 1
        if k < x.size:
            v = x[k]
            if skip_nan and v != v:
                v = 0.0
            acc += v
    return acc


@njit(cache=True, nogil=True)
def window_summaries(x: F64, start: I64, end: I64, extreme_end: I64) -> F64:
    """Mean, minimum and maximum of ``x`` over each window; shape (windows, 3).

    Parameters
    ----------
    x : ndarray
        The channel's samples [channel unit].
    start, end : ndarray of int
        Each window's first sample and one past its last, for the mean:
        ``0 <= start < end <= x.size``, windows in ascending order, not overlapping
        (``start[i + 1] >= end[i]``).
    extreme_end : ndarray of int
        One past the last sample of each window for the minimum and maximum; a window
        with ``extreme_end <= start`` is its first sample alone (``numpy.ufunc.reduceat``).

    Returns
    -------
    ndarray
        Columns: mean, minimum, maximum [channel unit]. A running sum that is not
        finite at the end (a long gap left NaN) counts NaN as 0 for the means.
    """
    m = start.size
    at = np.empty(2 * m, dtype=np.int64)  # window bounds, ascending
    for i in range(m):
        at[2 * i] = start[i]
        at[2 * i + 1] = end[i]
    sums = np.empty(2 * m)
    if not np.isfinite(_running_sums_at(x, at, False, sums)):
        _running_sums_at(x, at, True, sums)
    out = np.empty((m, 3))
    for i in range(m):
        a = start[i]
        out[i, 0] = (sums[2 * i + 1] - sums[2 * i]) / (end[i] - a)
        lo = x[a]
        hi = x[a]
        for k in range(a + 1, extreme_end[i]):
            v = x[k]
            if v != v:  # NaN propagates, as numpy.minimum and numpy.maximum do
                lo = v
                hi = v
                break
            if v < lo:
                lo = v
            if v > hi:
                hi = v
        out[i, 1] = lo
        out[i, 2] = hi
    return out
