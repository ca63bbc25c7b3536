"""Data you can trust, or none: samples a live source says it lost, per channel and cycle.

A source that knows it lost samples records the time span of the loss here
(:class:`LossLedger`): an OPC UA value whose status carries the Overflow bit (the
server's queue discarded the values between the previous value received and this
one), a Bad or Uncertain value (the channel is unknown from that value until the
next Good one), and payloads missing from a publisher's sequence numbers
(:class:`SequenceTracker`: every channel is unknown between the samples before and
after them). Before a completed cycle is scored, :meth:`LossLedger.incomplete`
gives each channel's share of the cycle that was received; a cycle where a channel
falls below :data:`MIN_COMPLETENESS` is skipped (never scored, never evidence of a
leak), counted and said live, as the gap rule skips a recording's cycles.

Examples
--------
>>> ledger = LossLedger()
>>> ledger.observe("P_In", 10.0, 0)
True
>>> ledger.observe("P_In", 13.0, OVERFLOW)  # values between 10 s and 13 s were discarded
True
>>> ledger.incomplete(0.0, 20.0, ["P_In", "Q_In"])
[('P_In', 0.85)]
"""

from __future__ import annotations

import math
import statistics
import threading
from collections import deque
from collections.abc import Iterable, Sequence
from datetime import UTC, datetime

__all__ = [
    "BAD",
    "MIN_COMPLETENESS",
    "OVERFLOW",
    "UNCERTAIN",
    "ClockOffsets",
    "LossLedger",
    "SequenceTracker",
    "iso_time",
    "status_kind",
]

MIN_COMPLETENESS = 0.95
"""Share of a cycle's duration a channel must have been received for to be scored [-]."""

OVERFLOW = 0x480
"""OPC UA StatusCode InfoType DataValue (0x400) with the Overflow bit (0x80) (Part 4, 7.39)."""
BAD = 0x80000000
"""OPC UA StatusCode severity Bad (top bits 10)."""
UNCERTAIN = 0x40000000
"""OPC UA StatusCode severity Uncertain (top bits 01)."""


def status_kind(code: int) -> str | None:
    """What an OPC UA status code says about the value: ``bad``, ``uncertain``,
    ``overflow`` (Good, but values before it were discarded) or None (Good).

    Examples
    --------
    >>> status_kind(0), status_kind(0x480), status_kind(0x80350000), status_kind(0x40000000)
    (None, 'overflow', 'bad', 'uncertain')
    """
    severity = code & 0xC0000000
    if severity & BAD:
        return "bad"
    if severity == UNCERTAIN:
        return "uncertain"
    if code & OVERFLOW == OVERFLOW:
        return "overflow"
    return None


