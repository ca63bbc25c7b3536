"""The narrow input of the diagnosis layer: a :class:`StepTable`.

A step table holds, for every complete machine cycle and every PLC step, the step's
start and end time and a few summaries of each analog channel over the step (mean,
minimum, maximum), plus optional step-aligned traces for the band method of
section 5.3.2. Each step is aligned at its own start, which is the lag removal of
section 5.3.1.1 (Figs. 5.6 -> 5.7): step ``j`` of any cycle is comparable with step
``j`` of the reference whatever delay the earlier steps accumulated.

The diagnosis engine only ever sees step tables; turning a
:class:`~pneufdd.recording.Recording` into one is the job of a thin adapter
(:mod:`pneufdd.features.step_summaries`) over the segmentation of :mod:`pneufdd.signals`,
with the PLC sequence of :func:`pneufdd.signals.segmentation.plc_sequence`.

How it relates to the feature registry (:mod:`pneufdd.features.registry`): the
registry's named features (motion times, air per stroke, Table 4.4, wavelets) are
computed by :func:`pneufdd.features.feature_matrix` for the classifiers, the
evaluation and the ``pneufdd features`` command; the step table is the diagnosis's
and the monitor's feature set. Its columns (:func:`feature_names`: ``duration@j`` and
``<channel>.<mean|min|max>@j`` for every analog channel of the sensor set) are not
registered features, so a feature added to the registry does not change what
``diagnose`` sees, and ``pneufdd features`` does not output these columns. Per-cycle
quantities the monitor records come from here too (:meth:`StepTable.cycle_integral`:
supply air; :meth:`StepTable.cycle_mean`: supply pressure).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.errors import ChannelError, InputError, describe

__all__ = [
    "STATISTICS",
    "StepTable",
    "feature_floor",
    "feature_names",
]


STATISTICS: tuple[str, ...] = ("mean", "min", "max")
"""Per-step summaries of every analog channel, in this order."""

_FLOOR_BY_UNIT: dict[str, float] = {
    "Pa": 50.0,  # pressure transducer resolution, about 0.007 psi [Pa]
    "kg/s": 2.0e-6,  # about 0.1 SLPM [kg/s]
    "m": 1.0e-5,  # LVDT resolution [m]
    "s": 3.0e-3,  # a 100 Hz digital edge is known to +-5 ms; uniform -> 2.9 ms [s]
}


def feature_floor(unit: str) -> float:
    """Smallest standard deviation a feature in ``unit`` is given.

    A feature that never varies over the reference cycles (a timer step, a flow that
    is always zero) would otherwise get a zero spread and an infinite standardised
    distance. The floor is the resolution of the quantity's sensor.

    Parameters
    ----------
    unit : str
        SI unit of the feature.

    Returns
    -------
    float
        Floor of the standard deviation [unit].

    Examples
    --------
    >>> feature_floor("s")
    0.003
    """
    return _FLOOR_BY_UNIT.get(unit, 1e-9)


def feature_names(channels: Sequence[str], n_steps: int) -> tuple[str, ...]:
    """Names of the flattened per-cycle feature vector of :meth:`StepTable.features`.

    The order is: step durations, then for each channel and statistic the value of
    every step. Steps are numbered from 1 as in the dissertation.

    Examples
    --------
    >>> feature_names(["Q_In"], 2)
    ('duration@1', 'duration@2', 'Q_In.mean@1', 'Q_In.mean@2', 'Q_In.min@1', 'Q_In.min@2', \
'Q_In.max@1', 'Q_In.max@2')
    """
    names = [f"duration@{j + 1}" for j in range(n_steps)]
    for channel in channels:
        for stat in STATISTICS:
            names.extend(f"{channel}.{stat}@{j + 1}" for j in range(n_steps))
    return tuple(names)


def _as_float(name: str, value: object, ndim: int) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != ndim:
        raise InputError(describe(f"dimensions of {name}", arr.ndim, [ndim]))
    return arr


@dataclass(frozen=True, eq=False)
class StepTable:
    """Per complete cycle and per PLC step: timing, analog summaries and aligned traces.

    Attributes
    ----------
    machine : str
        Name of the machine the cycles come from.
    step_start : ndarray, shape (n_cycles, n_steps)
        Start of each step (its valve firing) after the recording's start [s].
    step_end : ndarray, shape (n_cycles, n_steps)
        End of each step [s]; ``step_end - step_start`` is the step duration.
    channels : tuple of str
        Analog channels summarised (may be empty: digital signals only).
    units : tuple of str
        SI unit of each channel.
    summaries : ndarray, shape (n_cycles, n_steps, n_channels, 3)
        Mean, minimum and maximum of each channel over each step [channel unit].
    traces : ndarray, shape (n_cycles, n_channels, n_samples), optional
        Step-aligned traces: step ``j`` occupies samples
        ``trace_offsets[j]:trace_offsets[j + 1]``, starting at the step's own start
        (lag removed, section 5.3.1.1); samples past a step's end are NaN.
    trace_offsets : ndarray of int, shape (n_steps + 1,), optional
        Start sample of each step in ``traces``.
    trace_rate_hz : float
        Sample rate of ``traces`` [Hz].
    cycle_index : ndarray of int, shape (n_cycles,)
        Number of each cycle in its recording (0-based).
    skipped_cycles : tuple of (int, str)
        Complete cycles left out by the gap rule (:mod:`pneufdd.signals.quality`):
        each one's number in its recording and the channel whose gap skipped it.
    repaired_gaps : int
        Short gaps repaired by interpolation in the summarised channels.
    """

    machine: str
    step_start: FloatArray
    step_end: FloatArray
    channels: tuple[str, ...]
    units: tuple[str, ...]
    summaries: FloatArray
    traces: FloatArray | None = None
    trace_offsets: IntArray | None = None
    trace_rate_hz: float = 100.0
    cycle_index: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    skipped_cycles: tuple[tuple[int, str], ...] = ()
    repaired_gaps: int = 0

    def __post_init__(self) -> None:
        start = _as_float("step_start", self.step_start, 2)
        end = _as_float("step_end", self.step_end, 2)
        if start.shape != end.shape:
            raise InputError(describe("shape of step_end", end.shape, [start.shape]))
        if not (np.all(np.isfinite(start)) and np.all(np.isfinite(end))):
            raise InputError(describe("step times", "NaN or infinite values", "finite times"))
        if np.any(end < start):
            raise InputError(
                describe("step times", "a step ending before it starts", "end >= start")
            )
        n_cycles, n_steps = start.shape
        channels = tuple(self.channels)
        units = tuple(self.units)
        if len(units) != len(channels):
            raise InputError(describe("number of units", len(units), [len(channels)]))
        if len(set(channels)) != len(channels):
            raise ChannelError(describe("channels", channels, "each channel once"))
        summaries = _as_float("summaries", self.summaries, 4)
        expected = (n_cycles, n_steps, len(channels), len(STATISTICS))
        if summaries.shape != expected:
            raise InputError(describe("shape of summaries", summaries.shape, [expected]))
        traces = self.traces
        offsets = self.trace_offsets
        if (traces is None) != (offsets is None):
            raise InputError(
                describe("traces and trace_offsets", "only one of them", "both or neither")
            )
        if traces is not None and offsets is not None:
            traces = _as_float("traces", traces, 3)
            offsets = np.asarray(offsets, dtype=np.int64)
            if offsets.shape != (n_steps + 1,) or offsets[0] != 0 or np.any(np.diff(offsets) < 1):
                raise InputError(
                    describe("trace_offsets", offsets.shape, f"({n_steps + 1},) increasing from 0")
                )
            if traces.shape != (n_cycles, len(channels), int(offsets[-1])):
                raise InputError(
                    describe(
                        "shape of traces",
                        traces.shape,
                        [(n_cycles, len(channels), int(offsets[-1]))],
                    )
                )
        index = np.asarray(self.cycle_index, dtype=np.int64)
        if index.size == 0:
            index = np.arange(n_cycles, dtype=np.int64)
        if index.shape != (n_cycles,):
            raise InputError(describe("shape of cycle_index", index.shape, [(n_cycles,)]))
        for name, value in (
            ("step_start", start),
            ("step_end", end),
            ("summaries", summaries),
            ("traces", traces),
            ("trace_offsets", offsets),
            ("cycle_index", index),
        ):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "units", units)

    # ---------------------------------------------------------------- shape
    @property
    def n_cycles(self) -> int:
        """Number of complete cycles."""
        return int(self.step_start.shape[0])

    @property
    def n_steps(self) -> int:
        """Number of PLC steps per cycle."""
        return int(self.step_start.shape[1])

    @property
    def durations(self) -> FloatArray:
        """Step durations, shape (n_cycles, n_steps) [s]."""
        return self.step_end - self.step_start

    # ------------------------------------------------------------- features
    def feature_names(self) -> tuple[str, ...]:
        """Names of the columns of :meth:`features`."""
        return feature_names(self.channels, self.n_steps)

    def feature_units(self) -> tuple[str, ...]:
        """SI unit of each column of :meth:`features`."""
        units = ["s"] * self.n_steps
        for unit in self.units:
            units.extend([unit] * (self.n_steps * len(STATISTICS)))
        return tuple(units)

    def features(self) -> FloatArray:
        """Per-cycle feature matrix: durations, then each channel's step summaries.

        Returns
        -------
        ndarray, shape (n_cycles, n_steps * (1 + 3 * n_channels))
            One row per cycle, columns named by :meth:`feature_names` [SI units].
        """
        # (cycles, steps, channels, stats) -> (cycles, channels, stats, steps)
        per_channel = np.transpose(self.summaries, (0, 2, 3, 1)).reshape(self.n_cycles, -1)
        return np.concatenate([self.durations, per_channel], axis=1)

    # ------------------------------------------------------- per cycle
    def cycle_integral(self, channel: str) -> FloatArray:
        """Per cycle: ``channel`` integrated over the cycle from its step means.

        .. math:: I_c = \\sum_j \\bar{x}_{c,j} \\, (t^{end}_{c,j} - t^{start}_{c,j})

        For a mass flow (``Q_In`` [kg/s]) this is the air the cycle took [kg], the
        per-cycle form of eq. 4.17 the monitor records.

        Parameters
        ----------
        channel : str
            An analog channel of the table.

        Returns
        -------
        ndarray, shape (n_cycles,)
            The integral [channel unit * s].

        Raises
        ------
        ChannelError
            If the channel is not in the table.

        Examples
        --------
        >>> t = StepTable("m", np.array([[0.0, 1.0]]), np.array([[1.0, 3.0]]), ("Q_In",),
        ...               ("kg/s",), np.array([[[[2.0, 0, 0]], [[0.5, 0, 0]]]]))
        >>> t.cycle_integral("Q_In")
        array([3.])
        """
        means = self.summaries[:, :, self._column(channel), 0]
        return np.asarray(np.sum(means * self.durations, axis=1))

    def cycle_mean(self, channel: str) -> FloatArray:
        """Per cycle: the mean of ``channel``'s step means (every step weighs the same).

        Returns
        -------
        ndarray, shape (n_cycles,)
            [channel unit]

        Raises
        ------
        ChannelError
            If the channel is not in the table.
        """
        return np.asarray(np.mean(self.summaries[:, :, self._column(channel), 0], axis=1))

    def _column(self, channel: str) -> int:
        if channel not in self.channels:
            raise ChannelError(
                describe("analog channel not in the step table", channel, self.channels)
            )
        return self.channels.index(channel)

    # ------------------------------------------------------------ subsets
    def select(self, channels: Sequence[str]) -> StepTable:
        """Keep only the analog ``channels`` (the PLC's step timing is always kept).

        Raises
        ------
        ChannelError
            If a channel is not in the table; the message lists those there are.
        """
        missing = [c for c in channels if c not in self.channels]
        if missing:
            raise ChannelError(
                describe("analog channel(s) not in the recording", missing, self.channels)
            )
        idx = [self.channels.index(c) for c in channels]
        return StepTable(
            machine=self.machine,
            step_start=self.step_start,
            step_end=self.step_end,
            channels=tuple(channels),
            units=tuple(self.units[i] for i in idx),
            summaries=self.summaries[:, :, idx, :],
            traces=None if self.traces is None else self.traces[:, idx, :],
            trace_offsets=self.trace_offsets,
            trace_rate_hz=self.trace_rate_hz,
            cycle_index=self.cycle_index,
        )

    def take(self, cycles: Sequence[int] | IntArray) -> StepTable:
        """Keep only the cycles at positions ``cycles`` (0-based rows of this table)."""
        rows = np.asarray(cycles, dtype=np.int64)
        return StepTable(
            machine=self.machine,
            step_start=self.step_start[rows],
            step_end=self.step_end[rows],
            channels=self.channels,
            units=self.units,
            summaries=self.summaries[rows],
            traces=None if self.traces is None else self.traces[rows],
            trace_offsets=self.trace_offsets,
            trace_rate_hz=self.trace_rate_hz,
            cycle_index=self.cycle_index[rows],
        )

    @staticmethod
    def concatenate(tables: Sequence[StepTable]) -> StepTable:
        """Stack the cycles of several tables of the same machine and channels."""
        if not tables:
            raise InputError(describe("step tables", 0, "at least one"))
        first = tables[0]
        for other in tables[1:]:
            if other.channels != first.channels or other.n_steps != first.n_steps:
                raise InputError(
                    describe(
                        "step table to concatenate",
                        f"{other.n_steps} steps, channels {other.channels}",
                        f"{first.n_steps} steps, channels {first.channels}",
                    )
                )
            if other.machine != first.machine:
                raise InputError(describe("machine", other.machine, [first.machine]))
        with_traces = all(t.traces is not None for t in tables) and all(
            np.array_equal(t.trace_offsets, first.trace_offsets)  # type: ignore[arg-type]
            for t in tables
        )
        return StepTable(
            machine=first.machine,
            step_start=np.concatenate([t.step_start for t in tables]),
            step_end=np.concatenate([t.step_end for t in tables]),
            channels=first.channels,
            units=first.units,
            summaries=np.concatenate([t.summaries for t in tables]),
            traces=(
                np.concatenate([t.traces for t in tables if t.traces is not None])
                if with_traces
                else None
            ),
            trace_offsets=first.trace_offsets if with_traces else None,
            trace_rate_hz=first.trace_rate_hz,
            cycle_index=np.concatenate([t.cycle_index for t in tables]),
        )
