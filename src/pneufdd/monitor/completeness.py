"""Data you can trust, or none: samples a live source says it lost, per channel and cycle.

A source that knows it lost samples records the time span of the loss here
(:class:`LossLedger`): an OPC UA value whose status carries the Overflow bit (the
server's queue discarded the values between the previous value received and this
one), and a Bad or Uncertain value (the channel is unknown from that value until the
next Good one). Before a completed cycle is scored, :meth:`LossLedger.incomplete`
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

import threading
from collections.abc import Iterable

__all__ = ["BAD", "MIN_COMPLETENESS", "OVERFLOW", "UNCERTAIN", "LossLedger", "status_kind"]

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
        self._spans: dict[str, list[tuple[float, float]]] = {}
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
                self._spans.setdefault(channel, []).append((min(previous, t), t))
            elif kind is not None:
                self._bad_since.setdefault(channel, t)
            elif channel in self._bad_since:
                self._spans.setdefault(channel, []).append((self._bad_since.pop(channel), t))
            self._last[channel] = max(previous, t)
        return kind in (None, "overflow")

    def received_share(self, channel: str, start: float, end: float) -> float:
        """Share of ``[start, end]`` not covered by a loss of ``channel`` [-]."""
        if end <= start:
            return 1.0
        with self._lock:
            spans = list(self._spans.get(channel, ()))
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
