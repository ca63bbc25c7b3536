"""Incremental cycle segmentation: grid samples in, completed and summarised cycles out.

The streamer keeps a short buffer of grid samples (from a little before the last
completed cycle's end to now) and segments it with the reference's PLC sequence
exactly as :func:`pneufdd.diagnosis.recordings.run_table` segments a file
(:func:`pneufdd.signals.segmentation.segment`, then
:func:`pneufdd.features.step_summaries.build_step_table`). A cycle is complete when a
later step has started (its last step ends at the next step's start, section
5.3.1.1); then it is summarised, the buffer is cut just before its end, and the
cycle is passed on. At the end of a replay the last cycle is closed as a file's last
cycle is (:mod:`pneufdd.signals.final_step`).

Memory is bounded: the buffer never holds more than ``max_buffer_cycles`` cycle
durations of samples; when the machine stops or the signals make no sense for that
long, the oldest samples are dropped and counted (``dropped_s``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError, describe
from pneufdd.features.step_summaries import build_step_table, sequence_from_records
from pneufdd.features.step_table import StepTable
from pneufdd.monitor.samples import GridBlock
from pneufdd.recording.model import ANALOG, DIGITAL, Channel, Recording
from pneufdd.signals.segmentation import Cycle, StepSpec, segment

__all__ = ["CompletedCycle", "CycleStreamer", "needed_channels"]

MARGIN_S = 0.2
"""Samples kept before the last completed cycle's end [s]."""


def needed_channels(model: ReferenceModel) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Analog channels of the reference's sensor set, and the PLC signals segmentation uses."""
    sequence = sequence_from_records(model.sequence) if model.sequence else ()
    if not sequence:
        raise InputError(
            describe(
                f"PLC sequence of reference {model.machine!r}",
                None,
                "a reference that stores its sequence (rebuild it with pneufdd reference build)",
            )
        )
    digital: set[str] = set()
    for spec in sequence:
        digital |= {v.removesuffix(":off") for v in spec.valves}
        digital |= {name for name, _ in spec.switches}
    return tuple(model.channels), tuple(sorted(digital))


@dataclass(frozen=True)
class CompletedCycle:
    """One completed machine cycle.

    Attributes
    ----------
    start : float
        Start (first valve firing) [s since 1970-01-01 UTC].
    duration_s : float
        Duration [s].
    table : StepTable
        Its step summaries (one row), times relative to ``start``.
    """

    start: float
    duration_s: float
    table: StepTable

    @property
    def start_time(self) -> datetime:
        """Start as a timezone-aware datetime (UTC)."""
        return datetime.fromtimestamp(self.start, UTC)


