"""The monitor as a client of real servers started here: an MQTT broker (amqtt, in
process) and an OPC UA server (asyncua, in a thread) publishing a simulated festo-dsd
recording with a supply leak that appears mid-run (shortened: a few cycles, faster
than real time). The monitor's alarms and history are asserted.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import threading
import time
from datetime import UTC, datetime

import numpy as np
import pytest

from monitor_data import (
    PLC_ANALOG_HZ,
    as_plc_tags,
    free_port,
    leak_run,
    plc_reference,
    reference,
    running_mosquitto,
)
from pneufdd.errors import InputError
from pneufdd.monitor.alarms import AlarmSinks
from pneufdd.monitor.cycles import needed_channels
from pneufdd.monitor.database import HistoryDatabase
from pneufdd.monitor.live import MachineMonitor
from pneufdd.monitor.samples import SampleBatch
from pneufdd.monitor.sources import ChannelTags, MqttSource, OpcUaSource
from pneufdd.monitor.stream import run_stream
from pneufdd.physics.units import kg_s_to_l_min_anr, pa_to_bar_gauge
from pneufdd.recording.model import ANALOG, Recording


class _Loop:
    """An asyncio loop in a thread, for servers."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()

    def run(self, coro, timeout=60.0):
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def close(self) -> None:
        """Close what the servers left open on this loop, then the loop.

        amqtt's broker keeps its sessions' streams after ``shutdown``; left to the
        garbage collector they would warn (ResourceWarning) in whichever test runs next.
        """
        loop = self.loop

        async def tidy() -> None:
            gc.collect()
            for obj in gc.get_objects():
                if getattr(obj, "_loop", None) is loop and isinstance(
                    obj, asyncio.BaseTransport | asyncio.AbstractServer
                ):
                    obj.close()
            await asyncio.sleep(0.2)

        with contextlib.suppress(Exception):
            self.run(tidy(), timeout=30)
        loop.call_soon_threadsafe(loop.stop)
        self.thread.join(5)
        loop.close()
        gc.collect()


def _wait_for(log: list[str], text: str, count: int = 1, timeout: float = 180.0) -> None:
    end = time.monotonic() + timeout
    while sum(text in m for m in log) < count:
        assert time.monotonic() < end, f"never saw {text!r} in {log}"
        time.sleep(0.05)


def _check_history(
    db: HistoryDatabase, rec: Recording, sinks: AlarmSinks, skipped: int = 0
) -> None:
    machine = db.machine_id("festo-dsd")
    starts = rec.metadata["cycle_start_s"]
    recorded = db.cycle_starts(machine)
    t0 = rec.start_time.timestamp()
    # every cycle but possibly the last (closed only at the stream's end) is recorded once,
    # at the PLC's time (within a grid sample), unless it was skipped for lost samples
    assert len(recorded) >= len(starts) - 1 - skipped
    expected = t0 + np.array(starts)
    nearest = np.abs(np.asarray(recorded)[:, None] - expected[None, :]).min(axis=1)
    assert np.all(nearest <= 0.06), nearest
    assert len(set(np.round(recorded, 1))) == len(recorded)  # each cycle once
    leak_alarms = [a for a in sinks.sent if a.kind == "leak"]
    assert len(leak_alarms) == 1
    alarm = leak_alarms[0]
    assert alarm.machine == "festo-dsd"
    assert "supply" in alarm.locations
    assert alarm.flow_slpm > 30.0
    assert alarm.annual_cost > 0
    assert 0 < alarm.confidence <= 1
    first_leaky = next(i for i, t in enumerate(starts) if t >= 40.0)
    latest = first_leaky + 2 + skipped  # a skipped cycle is no evidence: one later each
    assert t0 + starts[first_leaky] <= alarm.time <= t0 + starts[latest] + 0.1
    assert db.alarm_rows(machine)[0]["locations"] == list(alarm.locations)
    assert db.integrity_ok()


# ----------------------------------------------------------------------------- MQTT
def _payloads(
    rec: Recording,
    channels: tuple[str, ...],
    block_s: float = 2.0,
    names: dict[str, str] | None = None,
    convert: dict[str, object] | None = None,
) -> list[bytes]:
    """JSON payloads of ``rec``; ``names``: channel -> published tag, ``convert``:
    channel -> function from SI to the published unit."""
    names = names or {}
    convert = convert or {}
    t0 = rec.start_time.timestamp()
    out = []
    for k in range(int(np.ceil(rec.duration / block_s))):
        body = {}
        for name in channels:
            info = rec.info(name)
            a, b = round(k * block_s * info.rate_hz), round((k + 1) * block_s * info.rate_hz)
            values = np.asarray(info.values[a:b], dtype=np.float64)
            if name in convert:
                values = np.asarray(convert[name](values), dtype=np.float64)  # type: ignore[operator]
            if values.size:
                body[names.get(name, name)] = {
                    "t0": t0 + info.t0 + a / info.rate_hz,
                    "rate_hz": info.rate_hz,
                    "values": values.tolist(),
                }
        out.append(json.dumps({"channels": body}).encode())
    return out


