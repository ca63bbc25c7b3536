"""Where samples come from: a replayed recording, an MQTT broker, an OPC UA server.

Every source is an iterable of :class:`~pneufdd.monitor.samples.SampleBatch` items and
``None`` markers (a marker: the batches so far may be released; the stream is
alive), with ``rates_hz`` (grid rate of each channel) and ``lateness_s``.

``replay:run.parquet[?speed=10]``
    A recording played at ``speed`` times real time (default 1; ``speed=max`` as
    fast as it can be read) in blocks of ``chunk`` seconds (default 1). Times are the
    recording's ``start_time`` plus the sample time.
``mqtt://host:port/topic``
    JSON payloads (documented in ``docs/monitor.md``)::

        {"channels": {"P_In": {"t0": 1767225600.0, "rate_hz": 1000, "values": [...]},
                      "U_DNC_A": {"times": [1767225600.01, ...], "values": [1, ...]}}}

    times in seconds since 1970-01-01 UTC, values in SI units (digital 0/1).
    ``{"end": true}`` ends the stream (for ``--once``). The client (paho-mqtt)
    reconnects by itself and says so. It keeps a persistent session so that a broker
    that stays up keeps the QoS 1 messages while pneufdd is away: MQTT 5 with clean
    start off and a session expiry (``?session_expiry=3600`` [s], the default), under
    a stable client id (``?client_id=``; default ``pneufdd-`` and a hash of host, port
    and topic); ``?protocol=3.1.1`` for a broker without MQTT 5 (clean session off;
    the broker sets the expiry).
``opcua://host:port/path``
    An OPC UA client (asyncua) subscribing to the tags of the tag map; the time of a
    sample is the server's source timestamp. After a lost connection it reconnects
    every second and says so. An optional ``end`` tag in the tag map ends the stream
    when it becomes true. ``OpcUaSource(watchdog_s=10)``: the server must answer a
    state probe within this time [s] before the connection is taken as lost. The
    parameters the server grants are checked against the channels' rates
    (:mod:`pneufdd.monitor.opcua`): asked once more, then refused (exit 2) unless
    ``?accept_revised=1``. Every value's status is checked: Overflow, Bad and
    Uncertain values mark lost samples in ``losses``
    (:class:`~pneufdd.monitor.completeness.LossLedger`).

The tag map (``--tags tags.toml``) names each channel's tag and grid rate::

    lateness_s = 1.0          # optional
    end = "ns=2;s=ReplayDone" # optional, OPC UA only
    [channels.P_In]
    node = "ns=2;s=P_In"      # OPC UA node id (MQTT: ignored)
    rate_hz = 20              # grid rate [Hz]

Without a tag map, OPC UA tags are ``ns=2;s=<channel>`` and grid rates are 1 kHz for
analog and 100 Hz for PLC channels (the rates of the twin's recordings).

The same map a plant writes for its files (``pneufdd import --map``,
:mod:`pneufdd.recording.tag_map`) also serves the monitor: its keys are the PLC's tag
names, each with its role, unit and flow basis, plus the optional ``node`` (OPC UA node
id; default ``ns=2;s=<tag>``) and ``rate_hz`` (grid rate) the monitor needs::

    lateness_s = 1.0
    [columns]
    "B_P1" = { role = "P_In", unit = "bar(g)", rate_hz = 50 }
    "B_F1" = { role = "Q_In", unit = "l/min", basis = "ANR", node = "ns=3;s=DB10.F1" }
    "Y1.0" = { role = "U_FEED_A" }

Live values are brought to SI at the edge with the very conversion the import uses
(:func:`pneufdd.physics.units.to_si`); MQTT payloads may name their channels by tag.
A map with both ``[channels]`` and ``[columns]`` is refused.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import json
import math
import queue
import threading
import time as wallclock
import urllib.parse
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC as _UTC
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.limits import (
    MAX_PAYLOAD_BYTES,
    MAX_RATE_HZ,
    MAX_REPLAY_CHUNK_S,
    MAX_REPLAY_SPEED,
    MIN_REPLAY_CHUNK_S,
    MIN_REPLAY_SPEED,
    check_json_depth,
)
from pneufdd.monitor.completeness import LossLedger
from pneufdd.monitor.database import masked_url
from pneufdd.monitor.opcua import SubscriptionRefusedError, grant_problems, needed_queue, subscribe
from pneufdd.monitor.samples import SampleBatch
from pneufdd.physics.units import UNITS, to_si
from pneufdd.recording.model import Recording
from pneufdd.recording.tag_map import TagMap, load_tag_map

__all__ = [
    "DEFAULT_ANALOG_HZ",
    "DEFAULT_DIGITAL_HZ",
    "ChannelTags",
    "MqttSource",
    "OpcUaSource",
    "ReplaySource",
    "open_source",
    "parse_payload",
]

DEFAULT_ANALOG_HZ = 1000.0
DEFAULT_DIGITAL_HZ = 100.0
Log = Callable[[str], None]


def _quiet(_: str) -> None:
    return None


@dataclass(frozen=True)
class ChannelTags:
    """Channel -> tag (node id) and grid rate; optional end tag and lateness.

    ``aliases`` maps a PLC tag name arriving in a stream to its channel, ``units`` a
    channel to the unit its live values come in (absent: already SI); both are filled
    from the PLC-tag form of the map (module docstring). Built from the one tag-map
    reader, :func:`pneufdd.recording.tag_map.load_tag_map`.
    """

    nodes: dict[str, str]
    rates_hz: dict[str, float]
    end: str | None = None
    lateness_s: float = 1.0
    aliases: dict[str, str] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)

    def to_si(self, batch: SampleBatch) -> SampleBatch:
        """The batch under its channel's name, its values in SI units."""
        channel = self.aliases.get(batch.channel, batch.channel)
        unit = self.units.get(channel)
        if channel == batch.channel and unit is None:
            return batch
        values = batch.values
        if unit is not None:
            values, _ = to_si(values, unit, f"of live tag {batch.channel!r}")
        return batch._replace(channel=channel, values=np.asarray(values, dtype=np.float64))

    @classmethod
    def default(cls, analog: Sequence[str], digital: Sequence[str]) -> ChannelTags:
        """``ns=2;s=<channel>`` tags at the twin's rates."""
        names = [*analog, *digital]
        rates = {c: DEFAULT_ANALOG_HZ for c in analog} | {c: DEFAULT_DIGITAL_HZ for c in digital}
        return cls({c: f"ns=2;s={c}" for c in names}, rates)

    @classmethod
    def from_tag_map(
        cls, tag_map: TagMap, analog: Sequence[str], digital: Sequence[str]
    ) -> ChannelTags:
        """The live tags of a parsed tag map; channels it leaves out get the defaults."""
        base = cls.default(analog, digital)
        nodes, rates = dict(base.nodes), dict(base.rates_hz)
        aliases: dict[str, str] = {}
        units: dict[str, str] = {}
        for tag in tag_map.live:
            if tag.node is not None:
                nodes[tag.channel] = tag.node
            elif tag_map.columns:  # the PLC-tag form: node ns=2;s=<PLC tag>
                nodes[tag.channel] = f"ns=2;s={tag.tag}"
            if tag.rate_hz is not None:
                rates[tag.channel] = tag.rate_hz
            if tag.tag != tag.channel:
                aliases[tag.tag] = tag.channel
            if tag.unit is not None and UNITS[tag.unit].si_unit != tag.unit:
                units[tag.channel] = tag.unit
        return cls(nodes, rates, tag_map.end, tag_map.lateness_s, aliases, units)

    @classmethod
    def read(cls, path: Path, analog: Sequence[str], digital: Sequence[str]) -> ChannelTags:
        """Read a tag map (either form); channels it leaves out get the defaults."""
        return cls.from_tag_map(load_tag_map(path, live=True), analog, digital)


