"""Digital (PLC I/O) signal conditioning: debouncing and edge detection.

Valve solenoid and proximity-switch channels are sampled at 100 Hz on the
dissertation's rig (section 3.2.4). Reed switches chatter when the piston magnet
arrives (section 3.2.4, SME-8 reed principle), so a state is accepted only when it
lasts a minimum dwell time, and a bouncing transition is dated at its first contact.
Everything here is vectorised with numpy: the run-length encoding of a channel is
computed once and short runs are absorbed into the next accepted state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import IntArray
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording

__all__ = ["Edges", "debounce", "debounced_edges", "debounced_edges_many", "edge_times", "edges"]


def debounce(values: npt.ArrayLike, fs: float, min_dwell_s: float) -> npt.NDArray[np.uint8]:
    """Remove states that last less than a minimum dwell time.

    A run of equal samples shorter than ``min_dwell_s`` (``run_length / fs <
    min_dwell_s``) is chatter: it takes the state of the next accepted run, so a
    bouncing transition is dated at its first contact (a reed switch closes when the
    magnet arrives and then bounces); short runs at the end of the data take the
    state before them. The first run is kept whatever its length, as the recording's
    start cuts it.

    Parameters
    ----------
    values : array_like
        Digital samples, 0 or 1.
    fs : float
        Sample rate [Hz].
    min_dwell_s : float
        Minimum time a state must last to be accepted [s]; 0 disables debouncing.

    Returns
    -------
    ndarray of uint8
        The debounced samples.

    Examples
    --------
    >>> debounce([0, 0, 0, 1, 0, 1, 1, 1, 0, 1, 1, 1], fs=100.0, min_dwell_s=0.025)
    array([0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1], dtype=uint8)
    """
    return debounced_edges(values, fs, min_dwell_s)[0]


def _check_dwell(fs: float, min_dwell_s: float) -> None:
    if not (math.isfinite(fs) and fs > 0):
        raise InputError(describe("fs [Hz]", fs, "> 0"))
    if not (math.isfinite(min_dwell_s) and min_dwell_s >= 0):
        raise InputError(describe("min_dwell_s [s]", min_dwell_s, ">= 0"))


def _absorb_short_runs(
    x: npt.NDArray[np.uint8], changes: IntArray, fs: float, min_dwell_s: float
) -> npt.NDArray[np.uint8]:
    """``x`` with its short runs absorbed (``x`` itself when no run is short)."""
    bounds = np.empty(changes.size + 2, dtype=np.int64)
    bounds[0], bounds[-1] = 0, x.size
    bounds[1:-1] = changes
    starts = bounds[:-1]
    lengths = bounds[1:] - starts
    keep = lengths / fs >= min_dwell_s - 1e-12
    keep[0] = True
    if keep.all():
        return x
    runs = np.arange(starts.size)
    # Index of the next accepted run (backward fill); none after: the previous one.
    following = np.where(keep, runs, starts.size)
    following = np.minimum.accumulate(following[::-1])[::-1]
    previous = np.maximum.accumulate(np.where(keep, runs, 0))
    source = np.where(following < starts.size, following, previous)
    run_values = x[starts][source]
    return np.repeat(run_values, lengths).astype(np.uint8)


@dataclass(frozen=True)
class Edges:
    """Sample indices of the transitions of one digital channel.

    Attributes
    ----------
    rising : ndarray of int
        Index of the first sample at 1 after each 0 -> 1 transition.
    falling : ndarray of int
        Index of the first sample at 0 after each 1 -> 0 transition.
    """

    rising: IntArray
    falling: IntArray


def edges(values: npt.ArrayLike) -> Edges:
    """Find the rising and falling edges of a digital channel.

    The edge is placed at the first sample that shows the new state, i.e. the
    transition happened at most one sample period earlier.

    Examples
    --------
    >>> e = edges([0, 1, 1, 0, 1])
    >>> e.rising.tolist(), e.falling.tolist()
    ([1, 4], [3])
    """
    x = np.asarray(values).astype(np.int8)
    d = np.diff(x)
    return Edges(
        rising=(np.flatnonzero(d > 0) + 1).astype(np.int64),
        falling=(np.flatnonzero(d < 0) + 1).astype(np.int64),
    )


def edge_times(
    recording: Recording, name: str
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Times of the rising and falling edges of one digital channel of a recording [s].

    An edge is dated at the first sample that shows the new state (:func:`edges`);
    a sample counts as on above 0.5. A channel the recording lacks has no edges.
    """
    if name not in recording.channels:
        return np.zeros(0), np.zeros(0)
    t, values = recording.channel(name)
    e = edges(np.asarray(values) > 0.5)
    times = np.asarray(t, dtype=np.float64)
    return times[e.rising], times[e.falling]