def _plc_tag_map(tmp_path, analog, digital) -> tuple[dict[str, str], dict[str, object]]:
    """A file-import style map (PLC tags, bar(g), l/min ANR) for the monitor."""
    names = {c: f"DB10.{c.replace('_', '.')}" for c in (*analog, *digital)}
    lines = ["lateness_s = 1.0", "[columns]"]
    for c in digital:
        lines.append(f'"{names[c]}" = {{ role = "{c}" }}')
    units = {"P_In": 'unit = "bar(g)"', "Q_In": 'unit = "l/min", basis = "ANR"'}
    for c in analog:
        lines.append(f'"{names[c]}" = {{ role = "{c}", {units[c]} }}')
    (tmp_path / "plc-tags.toml").write_text("\n".join(lines) + "\n")
    return names, {"P_In": pa_to_bar_gauge, "Q_In": kg_s_to_l_min_anr}


def test_monitor_over_mqtt_survives_a_broker_restart(tmp_path):
    from amqtt.broker import Broker
    from paho.mqtt import publish

    model = reference()
    rec = leak_run()
    analog, digital = needed_channels(model)
    port = free_port()
    config = {
        "listeners": {"default": {"type": "tcp", "bind": f"127.0.0.1:{port}"}},
        "plugins": {"amqtt.plugins.authentication.AnonymousAuthPlugin": {"allow_anonymous": True}},
    }
    loop = _Loop()

    async def start() -> Broker:
        broker = Broker(config)
        await broker.start()
        return broker

    broker = loop.run(start())
    log: list[str] = []
    db = HistoryDatabase(f"sqlite:///{tmp_path / 'mqtt.db'}")
    sinks = AlarmSinks()
    monitor = MachineMonitor(model, db, alarm=sinks)
    # the plant's own tag map, as written for `pneufdd import`: PLC tag names, bar(g),
    # l/min (ANR); the monitor brings the live values to SI with the import's conversion
    names, convert = _plc_tag_map(tmp_path, analog, digital)
    tags = ChannelTags.read(tmp_path / "plc-tags.toml", analog, digital)
    assert tags.aliases["DB10.P.In"] == "P_In"
    assert tags.units == {"P_In": "bar(g)", "Q_In": "l/min (ANR)"}
    source = MqttSource(
        "127.0.0.1", port, "plant/festo-dsd/samples", tags, log=log.append, protocol="3.1.1"
    )  # amqtt speaks MQTT 3.1.1
    result: dict[str, object] = {}

    def consume() -> None:
        try:
            result["stats"] = run_stream(monitor, source, source.rates_hz, source.lateness_s)
        except BaseException as exc:  # pragma: no cover - reported below
            result["error"] = exc

    thread = threading.Thread(target=consume, daemon=True)
    thread.start()
    try:
        _wait_for(log, "subscribed to MQTT topic")
        payloads = _payloads(rec, (*analog, *digital), names=names, convert=convert)
        half = len(payloads) // 2
        topic = "plant/festo-dsd/samples"
        msgs = [{"topic": topic, "payload": p, "qos": 1} for p in payloads[:half]]
        publish.multiple(msgs, hostname="127.0.0.1", port=port)
        # the broker goes away once the monitor has had the first half (its third cycle
        # closed), so only what is in flight can be lost
        deadline = time.monotonic() + 120.0
        while len(db.cycle_starts(db.machine_id("festo-dsd"))) < 3:
            assert time.monotonic() < deadline, "the monitor did not consume the first half"
            time.sleep(0.1)
        time.sleep(1.0)
        loop.run(broker.shutdown())  # the broker goes away ...
        _wait_for(log, "connection lost")
        broker = loop.run(start())  # ... and comes back
        _wait_for(log, "reconnected to MQTT")
        _wait_for(log, "subscribed to MQTT topic", count=2)
        msgs = [{"topic": topic, "payload": p, "qos": 1} for p in payloads[half:]]
        msgs.append({"topic": topic, "payload": json.dumps({"end": True}), "qos": 1})
        publish.multiple(msgs, hostname="127.0.0.1", port=port)
        thread.join(600)
        assert not thread.is_alive()
        assert "error" not in result, result.get("error")
        # samples in flight when the broker stopped are lost (amqtt keeps no session): a
        # cycle that lost them is skipped and stored as a gap, never scored, never lost
        # unreported
        skipped = monitor.stats.incomplete
        _check_history(db, rec, sinks, skipped)
        machine = db.machine_id("festo-dsd")
        assert len(db.cycle_starts(machine)) + skipped == len(rec.metadata["cycle_start_s"])
        if skipped:
            assert db.gap_rows(machine)
    finally:
        db.close()
        loop.run(broker.shutdown())
        loop.close()