# --------------------------------------------------------------------- replay
@dataclass
class ReplaySource:
    """Play a recording as if it arrived live.

    Parameters
    ----------
    recording : Recording
        The recording.
    speed : float
        Times real time; ``math.inf`` as fast as possible.
    chunk_s : float
        Seconds of data per block [s].
    """

    recording: Recording
    speed: float = 1.0
    chunk_s: float = 1.0
    log: Log = _quiet
    rates_hz: dict[str, float] = field(init=False)
    lateness_s: float = 0.0

    def __post_init__(self) -> None:
        if not (self.speed == math.inf or MIN_REPLAY_SPEED <= self.speed <= MAX_REPLAY_SPEED):
            raise InputError(
                describe(
                    "replay speed (replay:...?speed=)",
                    self.speed,
                    f"{MIN_REPLAY_SPEED:g} to {MAX_REPLAY_SPEED:g} times real time, or 'max' "
                    "(docs/limits.md)",
                )
            )
        if not MIN_REPLAY_CHUNK_S <= self.chunk_s <= MAX_REPLAY_CHUNK_S:
            raise InputError(
                describe(
                    "replay chunk [s] (replay:...?chunk=)",
                    self.chunk_s,
                    f"{MIN_REPLAY_CHUNK_S:g} to {MAX_REPLAY_CHUNK_S:g} s (docs/limits.md)",
                )
            )
        self.rates_hz = {c: self.recording.rate(c) for c in self.recording.channels}

    def __iter__(self) -> Iterator[SampleBatch | None]:
        rec = self.recording
        origin = rec.start_time.timestamp()
        infos = [rec.info(c) for c in rec.channels]
        n_chunks = math.ceil(rec.duration / self.chunk_s)
        began = wallclock.monotonic()
        for k in range(n_chunks):
            lo, hi = k * self.chunk_s, (k + 1) * self.chunk_s
            if math.isfinite(self.speed):
                wait = began + hi / self.speed - wallclock.monotonic()
                if wait > 0:
                    wallclock.sleep(wait)
            for info in infos:
                a = max(math.ceil((lo - info.t0) * info.rate_hz - 1e-9), 0)
                b = max(math.ceil((hi - info.t0) * info.rate_hz - 1e-9), 0)
                if b > a:
                    yield SampleBatch(
                        info.name,
                        np.asarray(info.values[a:b], dtype=np.float64),
                        t0=origin + info.t0 + a / info.rate_hz,
                        rate_hz=info.rate_hz,
                    )
            yield None


