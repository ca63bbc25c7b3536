"""Alarms: printed, logged as JSON lines, optionally POSTed to a webhook.

Every alarm carries the machine, the time, the location(s), the size, the cost and
the confidence. ``kind`` is ``leak`` (a leak declared or re-estimated with a new
location) or ``repaired`` (the machine is back to leak-free).

A live monitor must not stop itself over an alarm output (issue 39): the webhook URL
is checked when the sinks are made (http or https with a host, :func:`check_webhook`),
and an output that fails while running (the webhook down, the disk full) is reported
through ``warn`` and its alarms are held and sent again later, oldest first
(:meth:`AlarmSinks.retry`), never raising into the monitor.
"""

from __future__ import annotations

import json
import math
import time
import urllib.parse
import urllib.request
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pneufdd.errors import InputError, describe

__all__ = ["MAX_HELD_ALARMS", "Alarm", "AlarmSinks", "check_webhook"]

MAX_HELD_ALARMS = 10_000
"""Alarms held per failing output for a later retry; beyond it the oldest are dropped."""

WEBHOOK_SCHEMES = ("http", "https")


def check_webhook(url: str) -> str:
    """The webhook URL if alarms can be POSTed to it: http(s), with a host.

    Parameters
    ----------
    url : str
        The ``--webhook`` value.

    Returns
    -------
    str
        ``url`` unchanged.

    Raises
    ------
    InputError
        Naming ``--webhook``, the value received and what is allowed.

    Examples
    --------
    >>> check_webhook("https://alarms.example.com/pneufdd")
    'https://alarms.example.com/pneufdd'
    >>> try:
    ...     check_webhook("file:///etc/passwd")
    ... except InputError as exc:
    ...     print(exc)
    --webhook: received 'file:///etc/passwd'; allowed: an http:// or https:// URL with a host (e.g. http://alarms.local:8080/pneufdd)
    """
    allowed = "an http:// or https:// URL with a host (e.g. http://alarms.local:8080/pneufdd)"
    text = str(url)
    try:
        parts = urllib.parse.urlsplit(text)
        port_ok = parts.port is None or parts.port > 0
    except ValueError:  # a port that is not a number, or brackets that do not match
        raise InputError(describe("--webhook", text, allowed)) from None
    if (
        parts.scheme.lower() not in WEBHOOK_SCHEMES
        or not parts.hostname
        or not port_ok
        or any(c.isspace() or ord(c) < 32 or ord(c) == 127 for c in text)
    ):
        raise InputError(describe("--webhook", text, allowed))
    return text


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
        http(s) URL each alarm is POSTed to as JSON (checked here: :func:`check_webhook`).
    warn : callable, optional
        Called with a message when an output fails, and when held alarms get through.
    timeout_s : float
        Time a webhook POST may take [s].
    retry_after_s : float
        Wait before the first retry of a failed output [s]; doubled after each failure
        in a row, up to 10 minutes. A new alarm also retries (its held ones first).

    Raises
    ------
    InputError
        If ``webhook`` is not an http(s) URL with a host.
    """

    def __init__(
        self,
        echo: Callable[[str], None] | None = None,
        log_path: Path | None = None,
        webhook: str | None = None,
        warn: Callable[[str], None] | None = None,
        timeout_s: float = 5.0,
        retry_after_s: float = 30.0,
    ) -> None:
        self.echo = echo
        self.log_path = log_path
        self.webhook = None if webhook is None else check_webhook(webhook)
        self.warn = warn
        self.timeout_s = timeout_s
        self.retry_after_s = retry_after_s
        self.sent: list[Alarm] = []
        self.held: dict[str, deque[dict[str, Any]]] = {name: deque() for name in self._outputs()}
        self._failures = dict.fromkeys(self.held, 0)
        self._next_try = dict.fromkeys(self.held, 0.0)

    def _outputs(self) -> list[str]:
        names = []
        if self.log_path is not None:
            names.append("alarm log")
        if self.webhook:
            names.append("webhook")
        return names

    def __call__(self, alarm: Alarm) -> None:
        """Send one alarm everywhere; an output that fails keeps it for a retry."""
        self.sent.append(alarm)
        if self.echo is not None:
            self.echo(alarm.message())
        payload = alarm.to_dict()
        for name, queue in self.held.items():
            if len(queue) >= MAX_HELD_ALARMS:
                queue.popleft()
                self._say(f"{name}: more than {MAX_HELD_ALARMS} alarms held; the oldest dropped")
            queue.append(payload)
        self.retry(force=True)

    @property
    def pending(self) -> int:
        """Alarms held by failing outputs, not yet delivered (counted per output)."""
        return sum(len(q) for q in self.held.values())

    def retry(self, force: bool = False) -> int:
        """Send the held alarms of every output whose retry is due (all with ``force``).

        Returns
        -------
        int
            Alarms still held.
        """
        now = time.monotonic()
        for name, queue in self.held.items():
            if not queue or (not force and now < self._next_try[name]):
                continue
            failures, delivered = self._failures[name], 0
            while queue:
                error = self._send(name, queue[0])
                if error is not None:
                    self._failed(name, error, len(queue))
                    break
                queue.popleft()
                delivered += 1
            if delivered and failures:
                self._failures[name] = 0
                self._say(f"{name} works again: {delivered} held alarm(s) delivered")
        return self.pending

    def _failed(self, name: str, error: str, held: int) -> None:
        self._failures[name] += 1
        wait = min(600.0, self.retry_after_s * 2.0 ** (self._failures[name] - 1))
        self._next_try[name] = time.monotonic() + wait
        self._say(f"{name} failed: {error}; {held} alarm(s) held, retrying in {wait:.0f} s")

    def _say(self, message: str) -> None:
        if self.warn is not None:
            self.warn(message)

    def _send(self, name: str, payload: dict[str, Any]) -> str | None:
        """Deliver one alarm to one output; the error as text, or None when delivered."""
        line = json.dumps(payload, allow_nan=False)
        try:
            if name == "alarm log":
                assert self.log_path is not None
                self.log_path.parent.mkdir(parents=True, exist_ok=True)
                with open(self.log_path, "a", encoding="utf-8") as handle:
                    handle.write(line + "\n")
                    handle.flush()
            else:
                assert self.webhook is not None
                request = urllib.request.Request(
                    self.webhook,
                    data=line.encode(),
                    headers={"Content-Type": "application/json"},
                    method="POST",
                )
                with urllib.request.urlopen(request, timeout=self.timeout_s) as response:
                    response.read()
        except Exception as exc:  # any failure of an output: reported, held, retried
            where = self.log_path if name == "alarm log" else self.webhook
            return f"{where}: {type(exc).__name__}: {exc}"
        return None