@pytest.fixture
def mosquitto(tmp_path):
    """A mosquitto broker (MQTT 5) on a free port; skipped when it is not installed.

    amqtt (the in-process broker above) does not keep sessions (its CONNACK says
    session_present=False after a clean-session-off reconnect), so the persistent session
    is tested against mosquitto (``apt-get install mosquitto``, best effort like PostgreSQL).
    """
    with running_mosquitto(tmp_path) as port:
        yield port


def _receive(source: MqttSource, want: int, log: list[str], timeout: float = 60.0) -> list[float]:
    """Iterate ``source`` until ``want`` batches came (their first value each), then stop."""
    got: list[float] = []
    end = time.monotonic() + timeout
    stream = iter(source)
    try:
        for item in stream:
            if item is not None:
                got.append(float(item.values[0]))
            if len(got) >= want or time.monotonic() > end:
                break
    finally:
        stream.close()  # the client disconnects; its session stays on the broker
    return got


def test_mqtt_keeps_a_persistent_session_so_messages_sent_while_away_arrive(mosquitto):
    """pneufdd away (stopped), the broker up: QoS 1 messages published meanwhile are
    delivered when it comes back under the same client id (MQTT 5, clean start off,
    session expiry 3600 s)."""
    from paho.mqtt import publish

    port = mosquitto
    tags = ChannelTags({"P_In": "ns=2;s=P_In"}, {"P_In": 10.0}, lateness_s=0.0)
    topic = "plant/line1/samples"

    def payload(value: float) -> dict[str, object]:
        body = {"channels": {"P_In": {"t0": 1.77e9 + value, "rate_hz": 10, "values": [value]}}}
        return {"topic": topic, "payload": json.dumps(body), "qos": 1}

    log: list[str] = []
    first = MqttSource("127.0.0.1", port, topic, tags, log=log.append)
    assert first.client_id.startswith("pneufdd-")
    thread_result: dict[str, list[float]] = {}
    thread = threading.Thread(target=lambda: thread_result.update(got=_receive(first, 1, log)))
    thread.start()
    _wait_for(log, "subscribed to MQTT topic")
    publish.multiple([payload(1.0)], hostname="127.0.0.1", port=port)
    thread.join(60)
    assert thread_result["got"] == [1.0]
    time.sleep(0.5)
    publish.multiple([payload(2.0), payload(3.0)], hostname="127.0.0.1", port=port)  # away
    again = MqttSource("127.0.0.1", port, topic, tags, log=log.append)
    assert again.client_id == first.client_id  # the same session
    assert _receive(again, 2, log) == [2.0, 3.0]


def test_mqtt_source_options_from_the_url():
    from pneufdd.monitor.sources import open_source

    source = open_source("mqtt://b:1884/t?client_id=line1&session_expiry=600", ["P_In"], [])
    assert isinstance(source, MqttSource)
    assert (source.client_id, source.session_expiry_s, source.protocol) == ("line1", 600, "5")
    default = open_source("mqtt://b/t", ["P_In"], [])
    assert isinstance(default, MqttSource)
    assert default.session_expiry_s == 3600
    assert default.client_id == open_source("mqtt://b/t", ["P_In"], []).client_id  # stable
    for bad in ("mqtt://b/t?protocol=4", "mqtt://b/t?session_expiry=soon", "mqtt://b/t?qos=0"):
        with pytest.raises(InputError):
            open_source(bad, ["P_In"], [])


# ---------------------------------------------------------------------------- OPC UA
SPEED = 8.0