class CycleStreamer:
    """Turn released grid samples into completed, summarised cycles.

    Parameters
    ----------
    model : ReferenceModel
        The reference (its sequence, sensor set and template offsets).
    rates_hz : mapping of str to float
        Grid rate of every channel [Hz].
    origin : float
        Time of grid index 0 [s since 1970-01-01 UTC].
    max_buffer_cycles : float
        Most cycle durations of samples kept while no cycle completes.
    """

    def __init__(
        self,
        model: ReferenceModel,
        rates_hz: dict[str, float],
        origin: float,
        max_buffer_cycles: float = 4.0,
    ) -> None:
        self.model = model
        self.analog, self.digital = needed_channels(model)
        self.rates_hz = {name: rates_hz[name] for name in (*self.analog, *self.digital)}
        self.units = dict(zip(model.channels, model.units, strict=True))
        self.origin = origin
        self.sequence: tuple[StepSpec, ...] = sequence_from_records(model.sequence)
        durations = model.features[:, : model.n_steps].sum(axis=1)
        self.cycle_s = float(np.median(durations))
        self.max_buffer_s = max_buffer_cycles * self.cycle_s + 10.0
        self._start = {name: 0 for name in self.rates_hz}  # grid index of buffer[0]
        self._buffer: dict[str, list[FloatArray]] = {name: [] for name in self.rates_hz}
        self._size = dict.fromkeys(self.rates_hz, 0)
        self._buffer_t0 = 0.0  # stream time of the buffer's start [s after origin]
        self._tried_at = -math.inf
        self.last_start = -math.inf  # newest emitted cycle's start [s since epoch]
        self.dropped_s = 0.0

    # ------------------------------------------------------------ buffer
    def _end_s(self) -> float:
        """Stream time up to which every channel has samples [s after origin]."""
        return min((self._start[n] + self._size[n]) / r for n, r in self.rates_hz.items())

    def _consolidate(self) -> None:
        for name, parts in self._buffer.items():
            if len(parts) > 1:
                self._buffer[name] = [np.concatenate(parts)]

    def _cut(self, t_s: float) -> None:
        """Drop samples before stream time ``t_s``."""
        self._consolidate()
        for name, rate in self.rates_hz.items():
            first = math.ceil(t_s * rate - 1e-9)
            drop = min(max(first - self._start[name], 0), self._size[name])
            if drop:
                self._buffer[name] = [self._buffer[name][0][drop:]]
                self._start[name] += drop
                self._size[name] -= drop
        self._buffer_t0 = max(self._buffer_t0, t_s)

    def add(self, block: GridBlock, final: bool = False) -> list[CompletedCycle]:
        """Append released samples; return the cycles they complete."""
        for name in self.rates_hz:
            values = block.values.get(name)
            if values is None or values.size == 0:
                continue
            if block.start[name] != self._start[name] + self._size[name]:
                raise InputError(
                    describe(f"grid block of {name!r}", block.start[name], "contiguous samples")
                )
            self._buffer[name].append(values)
            self._size[name] += values.size
        end = self._end_s()
        if not final and end < self.due_s:
            return []
        self._tried_at = end
        cycles = self._complete(final)
        if not cycles and end - self._buffer_t0 > self.max_buffer_s:
            keep_from = end - 2.0 * self.cycle_s
            self.dropped_s += keep_from - self._buffer_t0
            self._cut(keep_from)
        return cycles

    @property
    def due_s(self) -> float:
        """Stream time from which the next cycle can be complete [s after origin].

        The next cycle completes when the one after it starts: about a cycle after the
        last one ended (the buffer starts ``MARGIN_S`` before that end); while none
        completes, segmentation is retried every 0.1 cycle. Samples that end before
        this time need not be added yet (:func:`pneufdd.monitor.live.run_stream`
        releases them from the assembler only then).
        """
        return max(
            self._tried_at + 0.1 * self.cycle_s,
            self._buffer_t0 + MARGIN_S + 1.02 * self.cycle_s,
        )

    def _recording(self) -> Recording:
        self._consolidate()
        channels = []
        for name, rate in self.rates_hz.items():
            values = self._buffer[name][0] if self._buffer[name] else np.zeros(0)
            t0 = self._start[name] / rate - self._buffer_t0
            if name in self.units:
                channels.append(Channel(name, values, rate, self.units[name], ANALOG, t0))
            else:
                digital = (values > 0.5).view(np.uint8)
                channels.append(Channel(name, digital, rate, "1", DIGITAL, t0))
        return Recording(channels)

    # ------------------------------------------------------------ cycles
    def _complete(self, final: bool) -> list[CompletedCycle]:
        if min(self._size.values()) < 2:
            return []
        recording = self._recording()
        try:
            seg = segment(recording, self.sequence)
        except InputError:
            return []
        base = self.origin + self._buffer_t0
        found: list[Cycle] = []
        for position, cycle in enumerate(seg.cycles):
            if not cycle.complete or (not final and position == len(seg.cycles) - 1):
                continue
            if base + cycle.start_s <= self.last_start + 1e-6:
                continue
            if cycle.steps[-1].end_s > recording.duration + 1e-9:
                continue
            if final and position == len(seg.cycles) - 1:
                cycle = self._close_last(cycle)
            found.append(cycle)
        if not found:
            return []
        table = build_step_table(
            recording,
            found,
            self.model.machine,
            self.model.channels,
        )
        out = [
            CompletedCycle(base + c.start_s, c.end_s - c.start_s, _row(table, i, c.start_s))
            for i, c in enumerate(found)
        ]
        self.last_start = out[-1].start
        self._cut(self._buffer_t0 + found[-1].end_s - MARGIN_S)
        return out

    def _close_last(self, cycle: Cycle) -> Cycle:
        """The stream's last cycle: its last step lasts at most the reference's median.

        In a file, the last step is closed with the median of the same step in the
        file's other cycles (:mod:`pneufdd.signals.final_step`); the stream keeps no
        other cycle, so the reference's median stands for them.
        """
        last = cycle.steps[-1]
        typical = float(np.median(self.model.features[:, self.model.n_steps - 1]))
        if last.end_s - last.start_s <= typical:
            return cycle
        steps = (*cycle.steps[:-1], replace(last, end_s=last.start_s + typical))
        return replace(cycle, steps=steps)

    def flush(self, block: GridBlock | None) -> list[CompletedCycle]:
        """The cycles still in the buffer at the end of the stream (last one closed)."""
        empty = GridBlock({}, {})
        return self.add(block or empty, final=True)

    @property
    def buffered_samples(self) -> int:
        """Samples held in the buffer (all channels)."""
        return int(sum(self._size.values()))


def _row(table: StepTable, i: int, t0: float) -> StepTable:
    return StepTable(
        machine=table.machine,
        step_start=table.step_start[i : i + 1] - t0,
        step_end=table.step_end[i : i + 1] - t0,
        channels=table.channels,
        units=table.units,
        summaries=table.summaries[i : i + 1].copy(),
        traces=None if table.traces is None else table.traces[i : i + 1].copy(),
        trace_offsets=table.trace_offsets,
        trace_rate_hz=table.trace_rate_hz,
        cycle_index=np.zeros(1, dtype=np.int64),
    )


def concatenate_rows(rows: Sequence[StepTable]) -> StepTable:
    """The step table of several completed cycles."""
    return StepTable.concatenate(list(rows))
