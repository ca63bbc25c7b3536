"""Samples as they arrive from a PLC, a broker or a replay, put back on a time grid.

A source delivers :class:`SampleBatch` objects: samples of one channel, either
uniformly spaced (``t0`` and ``rate_hz``: a DAQ block, a replay, an MQTT batch) or
with a time stamp each (``times``: OPC UA data changes, reported by exception).
:class:`SampleAssembler` places every sample on its channel's grid (``k = round((t -
origin) * rate)``) and releases the grid up to a **watermark**, the newest time seen
minus an allowed lateness. A grid sample no batch wrote holds the channel's previous
value (a PLC tag reports only its changes). Samples that arrive out of order but
before the watermark passes them are sorted in (and counted); samples older than what
was already released are counted as late, per channel, and dropped (never crashed
on); the span from the oldest of them to what was released is reported
(:attr:`SampleAssembler.late_spans`): the grid holds other values there, so the
cycles it touches must not be scored. Before the first release, a sample older than
the grid's origin is not late: it is the channel's value at the start (an OPC UA
subscription's first notification carries the time the tag last changed, which may be
long ago). NaN values inside a uniform
block are kept (sensor gaps; the step summaries fill them as for files). Memory is what arrived
since the last release.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.monitor.completeness import iso_time

__all__ = ["GridBlock", "SampleAssembler", "SampleBatch"]


class SampleBatch(NamedTuple):
    """Samples of one channel.

    A named tuple (immutable, cheap to make: a live stream delivers hundreds per
    machine cycle).

    Attributes
    ----------
    channel : str
        Channel name (``P_In``, ``U_DNC_A``, ...).
    values : ndarray
        Values in SI units (digital: 0/1).
    t0 : float
        Time of the first sample when ``times`` is None [s since 1970-01-01 UTC].
    rate_hz : float
        Sample rate when ``times`` is None [Hz].
    times : ndarray, optional
        Time of every sample [s since 1970-01-01 UTC].
    """

    channel: str
    values: FloatArray
    t0: float = 0.0
    rate_hz: float = 0.0
    times: FloatArray | None = None

    def sample_times(self) -> FloatArray:
        """Time of every sample [s since 1970-01-01 UTC]."""
        if self.times is not None:
            return np.asarray(self.times, dtype=np.float64)
        if not self.rate_hz > 0:
            raise InputError(
                describe(f"rate of samples of {self.channel!r} [Hz]", self.rate_hz, "> 0")
            )
        return self.t0 + np.arange(np.size(self.values)) / self.rate_hz


@dataclass
class GridBlock:
    """Grid samples released together: ``values[c]`` starts at grid index ``start[c]``."""

    start: dict[str, int]
    values: dict[str, FloatArray]


@dataclass
class _Pending:
    index: list[npt.NDArray[np.int64]] = field(default_factory=list)
    values: list[FloatArray] = field(default_factory=list)
    dense_start: int = -1  # grid index of dense_values[0]; -1: no dense run
    dense_values: list[FloatArray] = field(default_factory=list)
    dense_size: int = 0

    def spill(self) -> None:
        """Move the dense run into the general (index, value) lists."""
        if self.dense_size:
            values = np.concatenate(self.dense_values)
            self.index.append(self.dense_start + np.arange(values.size, dtype=np.int64))
            self.values.append(values)
        self.dense_start, self.dense_values, self.dense_size = -1, [], 0


class SampleAssembler:
    """Put samples of several channels on fixed grids and release them in time order.

    Parameters
    ----------
    rates_hz : mapping of str to float
        Grid rate of every channel that is kept [Hz]; other channels are ignored.
    lateness_s : float
        How long a sample may arrive after newer ones and still be used [s].

    Examples
    --------
    >>> a = SampleAssembler({"P": 10.0}, lateness_s=0.0)
    >>> a.add(SampleBatch("P", np.array([1.0, 2.0]), t0=100.0, rate_hz=10.0))
    >>> a.add(SampleBatch("P", np.array([5.0]), times=np.array([100.5])))
    >>> block = a.release()
    >>> block.start["P"], block.values["P"].tolist()
    (0, [1.0, 2.0, 2.0, 2.0, 2.0, 5.0])
    >>> a.add(SampleBatch("P", np.array([9.0]), times=np.array([100.2])))  # too late
    >>> a.late_samples
    1
    """

    def __init__(self, rates_hz: Mapping[str, float], lateness_s: float = 1.0) -> None:
        for name, rate in rates_hz.items():
            if not (math.isfinite(rate) and rate > 0):
                raise InputError(describe(f"grid rate of channel {name!r} [Hz]", rate, "> 0"))
        self.rates_hz = dict(rates_hz)
        self.lateness_s = float(lateness_s)
        self.origin: float | None = None
        self.newest = -math.inf
        self.late_samples = 0
        self.late_by_channel: dict[str, int] = {}
        self.last_late_s = math.nan  # time stamp of the newest late sample [s since 1970]
        self.late_spans: list[tuple[str, float, float]] = []
        """(channel, from, to) [s since 1970] of late samples dropped, for the caller to
        mark lost (:class:`~pneufdd.monitor.completeness.LossLedger`) and clear."""
        self.out_of_order = 0
        self._released = False
        self._newest_of: dict[str, float] = {}
        self._next: dict[str, int] = dict.fromkeys(self.rates_hz, 0)
        self._last: dict[str, float] = {}
        self._pending: dict[str, _Pending] = {name: _Pending() for name in self.rates_hz}

    def add(self, batch: SampleBatch) -> None:
        """Take a batch (unknown channels are ignored; NaN times are dropped)."""
        rate = self.rates_hz.get(batch.channel)
        if rate is None:
            return
        values = batch.values
        if type(values) is not np.ndarray or values.dtype != np.float64 or values.ndim != 1:
            values = np.asarray(values, dtype=np.float64).ravel()
        if values.size == 0:
            return
        if (
            batch.times is None
            and batch.rate_hz == rate
            and self.origin is not None
            and self._add_dense(batch.channel, values, batch.t0, rate)
        ):
            return
        times = batch.sample_times()
        if times.shape != values.shape:
            raise InputError(
                describe(f"time stamps of {batch.channel!r}", times.shape, [values.shape])
            )
        ok = np.isfinite(times)
        times, values = times[ok], values[ok]
        if times.size == 0:
            return
        if self.origin is None:
            self.origin = float(np.min(times))
        channel = batch.channel
        newest = float(np.max(times))
        before = self._newest_of.get(channel, -math.inf)
        if newest > before:
            self._newest_of[channel] = newest
        self.out_of_order += int(np.count_nonzero(times < before)) + int(
            np.count_nonzero(np.diff(times) < 0)
        )
        self.newest = max(self.newest, newest)
        index = np.round((times - self.origin) * rate).astype(np.int64)
        late = index < self._next[channel]
        if np.any(late):
            if not self._released:
                # before the first release: the value the channel had at the start
                self._last[channel] = float(values[late][np.argmax(times[late])])
            else:
                count = int(np.sum(late))
                self.late_samples += count
                self.late_by_channel[channel] = self.late_by_channel.get(channel, 0) + count
                self.last_late_s = float(np.max(times[late]))
                # the grid already holds other values there (held ones): from the oldest
                # late sample to what was released, the channel is not what was received
                released = self.time_of(channel, self._next[channel] - 1)
                self.late_spans.append((channel, float(np.min(times[late])), released))
            index, values = index[~late], values[~late]
            if index.size == 0:
                return
        pending = self._pending[channel]
        pending.spill()
        pending.index.append(index)
        pending.values.append(values)

    def _add_dense(self, channel: str, values: FloatArray, t0: float, rate: float) -> bool:
        """Append a uniform batch that continues the channel's samples exactly (fast path)."""
        exact = (t0 - (self.origin or 0.0)) * rate
        start = round(exact)
        if abs(exact - start) > 1e-3:
            return False
        pending = self._pending[channel]
        if pending.dense_size:
            expected = pending.dense_start + pending.dense_size
        else:
            expected = -1 if pending.index else self._next[channel]
        if start != expected:
            return False
        if not pending.dense_size:
            pending.dense_start = start
        pending.dense_values.append(values)
        pending.dense_size += values.size
        last = t0 + (values.size - 1) / rate
        self._newest_of[channel] = last
        if last > self.newest:
            self.newest = last
        return True

    @property
    def watermark_s(self) -> float:
        """Time up to which :meth:`release` would release [s after the origin].

        Minus infinity before the first sample.
        """
        if self.origin is None:
            return -math.inf
        return self.newest - self.lateness_s - self.origin

    def late_message(self) -> str:
        """One line about the late samples dropped so far (for the console)."""
        parts = ", ".join(f"{c}: {n}" for c, n in sorted(self.late_by_channel.items()))
        return (
            f"{self.late_samples} late samples dropped ({parts}): their time stamps are "
            f"older than the data already used (newest sample {iso_time(self.newest)}, newest "
            f"late one {iso_time(self.last_late_s)}, lateness_s {self.lateness_s:g} s); a source "
            "clock behind the others, or one that jumped back, loses its samples"
        )

    def time_of(self, channel: str, index: int) -> float:
        """Time of grid sample ``index`` of ``channel`` [s since 1970-01-01 UTC]."""
        return (self.origin or 0.0) + index / self.rates_hz[channel]

    def release(self, final: bool = False) -> GridBlock | None:
        """Grid samples up to the watermark (all that arrived when ``final``).

        Returns None until every channel has had a value.
        """
        if self.origin is None:
            return None
        if len(self._last) < len(self.rates_hz):
            for name, pending in self._pending.items():
                if name not in self._last and pending.dense_size:
                    self._last[name] = float(pending.dense_values[0][0])
                elif name not in self._last and pending.index:
                    idx = np.concatenate(pending.index)
                    vals = np.concatenate(pending.values)
                    self._last[name] = float(vals[int(np.argmin(idx))])
            if len(self._last) < len(self.rates_hz):
                return None
        self._released = True
        mark = self.newest - (0.0 if final else self.lateness_s)
        start: dict[str, int] = {}
        values: dict[str, FloatArray] = {}
        for name, rate in self.rates_hz.items():
            first = self._next[name]
            last = math.floor((mark - self.origin) * rate + 1e-9)
            count = last - first + 1
            if count <= 0:
                start[name], values[name] = first, np.zeros(0)
                continue
            pending = self._pending[name]
            if pending.dense_size and not pending.index and pending.dense_start == first:
                run = (
                    np.concatenate(pending.dense_values)
                    if len(pending.dense_values) > 1
                    else pending.dense_values[0]
                )
                if run.size >= count:
                    start[name], values[name] = first, run[:count]
                    rest = run[count:]
                    pending.dense_start = first + count if rest.size else -1
                    pending.dense_values = [rest] if rest.size else []
                    pending.dense_size = rest.size
                    self._last[name] = float(run[count - 1])
                    self._next[name] = last + 1
                    continue
            pending.spill()
            out = np.full(count, np.nan)
            keep_index: list[npt.NDArray[np.int64]] = []
            keep_values: list[FloatArray] = []
            if pending.index:
                idx = np.concatenate(pending.index)
                vals = np.concatenate(pending.values)
                now = idx <= last
                out[idx[now] - first] = vals[now]
                if not np.all(now):
                    keep_index, keep_values = [idx[~now]], [vals[~now]]
            pending.index, pending.values = keep_index, keep_values
            if keep_index and _continues(keep_index[0], last + 1):
                # what waits is one contiguous run: back on the fast path, so one
                # jittered or late batch does not slow the channel for good
                pending.index, pending.values = [], []
                pending.dense_start = last + 1
                pending.dense_values, pending.dense_size = keep_values, keep_values[0].size
            # hold the previous value where no sample landed (report by exception)
            filled = ~np.isnan(out)
            where = np.where(filled, np.arange(count), -1)
            np.maximum.accumulate(where, out=where)
            held = np.where(where >= 0, out[np.maximum(where, 0)], self._last[name])
            self._last[name] = float(held[-1])
            start[name], values[name] = first, held
            self._next[name] = last + 1
        return GridBlock(start, values)


def _continues(index: npt.NDArray[np.int64], start: int) -> bool:
    """Whether ``index`` is exactly ``start, start + 1, ...`` (a contiguous run)."""
    return bool(index[0] == start and np.all(np.diff(index) == 1))
