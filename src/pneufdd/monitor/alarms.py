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

import hashlib
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
from typing import TYPE_CHECKING, Any, Protocol

from pneufdd.errors import InputError, describe

if TYPE_CHECKING:
    from pneufdd.monitor.database import HistoryDatabase

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
    id : int, optional
        Its row in the history's ``alarms`` table (repeated deliveries carry the same).
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
    id: int | None = None

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
            "id": self.id,
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
    """Where alarms go: printed, and delivered to each output (alarm log, webhook).

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

    Notes
    -----
    Undelivered alarms wait in a queue per output, oldest first: in memory (at most
    :data:`MAX_HELD_ALARMS` per output), or, once :meth:`attach` ties the sinks to a
    history database, in its ``alarm_outbox`` table, where the monitor queues each
    alarm in the transaction that commits it. An alarm is marked delivered per output
    once the output took it; a monitor killed before that delivers it at its next
    start (at least once: killed between an output taking it and the mark, that
    output gets it again; the payload's ``id`` tells repeats apart). More outputs
    (e.g. a publisher) join with :meth:`add_output`.
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
        self._send: dict[str, Callable[[str], None]] = {}
        self._where: dict[str, str] = {}
        self.keys: dict[str, str] = {}
        """Output name -> its key in the history's outbox."""
        self._store: _Store = _MemoryStore()
        self._failures: dict[str, int] = {}
        self._next_try: dict[str, float] = {}
        self._unsure: set[str] = set()  # outputs that may have alarms waiting
        if log_path is not None:
            key = f"alarm log {Path(log_path).resolve()}"
            self.add_output("alarm log", key, self._append_log, str(log_path))
        if self.webhook:
            parts = urllib.parse.urlsplit(self.webhook)
            digest = hashlib.sha256(self.webhook.encode()).hexdigest()[:12]
            # the key names the host, not the URL: a webhook's path or query may hold a token
            key = f"webhook {parts.scheme}://{parts.hostname} #{digest}"
            self.add_output("webhook", key, self._post, self.webhook)

    def add_output(
        self, name: str, key: str, send: Callable[[str], None], where: str | None = None
    ) -> None:
        """Deliver every alarm to one more output.

        ``send`` takes the alarm's JSON line and raises when the output fails;
        ``key`` names the output in the history's outbox (stable across restarts);
        ``where`` names it in messages.
        """
        self._send[name] = send
        self._where[name] = where or name
        self.keys[name] = key
        self._failures[name] = 0
        self._next_try[name] = 0.0
        self._unsure.add(name)

    def attach(self, history: HistoryDatabase, machine_id: int) -> tuple[str, ...]:
        """Keep the undelivered alarms in ``history``'s outbox; deliver what a killed
        monitor left undelivered. Returns the output keys the monitor queues alarms for.
        """
        self._store = _HistoryStore(history, machine_id, self.keys)
        self._unsure = set(self._send)
        if self._store.count():
            self._say(
                f"{self._store.count()} alarm delivery(ies) left from an earlier run: "
                "delivering them now, oldest first"
            )
            self.retry(force=True)
        return tuple(self.keys.values())

    def __call__(self, alarm: Alarm) -> None:
        """Send one alarm everywhere; an output that fails keeps it for a retry."""
        self.sent.append(alarm)
        if self.echo is not None:
            self.echo(alarm.message())
        if isinstance(self._store, _MemoryStore):
            self._store.put(list(self._send), json.dumps(alarm.to_dict(), allow_nan=False), self)
        self._unsure = set(self._send)
        self.retry(force=True)

    @property
    def pending(self) -> int:
        """Alarms not yet delivered (counted per output)."""
        return self._store.count()

    @property
    def held(self) -> dict[str, int]:
        """Alarms not yet delivered, per output."""
        return {name: self._store.count(name) for name in self._send}

    def retry(self, force: bool = False) -> int:
        """Send the held alarms of every output whose retry is due (all with ``force``).

        Returns
        -------
        int
            Alarms still held.
        """
        now = time.monotonic()
        for name, send in self._send.items():
            if name not in self._unsure or (not force and now < self._next_try[name]):
                continue
            failures, delivered, failed = self._failures[name], 0, False
            for key, line in self._store.waiting(name):
                try:
                    send(line)
                except Exception as exc:  # any failure of an output: reported, held, retried
                    error = f"{self._where[name]}: {type(exc).__name__}: {exc}"
                    self._failed(name, error, self._store.count(name))
                    failed = True
                    break
                self._store.done(name, key)
                delivered += 1
            if not failed and not self._store.count(name):
                self._unsure.discard(name)
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

    def _append_log(self, line: str) -> None:
        assert self.log_path is not None
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log_path, "a", encoding="utf-8") as handle:
            handle.write(line + "\n")
            handle.flush()

    def _post(self, line: str) -> None:
        assert self.webhook is not None
        request = urllib.request.Request(
            self.webhook,
            data=line.encode(),
            headers={"Content-Type": "application/json"},
            method="POST",
        )
        with urllib.request.urlopen(request, timeout=self.timeout_s) as response:
            response.read()


class _Store(Protocol):
    """Undelivered alarms per output: (key, JSON line), oldest first."""

    def waiting(self, name: str) -> list[tuple[int, str]]: ...

    def done(self, name: str, key: int) -> None: ...

    def count(self, name: str | None = None) -> int: ...


class _MemoryStore:
    """Held in memory, at most :data:`MAX_HELD_ALARMS` per output."""

    def __init__(self) -> None:
        self._held: dict[str, deque[tuple[int, str]]] = {}
        self._serial = 0

    def put(self, names: list[str], line: str, sinks: AlarmSinks) -> None:
        self._serial += 1
        for name in names:
            queue = self._held.setdefault(name, deque())
            if len(queue) >= MAX_HELD_ALARMS:
                queue.popleft()
                sinks._say(f"{name}: more than {MAX_HELD_ALARMS} alarms held; the oldest dropped")
            queue.append((self._serial, line))

    def waiting(self, name: str) -> list[tuple[int, str]]:
        return list(self._held.get(name, ()))

    def done(self, name: str, key: int) -> None:
        queue = self._held[name]
        if queue and queue[0][0] == key:
            queue.popleft()

    def count(self, name: str | None = None) -> int:
        if name is not None:
            return len(self._held.get(name, ()))
        return sum(len(q) for q in self._held.values())


class _HistoryStore:
    """Held in the history's ``alarm_outbox`` (the monitor queues them with the alarm)."""

    def __init__(self, history: HistoryDatabase, machine_id: int, keys: dict[str, str]) -> None:
        self.history = history
        self.machine_id = machine_id
        self.keys = keys

    def waiting(self, name: str) -> list[tuple[int, str]]:
        return self.history.undelivered(self.machine_id, self.keys[name])

    def done(self, name: str, key: int) -> None:
        self.history.mark_delivered(key, self.keys[name], time.time())

    def count(self, name: str | None = None) -> int:
        names = [name] if name is not None else list(self.keys)
        return sum(len(self.waiting(n)) for n in names)
