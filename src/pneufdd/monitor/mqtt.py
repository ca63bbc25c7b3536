"""MQTT source: JSON payloads of samples from a broker (paho-mqtt), checked before use.

Payload (times in seconds since 1970-01-01 UTC, values in SI units or the tag map's)::

    {"seq": 41,
     "channels": {"P_In": {"t0": 1767225600.0, "rate_hz": 1000, "values": [...]},
                  "U_DNC_A": {"times": [1767225600.01, ...], "values": [1, ...]}}}

``seq`` (optional) counts the publisher's payloads up by one; ``{"end": true}`` ends
the stream (for ``--once``). The client reconnects by itself and says so, and keeps a
persistent session so that a broker that stays up keeps the QoS 1 messages while
pneufdd is away: MQTT 5 with clean start off and a session expiry
(``?session_expiry=3600`` [s], the default), under a stable client id
(``?client_id=``; default ``pneufdd-`` and a hash of host, port and topic);
``?protocol=3.1.1`` for a broker without MQTT 5 (clean session off; the broker sets
the expiry).
"""

from __future__ import annotations

import hashlib
import json
import math
import queue
import threading
import time as wallclock
from collections import OrderedDict
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.limits import MAX_PAYLOAD_BYTES, MAX_RATE_HZ, check_json_depth
from pneufdd.monitor.completeness import ClockOffsets, LossLedger, SequenceTracker, iso_time
from pneufdd.monitor.samples import SampleBatch

if TYPE_CHECKING:
    from pneufdd.monitor.sources import ChannelTags

__all__ = ["RECENT_PAYLOADS", "MqttSource", "Payload", "parse_payload"]

RECENT_PAYLOADS = 1000
"""Payloads without ``seq`` remembered (by a hash of their bytes) to drop repeats [-]."""


def _quiet(_: str) -> None:
    return None


class Payload(NamedTuple):
    """One MQTT payload: its batches, whether it ends the stream, its sequence number."""

    batches: list[SampleBatch]
    end: bool
    seq: int | None


def parse_payload(payload: bytes | str) -> Payload:
    """Batches of one MQTT payload, whether it ends the stream, and its ``seq``.

    Examples
    --------
    >>> batches, end, seq = parse_payload('{"seq": 7, "channels": {"P_In": {"t0": 10, '
    ...                                   '"rate_hz": 2, "values": [6e5, 6.1e5]}}}')
    >>> batches[0].sample_times().tolist(), end, seq
    ([10.0, 10.5], False, 7)
    """
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise InputError(
            describe("MQTT payload size [bytes]", len(payload), f"<= {MAX_PAYLOAD_BYTES:,}")
        )
    check_json_depth(payload, "MQTT payload")
    try:
        data = json.loads(payload)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise InputError(describe("MQTT payload", str(payload)[:60], "JSON")) from exc
    if not isinstance(data, dict):
        raise InputError(describe("MQTT payload", type(data).__name__, "a JSON object"))
    out = []
    channels = data.get("channels", {})
    if not isinstance(channels, dict):
        raise InputError(describe("MQTT payload 'channels'", channels, "an object"))
    for name, entry in channels.items():
        if not isinstance(entry, dict) or "values" not in entry:
            raise InputError(describe(f"MQTT payload channel {name!r}", entry, "{values, ...}"))
        try:
            values = np.asarray(entry["values"], dtype=np.float64)
            times = np.asarray(entry.get("times", []), dtype=np.float64)
            t0, rate = float(entry.get("t0", 0.0)), float(entry.get("rate_hz", 1.0))
        except (TypeError, ValueError) as exc:
            raise InputError(
                describe(f"MQTT payload channel {name!r}", str(entry)[:60], "numbers")
            ) from exc
        if values.ndim != 1 or times.ndim != 1:
            raise InputError(describe(f"MQTT payload channel {name!r}", "nested lists", "lists"))
        if "times" in entry:
            out.append(SampleBatch(str(name), values, times=times))
        elif "t0" in entry and "rate_hz" in entry:
            if not (math.isfinite(t0) and 0.1 <= rate <= MAX_RATE_HZ):
                raise InputError(
                    describe(
                        f"MQTT payload channel {name!r} t0, rate_hz",
                        (t0, rate),
                        f"a finite t0 [s] and a rate from 0.1 to {MAX_RATE_HZ:g} Hz",
                    )
                )
            out.append(SampleBatch(str(name), values, t0=t0, rate_hz=rate))
        else:
            raise InputError(
                describe(
                    f"MQTT payload channel {name!r}", sorted(entry), "times, or t0 and rate_hz"
                )
            )
    seq = data.get("seq")
    if seq is not None and (type(seq) is not int or not 0 <= seq < 2**63):
        raise InputError(describe("MQTT payload 'seq'", seq, "an integer from 0 to 2^63 - 1"))
    return Payload(out, bool(data.get("end", False)), seq)


