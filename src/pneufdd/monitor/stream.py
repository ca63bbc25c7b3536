"""Drive a monitor from a source: batches -> grid -> cycles -> the monitor, until it ends.

:func:`run_stream` takes a source's batches (:class:`~pneufdd.monitor.samples.SampleBatch`,
``None`` heartbeats), places them on each channel's grid
(:class:`~pneufdd.monitor.samples.SampleAssembler`), segments the grid into cycles
(:class:`~pneufdd.monitor.cycles.CycleStreamer`) and hands each completed cycle to a
:class:`~pneufdd.monitor.live.MachineMonitor`, or skips it when the source lost samples
in it (:class:`~pneufdd.monitor.completeness.LossLedger`). The ingestion never waits
for locating and sizing: while an estimate runs beside it, completed cycles wait in
order and are handed over once its result is stored.
"""

from __future__ import annotations

import math
import time as wallclock
from collections import deque
from collections.abc import Callable, Iterable, Iterator

from pneufdd.errors import InputError, describe
from pneufdd.monitor.completeness import LossLedger
from pneufdd.monitor.cycles import CompletedCycle, CycleStreamer, needed_channels
from pneufdd.monitor.live import CycleOutcome, MachineMonitor, MonitorStats
from pneufdd.monitor.samples import SampleAssembler, SampleBatch

__all__ = ["MAX_WAITING_CYCLES", "run_stream"]


def run_stream(
    monitor: MachineMonitor,
    batches: Iterable[SampleBatch | None],
    rates_hz: dict[str, float],
    lateness_s: float = 1.0,
    on_cycle: Callable[[CycleOutcome], None] | None = None,
    max_cycles: int | None = None,
    flush: bool = True,
    losses: LossLedger | None = None,
    say: Callable[[str], None] | None = None,
) -> MonitorStats:
    """Feed a source's batches through segmentation and the monitor until it ends.

    ``None`` items are heartbeats (no data; the stream is alive). On a heartbeat the
    assembled samples are released to the streamer once they reach the time from
    which the next cycle can be complete (:attr:`CycleStreamer.due_s`), so a cycle is
    segmented once and its samples are copied once or twice (memory: about one cycle
    of samples waits in the assembler). ``rates_hz`` gives the grid rate of each
    channel; channels the reference does not need are ignored.
    ``flush``: at the end, close the last cycle as a file's last cycle is closed.
    ``losses``: the source's record of lost samples (late samples are added to it);
    a cycle where a channel was received for less than
    :data:`~pneufdd.monitor.completeness.MIN_COMPLETENESS` of its duration is skipped
    (:meth:`MachineMonitor.skip_incomplete`), never scored.
    ``say``: live notes (late samples dropped).

    While an estimate runs beside the ingestion (:attr:`MachineMonitor.busy`), the
    samples keep being assembled and segmented; completed cycles wait, in order, up
    to :data:`MAX_WAITING_CYCLES`, and go to the monitor once its result is stored.
    """
    analog, digital = needed_channels(monitor.model)
    missing = [c for c in (*analog, *digital) if c not in rates_hz]
    if missing:
        raise InputError(
            describe(
                "channels of the source",
                sorted(rates_hz),
                f"also {missing} (the reference needs them)",
            )
        )
    rates = {c: rates_hz[c] for c in (*analog, *digital)}
    losses = losses if losses is not None else LossLedger()  # late samples are lost samples
    assembler = SampleAssembler(rates, lateness_s)
    streamer: CycleStreamer | None = None
    waiting: deque[CompletedCycle] = deque()
    late = _LateNotes(assembler, say)
    began = wallclock.perf_counter()
    done = 0

    def take(wait: bool) -> bool:
        """Hand the waiting cycles to the monitor, oldest first (``wait``: even while
        an estimate runs); True once ``max_cycles`` are done."""
        nonlocal done
        while waiting:
            if not wait and monitor.busy and len(waiting) < MAX_WAITING_CYCLES:
                return False
            cycle = waiting.popleft()
            short = losses.incomplete(cycle.start, cycle.start + cycle.duration_s, rates)
            outcome = monitor.skip_incomplete(cycle, short) if short else monitor.process(cycle)
            losses.forget(cycle.start)
            done += 1
            if on_cycle is not None:
                on_cycle(outcome)
            if max_cycles is not None and done >= max_cycles:
                return True
        return False

    iterator: Iterator[SampleBatch | None] = iter(batches)
    stop = False
    for batch in iterator:
        if batch is not None:
            assembler.add(batch)
            continue
        if assembler.late_spans:
            for channel, start, end in assembler.late_spans:
                losses.lose([channel], start, end)
            assembler.late_spans.clear()
        late.check()
        if monitor.busy and monitor.poll() and take(wait=False):
            stop = True
            break
        if streamer is not None and assembler.watermark_s < streamer.due_s:
            continue  # nothing the streamer could complete a cycle with: keep assembling
        block = assembler.release()
        if block is None:
            continue
        if streamer is None:
            streamer = CycleStreamer(monitor.model, rates, assembler.origin or 0.0)
        waiting.extend(streamer.add(block))
        if take(wait=False):
            stop = True
            break
    if not stop and flush:
        block = assembler.release(final=True)
        if block is not None:
            if streamer is None:
                streamer = CycleStreamer(monitor.model, rates, assembler.origin or 0.0)
            waiting.extend(streamer.flush(block))
    if not stop:
        take(wait=True)
    monitor.settle()
    late.check(final=True)
    _notes(monitor.stats, assembler, streamer, losses)
    monitor.stats.seconds += wallclock.perf_counter() - began
    return monitor.stats


MAX_WAITING_CYCLES = 100
"""Completed cycles that wait for a running estimate before the stream waits too [-]."""


class _LateNotes:
    """Says live, at most every :attr:`every_s`, that late samples were dropped."""

    every_s = 10.0

    def __init__(self, assembler: SampleAssembler, say: Callable[[str], None] | None) -> None:
        self.assembler = assembler
        self.say = say
        self.said = 0
        self.when = -math.inf

    def check(self, final: bool = False) -> None:
        count = self.assembler.late_samples
        if self.say is None or count == self.said:
            return
        now = wallclock.monotonic()
        if not final and now - self.when < self.every_s:
            return
        self.said, self.when = count, now
        self.say(self.assembler.late_message())


def _notes(
    stats: MonitorStats,
    assembler: SampleAssembler,
    streamer: CycleStreamer | None,
    losses: LossLedger,
) -> None:
    if stats.incomplete:
        stats.notes.append(f"{stats.incomplete} cycle(s) skipped: the source lost samples in them")
    if losses.summary():
        stats.notes.append(f"values the source marked lost: {losses.summary()}")
    if assembler.late_samples:
        stats.notes.append(assembler.late_message())
    if assembler.out_of_order:
        stats.notes.append(
            f"{assembler.out_of_order} samples arrived out of order and were sorted in"
        )
    if streamer is not None and streamer.dropped_s > 0:
        stats.notes.append(
            f"{streamer.dropped_s:.1f} s of data held no complete cycle and were dropped"
        )