class LossLedger:
    """Time spans of lost samples per channel, and counts of what said so (thread-safe).

    Times are seconds since 1970-01-01 UTC (the samples' own time stamps).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._spans: dict[str, list[tuple[float, float, int]]] = {}
        self._last: dict[str, float] = {}
        self._bad_since: dict[str, float] = {}
        self.counts: dict[str, dict[str, int]] = {}
        """Channel -> kind (``overflow``, ``bad``, ``uncertain``) -> values received."""

    def observe(self, channel: str, t: float, code: int) -> bool:
        """Note a value of ``channel`` at time ``t`` [s] with status ``code``.

        Returns whether the value may be used (False for Bad and Uncertain values).
        """
        kind = status_kind(code)
        with self._lock:
            previous = self._last.get(channel, t)
            if kind is not None:
                counts = self.counts.setdefault(channel, {})
                counts[kind] = counts.get(kind, 0) + 1
            if kind == "overflow":
                self._spans.setdefault(channel, []).append((min(previous, t), t, 0))
            elif kind is not None:
                self._bad_since.setdefault(channel, t)
            elif channel in self._bad_since:
                self._spans.setdefault(channel, []).append((self._bad_since.pop(channel), t, 0))
            self._last[channel] = max(previous, t)
        return kind in (None, "overflow")

    def received_share(self, channel: str, start: float, end: float) -> float:
        """Share of ``[start, end]`` not covered by a loss of ``channel`` [-]."""
        if end <= start:
            return 1.0
        with self._lock:
            spans = [(a, b) for a, b, _ in self._spans.get(channel, ())]
            if channel in self._bad_since:
                spans.append((self._bad_since[channel], float("inf")))
        lost, reach = 0.0, start
        for a, b in sorted(spans):
            a, b = max(a, reach), min(b, end)
            if b > a:
                lost += b - a
                reach = b
        return max(0.0, 1.0 - lost / (end - start))

    def incomplete(
        self, start: float, end: float, channels: Iterable[str], threshold: float = MIN_COMPLETENESS
    ) -> list[tuple[str, float]]:
        """Channels received for less than ``threshold`` of ``[start, end]``, with their share."""
        shares = [(c, self.received_share(c, start, end)) for c in channels]
        return [(c, round(s, 4)) for c, s in shares if s < threshold]

    def lose(self, channels: Iterable[str], start: float, end: float, key: int = 0) -> None:
        """Mark ``[start, end]`` [s] lost for every one of ``channels`` (``key`` > 0: a
        loss that :meth:`withdraw` may take back if the samples arrive after all)."""
        with self._lock:
            for channel in channels:
                self._spans.setdefault(channel, []).append((start, end, key))

    def withdraw(self, key: int) -> None:
        """Take back the spans marked lost under ``key``."""
        with self._lock:
            for channel, spans in self._spans.items():
                self._spans[channel] = [s for s in spans if s[2] != key]

    def forget(self, before: float) -> None:
        """Drop the spans that ended before ``before`` [s] (memory stays bounded)."""
        with self._lock:
            for channel, spans in self._spans.items():
                self._spans[channel] = [s for s in spans if s[1] >= before]

    def summary(self) -> str:
        """One line: what the source said it lost, per channel (empty: nothing)."""
        with self._lock:
            parts = [
                f"{c}: " + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items()))
                for c, kinds in sorted(self.counts.items())
            ]
        return "; ".join(parts)


class SequenceTracker:
    """A publisher's payload sequence numbers: gaps, duplicates, late arrivals, restarts.

    Each payload of a publisher carries ``seq``, one more than the one before. A jump
    leaves the payloads between missing: every channel is marked lost in ``ledger``
    from the newest sample received before them to the first sample after them, so
    the cycles they touch are skipped. A missing payload that arrives after all (out
    of order) is used, and once every payload of a gap has arrived the loss is taken
    back. A number seen before is a duplicate (MQTT's QoS 1 delivers at least once)
    and is dropped, unless the payload's samples are newer than any received: then
    the publisher started counting again (it restarted).

    Examples
    --------
    >>> ledger = LossLedger()
    >>> seq = SequenceTracker(ledger, ["P_In"])
    >>> [seq.observe(k, 10.0 * k, 10.0 * k + 9.9) for k in (1, 2, 5, 2, 3, 4)]
    ['new', 'new', 'gap', 'duplicate', 'filled', 'filled']
    >>> seq.summary(), ledger.incomplete(29.0, 41.0, ["P_In"])
    ('1 duplicate, 2 out of order', [])
    """

    def __init__(self, ledger: LossLedger, channels: Sequence[str], remember: int = 10_000) -> None:
        self.ledger = ledger
        self.channels = tuple(channels)
        self.remember = remember
        self.newest: int | None = None
        self.newest_time = -math.inf
        self._missing: dict[int, int] = {}  # seq -> its gap's key
        self._gaps: dict[int, set[int]] = {}  # gap key -> seqs still missing
        self._keys = 0
        self.counts = {"missing": 0, "duplicate": 0, "out_of_order": 0, "restarted": 0}
        """``missing``: numbers never received (so far); the others: payloads seen."""
        self.last_gap: tuple[int, int, float, float] | None = None
        """The newest gap: first and last missing number, and the span lost [s]."""

    def observe(self, seq: int, first_time: float, last_time: float) -> str:
        """Note payload ``seq`` holding samples from ``first_time`` to ``last_time`` [s].

        Returns ``new``, ``gap`` (payloads before it are missing; it is used),
        ``filled`` (a missing one, late: used), ``duplicate`` (drop it) or
        ``restarted`` (the publisher counts again from ``seq``: used).
        """
        if self.newest is None or seq == self.newest + 1:
            return self._accept(seq, last_time, "new")
        if seq > self.newest:
            start, end = self.newest + 1, seq - 1
            self._keys += 1
            key = self._keys
            self._gaps[key] = set(range(start, end + 1))
            for k in self._gaps[key]:
                self._missing[k] = key
            self.counts["missing"] += end - start + 1
            self.ledger.lose(self.channels, self.newest_time, first_time, key)
            self.last_gap = (start, end, self.newest_time, first_time)
            self._forget_oldest()
            return self._accept(seq, last_time, "gap")
        if seq in self._missing:
            key = self._missing.pop(seq)
            self._gaps[key].discard(seq)
            if not self._gaps[key]:
                del self._gaps[key]
                self.ledger.withdraw(key)
            self.counts["missing"] -= 1
            self.counts["out_of_order"] += 1
            self.newest_time = max(self.newest_time, last_time)
            return "filled"
        if first_time > self.newest_time:
            self.counts["restarted"] += 1
            return self._accept(seq, last_time, "restarted")
        self.counts["duplicate"] += 1
        return "duplicate"

    def _accept(self, seq: int, last_time: float, what: str) -> str:
        self.newest = seq
        self.newest_time = max(self.newest_time, last_time)
        return what

    def _forget_oldest(self) -> None:
        while len(self._missing) > self.remember:
            seq = min(self._missing)
            key = self._missing.pop(seq)
            self._gaps[key].discard(seq)
            if not self._gaps[key]:
                del self._gaps[key]

    def summary(self) -> str:
        """One line of what the numbers showed (empty: nothing out of order)."""
        parts = [f"{n} {k.replace('_', ' ')}" for k, n in self.counts.items() if n]
        return ", ".join(parts)


class ClockOffsets:
    """Differences between the clocks that stamp a sample, kept for the newest values.

    ``observe("server - source", dt)``: e.g. an OPC UA value's server time stamp
    minus its source time stamp (the PLC's clock against the server's), or the
    local arrival time minus the sample's time (offset plus delay) [s]. Thread-safe.

    Examples
    --------
    >>> clocks = ClockOffsets()
    >>> for dt in (0.30, 0.31, 0.29):
    ...     clocks.observe("local - source", dt)
    >>> clocks.summary()
    'local - source: median 0.300 s (0.290 .. 0.310 s, 3 values)'
    """

    def __init__(self, keep: int = 2000) -> None:
        self._lock = threading.Lock()
        self._values: dict[str, deque[float]] = {}
        self._seen: dict[str, int] = {}
        self.keep = keep

    def observe(self, what: str, offset_s: float) -> None:
        """Note one offset [s] of the kind ``what``."""
        if not math.isfinite(offset_s):
            return
        with self._lock:
            self._values.setdefault(what, deque(maxlen=self.keep)).append(offset_s)
            self._seen[what] = self._seen.get(what, 0) + 1

    def count(self, what: str) -> int:
        """Offsets of the kind ``what`` observed [-]."""
        with self._lock:
            return self._seen.get(what, 0)

    def median(self, what: str) -> float:
        """Median of the newest offsets of kind ``what`` [s] (NaN: none)."""
        with self._lock:
            values = list(self._values.get(what, ()))
        return statistics.median(values) if values else math.nan

    def to_dict(self) -> dict[str, dict[str, float | int]]:
        """Per kind: median, min, max over the newest values [s], and values seen."""
        with self._lock:
            items = {k: (list(v), self._seen[k]) for k, v in self._values.items()}
        return {
            k: {
                "median_s": round(statistics.median(v), 6),
                "min_s": round(min(v), 6),
                "max_s": round(max(v), 6),
                "values": n,
            }
            for k, (v, n) in sorted(items.items())
        }

    def summary(self) -> str:
        """One line per kind (empty: nothing observed)."""
        return "; ".join(
            f"{k}: median {d['median_s']:.3f} s ({d['min_s']:.3f} .. {d['max_s']:.3f} s, "
            f"{d['values']} values)"
            for k, d in self.to_dict().items()
        )


def iso_time(t: float) -> str:
    """``t`` [s since 1970-01-01 UTC] as an ISO time to the millisecond (``?`` if not finite).

    >>> iso_time(0.0)
    '1970-01-01T00:00:00.000+00:00'
    """
    if not math.isfinite(t):
        return "?"
    return datetime.fromtimestamp(t, UTC).isoformat(timespec="milliseconds")