async def _serve(
    rec: Recording, port: int, ready: asyncio.Event, go: asyncio.Event, finish: asyncio.Event
) -> None:
    """Publish ``rec`` once ``go`` is set; stay up, as a PLC does, until ``finish``."""
    from asyncua import Server, ua

    server = Server()
    await server.init()
    server.set_endpoint(f"opc.tcp://127.0.0.1:{port}/pneufdd/")
    idx = await server.register_namespace("urn:pneufdd:test-plc")
    plc = await server.nodes.objects.add_object(idx, "festo-dsd")
    t0 = rec.start_time.timestamp()

    def stamp(t: float) -> datetime:
        return datetime.fromtimestamp(t0 + t, UTC)

    def value(v: float, t: float, bool_: bool = False) -> object:
        kind = ua.VariantType.Boolean if bool_ else ua.VariantType.Double
        return ua.DataValue(
            Value=ua.Variant(bool(v) if bool_ else float(v), kind), SourceTimestamp=stamp(t)
        )

    nodes = {}
    async with server:
        for name in rec.channels:
            node = await plc.add_variable(ua.NodeId(name, idx), name, 0.0)
            await node.write_value(value(rec.info(name).values[0], 0.0))
            nodes[name] = node
        done = await plc.add_variable(ua.NodeId("ReplayDone", idx), "ReplayDone", False)
        await done.write_value(value(0, 0.0, bool_=True))
        ready.set()
        await go.wait()
        # every analog sample, every digital change, in time order at SPEED x real time
        events = []
        for name in rec.channels:
            info = rec.info(name)
            v = np.asarray(info.values, dtype=np.float64)
            k = np.arange(1, v.size) if info.kind == ANALOG else np.flatnonzero(np.diff(v)) + 1
            events += [(info.t0 + i / info.rate_hz, name, v[i]) for i in k]
        events.sort()
        began = time.monotonic()
        for t, name, v in events:
            wait = began + t / SPEED - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
            await nodes[name].write_value(value(v, t))
        await asyncio.sleep(0.5)
        await done.write_value(value(1, rec.duration, bool_=True))
        await finish.wait()


def test_monitor_as_an_opc_ua_client_of_a_plc(tmp_path):
    model = plc_reference()
    rec = as_plc_tags(leak_run())
    analog, digital = needed_channels(model)
    port = free_port()
    # lateness is in the data's time: the replay runs SPEED x real time, so SPEED s of
    # data time is the 1 s of wall time a live PLC gets (1 s of data time, 0.125 s of
    # wall time, lost late samples and with them two cycles on a loaded 2-core machine)
    toml = [f"lateness_s = {SPEED:g}", 'end = "ns=2;s=ReplayDone"']
    for name in (*analog, *digital):
        rate = PLC_ANALOG_HZ if name in analog else 100.0
        toml += [f"[channels.{name}]", f'node = "ns=2;s={name}"', f"rate_hz = {rate}"]
    tags_path = tmp_path / "tags.toml"
    tags_path.write_text("\n".join(toml) + "\n")
    tags = ChannelTags.read(tags_path, analog, digital)
    loop = _Loop()
    ready, go, finish = asyncio.Event(), asyncio.Event(), asyncio.Event()
    serving = asyncio.run_coroutine_threadsafe(_serve(rec, port, ready, go, finish), loop.loop)
    log: list[str] = []
    db = HistoryDatabase(f"sqlite:///{tmp_path / 'opcua.db'}")
    sinks = AlarmSinks()
    try:
        deadline = time.monotonic() + 180
        while not ready.is_set():
            assert time.monotonic() < deadline
            assert not serving.done()
            time.sleep(0.05)
        monitor = MachineMonitor(model, db, alarm=sinks)
        # asyncua's server reports its publishing interval (50 ms) as every item's
        # sampling interval although it notifies every write: too slow on paper for the
        # 100 Hz PLC signals, so the run accepts the revised parameters (and would
        # skip any cycle the server said it lost samples of)
        source = OpcUaSource(
            f"opc.tcp://127.0.0.1:{port}/pneufdd/",
            tags,
            [*analog, *digital],
            log=log.append,
            accept_revised=True,
        )
        result: dict[str, object] = {}

        def consume() -> None:
            try:
                result["stats"] = run_stream(monitor, source, source.rates_hz, source.lateness_s)
            except BaseException as exc:  # pragma: no cover - reported below
                result["error"] = exc

        thread = threading.Thread(target=consume, daemon=True)
        thread.start()
        _wait_for(log, "connected to OPC UA")
        time.sleep(1.0)  # the subscription delivers the initial values
        loop.loop.call_soon_threadsafe(go.set)
        thread.join(rec.duration / SPEED + 600)
        assert not thread.is_alive(), log
        assert "error" not in result, result.get("error")
        # a busy monitor (estimating beside the ingestion) is not a lost server
        assert not any("lost" in m for m in log), [m for m in log if "lost" in m]
        assert any("sampling interval 50 ms granted" in m for m in log), log
        _check_history(db, rec, sinks)
        loop.loop.call_soon_threadsafe(finish.set)
        serving.result(30)
    finally:
        loop.loop.call_soon_threadsafe(finish.set)
        db.close()
        loop.close()


