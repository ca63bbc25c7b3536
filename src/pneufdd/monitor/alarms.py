"""Alarms: printed, logged as JSON lines, optionally POSTed to a webhook.

Every alarm carries the machine, the time, the location(s), the size, the cost and
the confidence. ``kind`` is ``leak`` (a leak declared or re-estimated with a new
location) or ``repaired`` (the machine is back to leak-free).
"""

from __future__ import annotations

import json
import math
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

__all__ = ["Alarm", "AlarmSinks"]


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class Alarm:
    """One alarm.

    Attributes
    ----------
    machine : str
        Machine name.
    time : float
        Start of the cycle that raised it [s since 1970-01-01 UTC].
    kind : str
        ``leak`` or ``repaired``.
    locations : tuple of str
        Leak location(s) (``unknown`` until located).
    flow_slpm : float
        Total leak flow while pressurised [SLPM: 0 degC, 1013 mbar].
    annual_cost : float
        Cost per year of the leaks (eq. 1.1) [$].
    confidence : float
        Confidence of the location (lowest over the leaks) [-].
    change_start : float or None
        Estimated start of the change (first cycle with the leak) [s since epoch].
    cycles : int
        Cycles the estimate is based on.
    leaks : tuple of dict
        Per leak: location, flow_slpm, annual_cost, confidence.
    """

    machine: str
    time: float
    kind: str
    locations: tuple[str, ...]
    flow_slpm: float
    annual_cost: float
    confidence: float
    change_start: float | None = None
    cycles: int = 0
    leaks: tuple[dict[str, Any], ...] = field(default_factory=tuple)

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form (the alarm log's line)."""
        return {
            "machine": self.machine,
            "time": datetime.fromtimestamp(self.time, UTC).isoformat(),
            "timestamp": self.time,
            "kind": self.kind,
            "locations": list(self.locations),
            "flow_slpm": _num(self.flow_slpm),
            "annual_cost": _num(self.annual_cost),
            "confidence": _num(self.confidence),
            "change_start": None
            if self.change_start is None
            else datetime.fromtimestamp(self.change_start, UTC).isoformat(),
            "cycles": self.cycles,
            "leaks": [dict(x) for x in self.leaks],
        }

    def message(self) -> str:
        """One line for people."""
        when = datetime.fromtimestamp(self.time, UTC).strftime("%Y-%m-%d %H:%M:%S")
        if self.kind == "repaired":
            return f"{when} {self.machine}: leak-free again (leaks repaired)"
        where = ", ".join(self.locations) or "unknown location"
        flow = f"{self.flow_slpm:.1f} SLPM" if math.isfinite(self.flow_slpm) else "size unknown"
        cost = f"${self.annual_cost:,.0f}/yr" if math.isfinite(self.annual_cost) else "cost unknown"
        conf = f"{self.confidence:.0%}" if math.isfinite(self.confidence) else "-"
        return f"{when} {self.machine}: LEAK at {where}, {flow}, {cost}, confidence {conf}"


class AlarmSinks:
    """Where alarms go.

    Parameters
    ----------
    echo : callable, optional
        Called with each alarm's message (printing).
    log_path : Path, optional
        JSON-lines file each alarm is appended to (flushed at once).
    webhook : str, optional
        URL each alarm is POSTed to as JSON; failures are reported through ``warn``.
    warn : callable, optional
        Called with a message when a webhook fails.
    """

    def __init__(
        self,
        echo: Callable[[str], None] | None = None,
        log_path: Path | None = None,
        webhook: str | None = None,
        warn: Callable[[str], None] | None = None,
        timeout_s: float = 5.0,
    ) -> None:
        self.echo = echo
        self.log_path = log_path
        self.webhook = webhook
        self.warn = warn
        self.timeout_s = timeout_s
        self.sent: list[Alarm] = []

    def __call__(self, alarm: Alarm) -> None:
        """Send one alarm everywhere."""
        self.sent.append(alarm)
        if self.echo is not None:
            self.echo(alarm.message())
        payload = alarm.to_dict()
        if self.log_path is not None:
            self.log_path.parent.mkdir(parents=True, exist_ok=True)
            with open(self.log_path, "a", encoding="utf-8") as handle:
                handle.write(json.dumps(payload, allow_nan=False) + "\n")
        if self.webhook:
            request = urllib.request.Request(
                self.webhook,
                data=json.dumps(payload, allow_nan=False).encode(),
                headers={"Content-Type": "application/json"},
                method="POST",
            )
            try:
                with urllib.request.urlopen(request, timeout=self.timeout_s) as response:
                    response.read()
            except (urllib.error.URLError, OSError) as exc:
                if self.warn is not None:
                    self.warn(f"webhook {self.webhook} failed: {exc}")