def debounced_edges(
    values: npt.ArrayLike, fs: float, min_dwell_s: float
) -> tuple[npt.NDArray[np.uint8], Edges]:
    """:func:`debounce` and then :func:`edges`, sharing one run-length encoding.

    Same results as ``clean = debounce(values, fs, min_dwell_s)`` followed by
    ``edges(clean)``, in fewer passes over the samples (one channel of
    :func:`debounced_edges_many`).

    Returns
    -------
    clean : ndarray of uint8
        The debounced samples.
    edges : Edges
        Their rising and falling edges.

    Examples
    --------
    >>> clean, e = debounced_edges([0, 0, 1, 0, 1, 1, 1, 0, 0, 0], 100.0, 0.025)
    >>> clean.tolist(), e.rising.tolist(), e.falling.tolist()
    ([0, 0, 1, 1, 1, 1, 1, 0, 0, 0], [2], [7])
    """
    x = np.asarray(values)
    if x.ndim != 1:
        raise InputError(describe("shape of a digital channel", x.shape, "(samples,)"))
    clean, (found,) = debounced_edges_many(x[None, :], fs, min_dwell_s)
    return clean[0], found


def debounced_edges_many(
    values: npt.ArrayLike, fs: float, min_dwell_s: float
) -> tuple[npt.NDArray[np.uint8], list[Edges]]:
    """:func:`debounced_edges` of every row of a 2-D array (channels on one time base).

    Each row is debounced as :func:`debounce` says; all channels share one pass of
    numpy operations when no row has a short run (the usual case: a PLC's channels
    rarely chatter), so a segmentation costs a few operations instead of a few per
    channel. :func:`debounce` and :func:`debounced_edges` are its one-channel forms.

    Parameters
    ----------
    values : array_like, shape (channels, samples)
        Digital samples, 0 or 1.
    fs : float
        Sample rate [Hz].
    min_dwell_s : float
        Minimum time a state must last to be accepted [s].

    Returns
    -------
    clean : ndarray of uint8, shape (channels, samples)
    edges : list of Edges, one per channel

    Examples
    --------
    >>> clean, e = debounced_edges_many([[0, 0, 1, 1, 1], [1, 1, 0, 1, 1]], 100.0, 0.015)
    >>> clean.tolist()  # the second channel's one-sample dip is chatter
    [[0, 0, 1, 1, 1], [1, 1, 1, 1, 1]]
    >>> [(x.rising.tolist(), x.falling.tolist()) for x in e]
    [([2], []), ([], [])]
    """
    x = np.array(values, dtype=np.uint8, ndmin=2)
    if x.ndim != 2:
        raise InputError(describe("shape of digital channels", x.shape, "(channels, samples)"))
    _check_dwell(fs, min_dwell_s)
    n_rows, n = x.shape
    rows, cols = _change_points_2d(x)
    if min_dwell_s > 0 and cols.size:
        following = np.empty_like(cols)
        following[:-1] = cols[1:]
        following[-1] = n
        following[np.flatnonzero(rows[1:] != rows[:-1])] = n  # a row's last run ends at n
        short = (following - cols) / fs < min_dwell_s - 1e-12
        if short.any():
            for r in np.unique(rows[short]).tolist():
                x[r] = _absorb_short_runs(x[r], cols[rows == r], fs, min_dwell_s)
            rows, cols = _change_points_2d(x)
    up = x[rows, cols] == 1
    bounds = np.searchsorted(rows, np.arange(n_rows + 1)).tolist()
    out = []
    for r in range(n_rows):
        c, u = cols[bounds[r] : bounds[r + 1]], up[bounds[r] : bounds[r + 1]]
        out.append(Edges(rising=c[u], falling=c[~u]))
    return x, out


def _change_points_2d(x: npt.NDArray[np.uint8]) -> tuple[IntArray, IntArray]:
    """Row and first-sample index of every run after each row's first (row-major order)."""
    rows, cols = np.nonzero(x[:, 1:] != x[:, :-1])
    return rows.astype(np.int64, copy=False), cols.astype(np.int64, copy=False) + 1
