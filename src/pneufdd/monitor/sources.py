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

import math
import time as wallclock
import urllib.parse
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.limits import (
    MAX_REPLAY_CHUNK_S,
    MAX_REPLAY_SPEED,
    MIN_REPLAY_CHUNK_S,
    MIN_REPLAY_SPEED,
)
from pneufdd.monitor.database import masked_url
from pneufdd.monitor.mqtt import MqttSource, parse_payload
from pneufdd.monitor.opcua_source import OpcUaSource
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