# ------------------------------------------------------------------ tag maps
def test_one_tag_map_for_files_and_live_sources(tmp_path):
    path = tmp_path / "tags.toml"
    path.write_text(
        "lateness_s = 2.0\n"
        "[columns]\n"
        '"t" = { role = "time", unit = "s" }\n'
        '"B_P1" = { role = "P_In", unit = "bar(g)", rate_hz = 50 }\n'
        '"B_F1" = { role = "Q_In", unit = "l/min", basis = "ANR", node = "ns=3;s=F1" }\n'
        '"Y1.0" = "U_FEED_A"\n'
    )
    tags = ChannelTags.read(path, ["P_In", "Q_In"], ["U_FEED_A"])
    assert tags.nodes == {"P_In": "ns=2;s=B_P1", "Q_In": "ns=3;s=F1", "U_FEED_A": "ns=2;s=Y1.0"}
    assert tags.rates_hz["P_In"] == 50.0
    assert tags.lateness_s == 2.0
    # 5 bar(g) is 601,325 Pa absolute; 60 l/min ANR is 1.185 g/s (ISO 8778 reference
    # air: 20 degC, 100 kPa, 65 % RH, 1.185 kg/m3)
    p = tags.to_si(SampleBatch("B_P1", np.array([5.0]), t0=0.0, rate_hz=50.0))
    assert p.channel == "P_In"
    assert p.values[0] == pytest.approx(601_325.0)
    q = tags.to_si(SampleBatch("Q_In", np.array([60.0]), t0=0.0, rate_hz=50.0))
    assert q.values[0] == pytest.approx(1.185e-3, rel=1e-9)
    u = SampleBatch("Y1.0", np.array([1.0]), t0=0.0, rate_hz=100.0)
    assert tags.to_si(u).channel == "U_FEED_A"


def test_the_channel_form_of_the_tag_map(tmp_path):
    path = tmp_path / "tags.toml"
    path.write_text(
        'lateness_s = 2.5\nend = "ns=2;s=ReplayDone"\n'
        '[channels.P_In]\nnode = "ns=3;s=P"\nrate_hz = 20\n[channels.U_FEED_A]\nrate_hz = 50\n'
    )
    tags = ChannelTags.read(path, ["P_In", "Q_In"], ["U_FEED_A"])
    assert tags.nodes == {"P_In": "ns=3;s=P", "Q_In": "ns=2;s=Q_In", "U_FEED_A": "ns=2;s=U_FEED_A"}
    assert tags.rates_hz == {"P_In": 20.0, "Q_In": 1000.0, "U_FEED_A": 50.0}
    assert (tags.end, tags.lateness_s, tags.aliases, tags.units) == (
        "ns=2;s=ReplayDone",
        2.5,
        {},
        {},
    )
    batch = SampleBatch("P_In", np.array([6e5]), t0=0.0, rate_hz=20.0)
    assert tags.to_si(batch) is batch  # SI already
    path.write_text("")  # an empty map: every channel at the defaults
    assert ChannelTags.read(path, ["P_In"], []) == ChannelTags.default(["P_In"], [])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ('[channels.P_In]\nnode = "a"\n[columns]\n"B" = "P_In"\n', "both"),
        ('[channels.P_In]\nrate_hz = "fast"\n', "rate_hz"),
        ("[channels.P_In]\nrat_hz = 20\n", "rat_hz"),
        ("lateness_s = -1\n[channels.P_In]\nrate_hz = 20\n", "lateness_s"),
        (
            '[columns]\n"B" = { role = "P_In", unit = "bar(g)", rate_hz = 0 }\n"Y" = "U_X_A"\n',
            "rate_hz",
        ),
        ('[columns]\n"B" = { role = "Q_In", unit = "l/min" }\n"Y" = "U_X_A"\n', "basis"),
    ],
)
def test_tag_map_errors_name_the_file_and_entry(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(InputError, match=match) as info:
        ChannelTags.read(path, ["P_In", "Q_In"], ["U_X_A"])
    assert "bad.toml" in str(info.value)