# ----------------------------------------------------------------------- MQTT
def parse_payload(payload: bytes | str) -> tuple[list[SampleBatch], bool]:
    """Batches of one MQTT payload, and whether it ends the stream.

    Examples
    --------
    >>> batches, end = parse_payload('{"channels": {"P_In": {"t0": 10, "rate_hz": 2, '
    ...                              '"values": [6e5, 6.1e5]}}}')
    >>> batches[0].sample_times().tolist(), end
    ([10.0, 10.5], False)
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
    return out, bool(data.get("end", False))


class MqttSource:
    """Subscribe to an MQTT topic (paho-mqtt) and yield its batches."""

    def __init__(
        self,
        host: str,
        port: int,
        topic: str,
        tags: ChannelTags,
        log: Log = _quiet,
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
        self._queue: queue.Queue[tuple[list[SampleBatch], bool]] = queue.Queue()

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
            self.log(f"MQTT connection lost ({reason}); reconnecting")

        def on_message(_c: Any, _u: Any, message: Any) -> None:
            try:
                batches, end = parse_payload(message.payload)
                self._queue.put(([self.tags.to_si(b) for b in batches], end))
            except InputError as exc:
                self.bad_payloads += 1
                self.log(f"ignored a bad MQTT payload: {exc}")

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
            client.loop_stop()
            client.disconnect()


# --------------------------------------------------------------------- OPC UA
class OpcUaSource:
    """Subscribe to PLC tags on an OPC UA server (asyncua) and yield their changes."""

    def __init__(
        self,
        url: str,
        tags: ChannelTags,
        channels: Sequence[str],
        log: Log = _quiet,
        publish_ms: float = 50.0,
        watchdog_s: float = 10.0,
        accept_revised: bool = False,
    ) -> None:
        self.url = url
        self.shown = masked_url(url)  # what messages show: never the password
        self.tags = tags
        self.channels = tuple(channels)
        self.rates_hz = {c: tags.rates_hz[c] for c in self.channels}
        self.lateness_s = tags.lateness_s
        self.log = log
        self.publish_ms = publish_ms
        self.watchdog_s = watchdog_s
        self.accept_revised = accept_revised
        self.losses = LossLedger()
        self._queue: queue.Queue[SampleBatch | BaseException | None] = queue.Queue()
        self._stop = threading.Event()

    def __iter__(self) -> Iterator[SampleBatch | None]:
        thread = threading.Thread(target=self._thread, daemon=True, name="pneufdd-opcua")
        thread.start()
        try:
            while True:
                try:
                    item = self._queue.get(timeout=0.5)
                except queue.Empty:
                    yield None
                    continue
                if isinstance(item, StopIteration):
                    yield None
                    return
                if isinstance(item, BaseException):
                    raise item
                yield item
                if item is None:
                    continue
        finally:
            self._stop.set()
            thread.join(timeout=5.0)

    def _thread(self) -> None:
        try:
            asyncio.run(self._run())
        except BaseException as exc:  # pragma: no cover - reported to the consumer
            self._queue.put(exc)

    async def _run(self) -> None:
        from asyncua.client.client import Client
        from asyncua.ua.uaerrors import UaError

        source = self
        ended = asyncio.Event()
        nodes_by_id: dict[str, str] = {}

        class Handler:
            def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
                name = nodes_by_id.get(node.nodeid.to_string())
                if name is None:
                    return
                value = data.monitored_item.Value
                stamp = value.SourceTimestamp or value.ServerTimestamp
                if name == "__end__":
                    if bool(val):
                        ended.set()
                    return
                code = int(getattr(value.StatusCode, "value", 0) or 0)
                if stamp is None:
                    if not code:
                        return
                    stamp = datetime.now(_UTC)  # a Bad value may carry no time stamp
                t = stamp.timestamp() if stamp.tzinfo else stamp.replace(tzinfo=_UTC).timestamp()
                if not source.losses.observe(name, t, code) or val is None:
                    return  # Bad or Uncertain: the channel is unknown until a Good value
                batch = SampleBatch(name, np.array([float(val)]), times=np.array([t]))
                source._queue.put(source.tags.to_si(batch))

        attempt = 0
        checked = False  # the granted parameters are judged at the first connection
        while not self._stop.is_set():
            # the client probes the server's state every watchdog_s and gives it as long
            # to answer: a diagnosis that keeps this process busy for seconds must not
            # count as a lost connection (asyncua's 1 s default dropped the subscription,
            # and the samples of the reconnection gap with it, on a loaded machine)
            client = Client(self.url, timeout=self.watchdog_s, watchdog_intervall=self.watchdog_s)
            try:
                await client.connect()
            except (TimeoutError, OSError, UaError) as exc:
                attempt += 1
                if attempt == 1 or attempt % 10 == 0:
                    self.log(f"OPC UA server {self.shown} unreachable ({exc}); retrying")
                await asyncio.sleep(1.0)
                continue
            self.log(("reconnected to" if attempt else "connected to") + f" OPC UA {self.shown}")
            attempt = 1
            try:
                nodes = []
                for name in self.channels:
                    node = client.get_node(self.tags.nodes[name])
                    nodes_by_id[node.nodeid.to_string()] = name
                    nodes.append(node)
                if self.tags.end:
                    node = client.get_node(self.tags.end)
                    nodes_by_id[node.nodeid.to_string()] = "__end__"
                    nodes.append(node)
                names = [*self.channels, *(["__end__"] if self.tags.end else [])]
                await self._subscribe(client, Handler(), nodes, names, first=not checked)
                checked = True
                while not self._stop.is_set() and not ended.is_set():
                    await asyncio.sleep(0.2)
                    self._queue.put(None)
                    await client.check_connection()
                if ended.is_set():
                    await asyncio.sleep(max(self.publish_ms / 1000.0, 0.1) * 3)
                    self._queue.put(StopIteration())
                    await client.disconnect()
                    return
                await client.disconnect()
                return
            except SubscriptionRefusedError:
                with contextlib.suppress(Exception):
                    await client.disconnect()
                raise
            except (TimeoutError, OSError, ConnectionError, UaError) as exc:
                self.log(f"OPC UA connection to {self.shown} lost ({exc}); reconnecting")
                with contextlib.suppress(Exception):  # already broken
                    await client.disconnect()
                await asyncio.sleep(1.0)

    async def _subscribe(
        self, client: Any, handler: Any, nodes: list[Any], names: list[str], first: bool
    ) -> None:
        """Subscribe; check what the server grants against the channels' rates.

        At the first connection, parameters that cannot carry a channel's rate are
        said (one line per channel) and asked for once more (half the publishing
        interval, twice the queue the granted interval needs); if still short, the
        source refuses (:class:`~pneufdd.monitor.opcua.SubscriptionRefusedError`, exit 2)
        unless ``accept_revised`` (the URL's ``?accept_revised=1``): then it runs,
        and the cycles the server loses samples of are skipped.
        """
        interval = self.publish_ms
        queue = dict.fromkeys(self.channels, 10_000)
        sub, granted = await subscribe(client, handler, nodes, names, interval, queue)
        problems = grant_problems(self.rates_hz, interval, 10_000, granted)
        if not problems or not first:
            return
        for line in problems:
            self.log(line)
        await sub.delete()
        interval = interval / 2.0
        queue = {
            c: max(10_000, 2 * needed_queue(r, granted.publishing_ms))
            for c, r in self.rates_hz.items()
        }
        self.log(
            f"asking OPC UA {self.shown} again: publishing interval {interval:g} ms, "
            f"queue {max(queue.values())}"
        )
        sub, granted = await subscribe(client, handler, nodes, names, interval, queue)
        problems = grant_problems(self.rates_hz, interval, max(queue.values()), granted)
        if not problems:
            return
        for line in problems:
            self.log(line)
        if self.accept_revised:
            self.log(
                "accepting the revised parameters (accept_revised=1): cycles the server "
                "loses samples of are skipped and reported"
            )
            return
        await sub.delete()
        raise SubscriptionRefusedError(
            f"OPC UA server {self.shown} cannot deliver the rates the reference needs "
            f"({len(problems)} channel(s), above); lower the channels' rate_hz in the tag "
            "map (and build the reference at that rate), raise the server's queue and "
            "publishing limits, or add ?accept_revised=1 to the source to run anyway "
            "(cycles with lost samples are then skipped)"
        )


# --------------------------------------------------------------------- factory
def _replay_options(query: str) -> tuple[float, float]:
    params = urllib.parse.parse_qs(query, keep_blank_values=True)
    if set(params) - {"speed", "chunk"} or any(len(v) > 1 for v in params.values()):
        raise ValueError("an unknown or repeated replay option")  # a typo is no default
    speed_text = params.get("speed", ["1"])[0]
    speed = math.inf if speed_text == "max" else float(speed_text)
    chunk = float(params.get("chunk", ["1"])[0])
    return speed, chunk


def open_source(
    text: str,
    analog: Sequence[str],
    digital: Sequence[str],
    tags: Path | None = None,
    log: Log = _quiet,
) -> ReplaySource | MqttSource | OpcUaSource:
    """The source named by ``--source`` (see the module docstring)."""
    tag_map = (
        ChannelTags.read(tags, analog, digital)
        if tags is not None
        else ChannelTags.default(analog, digital)
    )
    if text.startswith("replay:"):
        path_text, _, query = text[len("replay:") :].partition("?")
        try:
            speed, chunk = _replay_options(query)
        except ValueError as exc:
            raise InputError(
                describe("--source replay options", query, "speed=<number>|max, chunk=<s>")
            ) from exc
        path = Path(path_text)
        if not path_text or not path.is_file():
            raise InputError(
                describe("--source replay file", path_text, "an existing recording file")
            )
        return ReplaySource(Recording.read(path), speed, chunk, log)
    shown = masked_url(text)  # messages never show a password
    try:
        parsed = urllib.parse.urlparse(text)
        port = parsed.port  # raises on a port that is no number from 0 to 65535
    except ValueError as exc:
        raise InputError(
            describe("--source", shown, f"a URL with a host and a port from 0 to 65535 ({exc})")
        ) from None
    if parsed.scheme == "mqtt":
        topic = parsed.path.lstrip("/")
        if not parsed.hostname or not topic:
            raise InputError(describe("--source", shown, "mqtt://host:port/topic"))
        options = dict(urllib.parse.parse_qsl(parsed.query))
        unknown = sorted(set(options) - {"client_id", "session_expiry", "protocol"})
        if unknown:
            raise InputError(
                describe("--source MQTT options", unknown, "client_id, session_expiry, protocol")
            )
        try:
            expiry = int(options.get("session_expiry", "3600"))
        except ValueError:
            raise InputError(
                describe("--source session_expiry", options["session_expiry"], "seconds (integer)")
            ) from None
        return MqttSource(
            parsed.hostname,
            port or 1883,
            topic,
            tag_map,
            log,
            client_id=options.get("client_id"),
            session_expiry_s=expiry,
            protocol=options.get("protocol", "5"),
        )
    if parsed.scheme == "opcua":
        address, _, query = text[len("opcua://") :].partition("?")
        options = dict(urllib.parse.parse_qsl(query))
        if set(options) - {"accept_revised"} or options.get("accept_revised", "0") not in (
            "0",
            "1",
        ):
            raise InputError(describe("--source OPC UA options", query, "accept_revised=0|1"))
        accept = options.get("accept_revised", "0") == "1"
        return OpcUaSource(
            "opc.tcp://" + address, tag_map, [*analog, *digital], log, accept_revised=accept
        )
    raise InputError(
        describe(
            "--source", shown, "replay:FILE[?speed=N], mqtt://host:port/topic, opcua://host:port"
        )
    )