def _time_span(batches: list[SampleBatch]) -> tuple[float, float]:
    """First and last sample time of ``batches`` [s since 1970-01-01 UTC]."""
    first, last = math.inf, -math.inf
    for batch in batches:
        if batch.times is not None:
            times = np.asarray(batch.times, dtype=np.float64)
            times = times[np.isfinite(times)]
            if times.size:
                first, last = min(first, float(times.min())), max(last, float(times.max()))
        elif np.size(batch.values):
            first = min(first, batch.t0)
            last = max(last, batch.t0 + (np.size(batch.values) - 1) / batch.rate_hz)
    return first, last


class MqttSource:
    """Subscribe to an MQTT topic (paho-mqtt) and yield its batches.

    Payloads are checked before their batches are used: a payload with ``seq`` goes
    through a :class:`~pneufdd.monitor.completeness.SequenceTracker` (a gap marks
    every channel lost in ``losses`` between the samples around it, a repeated
    number is dropped); a payload without one is dropped when its bytes repeat one of
    the last :data:`RECENT_PAYLOADS` (QoS 1 delivers at least once). The arrival
    time minus the newest sample time of each payload is kept in ``clocks``
    (``local - sample``: the publisher's clock offset plus the delay).
    """

    def __init__(
        self,
        host: str,
        port: int,
        topic: str,
        tags: ChannelTags,
        log: Callable[[str], None] = _quiet,
        idle_s: float = 0.5,
        client_id: str | None = None,
        session_expiry_s: int = 3600,
        protocol: str = "5",
        answer_s: float = 10.0,
    ) -> None:
        if protocol not in ("5", "3.1.1"):
            raise InputError(describe("MQTT protocol", protocol, ["5", "3.1.1"]))
        if not 0 <= session_expiry_s <= 0xFFFFFFFF:
            raise InputError(describe("MQTT session_expiry [s]", session_expiry_s, "0 .. 2^32-1"))
        key = hashlib.sha1(f"{host}:{port}/{topic}".encode()).hexdigest()[:12]
        self.client_id = client_id or f"pneufdd-{key}"
        self.session_expiry_s = int(session_expiry_s)
        self.protocol = protocol
        self.answer_s = answer_s
        self.host, self.port, self.topic = host, port, topic
        self.tags = tags
        self.rates_hz = dict(tags.rates_hz)
        self.lateness_s = tags.lateness_s
        self.log = log
        self.idle_s = idle_s
        self.bad_payloads = 0
        self.duplicates = 0
        self.repeated = 0  # duplicates without a sequence number (the same bytes again)
        self.losses = LossLedger()
        self.sequence = SequenceTracker(self.losses, list(self.rates_hz))
        self.clocks = ClockOffsets()
        self._recent: OrderedDict[bytes, None] = OrderedDict()
        self._queue: queue.Queue[tuple[list[SampleBatch], bool]] = queue.Queue()

    def _check(
        self, raw: bytes, batches: list[SampleBatch], seq: int | None, arrived: float
    ) -> bool:
        """Whether a payload's batches are used (False: a duplicate, dropped)."""
        first, last = _time_span(batches)
        if seq is None:
            digest = hashlib.blake2b(raw, digest_size=16).digest()
            if digest in self._recent:
                self.repeated += 1
                return self._duplicate("its bytes repeat an earlier payload")
            self._recent[digest] = None
            if len(self._recent) > RECENT_PAYLOADS:
                self._recent.popitem(last=False)
        else:
            what = self.sequence.observe(seq, first, last)
            if what == "duplicate":
                return self._duplicate(f"sequence number {seq} came before")
            if what == "gap" and self.sequence.last_gap is not None:
                a, b, start, end = self.sequence.last_gap
                self.log(
                    f"MQTT payloads {a}..{b} missing (sequence numbers): every channel lost "
                    f"from {iso_time(start)} to {iso_time(end)}; the cycles that touch it "
                    "are skipped"
                )
            elif what == "restarted":
                self.log(f"MQTT publisher counts again from sequence number {seq} (restarted)")
        if math.isfinite(last):
            self.clocks.observe("local - sample", arrived - last)
        return True

    def _duplicate(self, why: str) -> bool:
        self.duplicates += 1
        if self.duplicates == 1:
            self.log(f"dropped a duplicate MQTT payload ({why}); further ones are counted")
        return False

    def notes(self) -> list[str]:
        """What the payloads showed, for the end of the run (empty: nothing to say)."""
        out = []
        if self.sequence.summary():
            out.append(f"MQTT sequence numbers: {self.sequence.summary()}")
        if self.repeated:
            out.append(f"{self.repeated} MQTT payload(s) repeating an earlier one dropped")
        if self.bad_payloads:
            out.append(f"{self.bad_payloads} bad MQTT payload(s) ignored")
        if self.clocks.summary():
            out.append(f"clock offsets: {self.clocks.summary()}")
        return out

    def __iter__(self) -> Iterator[SampleBatch | None]:
        import paho.mqtt.client as mqtt
        from paho.mqtt.enums import CallbackAPIVersion
        from paho.mqtt.packettypes import PacketTypes
        from paho.mqtt.properties import Properties

        # a persistent session: the broker keeps the subscription and queues QoS 1
        # messages while pneufdd is away (killed, restarted), for the session expiry
        v5 = self.protocol == "5"
        client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=self.client_id,
            protocol=mqtt.MQTTv5 if v5 else mqtt.MQTTv311,
            clean_session=None if v5 else False,
        )
        client.reconnect_delay_set(min_delay=1, max_delay=5)
        ever = threading.Event()
        closing = threading.Event()

        def on_connect(c: Any, _u: Any, _f: Any, reason: Any, _p: Any = None) -> None:
            if reason.is_failure:
                self.log(f"MQTT connection to {self.host}:{self.port} refused: {reason}")
                return
            self.log(
                ("reconnected to" if ever.is_set() else "connected to")
                + f" MQTT {self.host}:{self.port}, topic {self.topic}"
            )
            ever.set()
            c.subscribe(self.topic, qos=1)

        def on_subscribe(_c: Any, _u: Any, _mid: Any, _codes: Any, _p: Any = None) -> None:
            self.log(f"subscribed to MQTT topic {self.topic}")

        def on_disconnect(_c: Any, _u: Any, _f: Any, reason: Any, _p: Any = None) -> None:
            if not closing.is_set():  # a normal end is no lost connection
                self.log(f"MQTT connection lost ({reason}); reconnecting")

        def on_message(_c: Any, _u: Any, message: Any) -> None:
            arrived = wallclock.time()
            try:
                batches, end, seq = parse_payload(message.payload)
                batches = [self.tags.to_si(b) for b in batches]
            except InputError as exc:
                self.bad_payloads += 1
                self.log(f"ignored a bad MQTT payload: {exc}")
                return
            if batches and not self._check(message.payload, batches, seq, arrived):
                return
            self._queue.put((batches, end))

        client.on_connect = on_connect
        client.on_disconnect = on_disconnect
        client.on_subscribe = on_subscribe
        client.on_message = on_message
        if v5:
            properties = Properties(PacketTypes.CONNECT)  # type: ignore[no-untyped-call]
            properties.SessionExpiryInterval = self.session_expiry_s
            client.connect_async(
                self.host, self.port, keepalive=10, clean_start=False, properties=properties
            )
        else:
            client.connect_async(self.host, self.port, keepalive=10)
        client.loop_start()
        began, warned = wallclock.monotonic(), False
        try:
            while True:
                try:
                    batches, end = self._queue.get(timeout=self.idle_s)
                except queue.Empty:
                    waited = wallclock.monotonic() - began
                    if not ever.is_set() and not warned and waited > self.answer_s:
                        warned = True
                        self.log(
                            f"no answer from MQTT {self.host}:{self.port} after "
                            f"{self.answer_s:g} s (MQTT {self.protocol}; a broker that "
                            "speaks only MQTT 3.1.1 does not answer MQTT 5: add "
                            "?protocol=3.1.1 to the source)"
                        )
                    yield None
                    continue
                yield from batches
                yield None
                if end:
                    return
        finally:
            closing.set()
            client.disconnect()
            client.loop_stop()
