"""Results back to the plant: the monitor's OPC UA server, MQTT messages and metrics.

One real monitor run (a festo-dsd replay whose 4-turn supply leak appears at 40 s)
publishes to all three at once; each is then read by a client of another library and
compared with the history the same run wrote:

- OPC UA: an open62541 client (``o6``) over Basic256Sha256 SignAndEncrypt with a user
  name and password of the users file;
- MQTT: a paho subscriber connecting *after* the run gets the retained state and
  diagnosis from a mosquitto broker the test starts;
- Prometheus: ``prometheus_client.parser`` parses ``/metrics``.
"""

from __future__ import annotations

import asyncio
import importlib.util
import json
import math
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

import pytest
import tomli_w

from monitor_data import free_port, leak_run, reference, running_mosquitto
from pneufdd.errors import InputError
from pneufdd.monitor.credentials import hash_password
from pneufdd.monitor.database import HistoryDatabase
from pneufdd.monitor.live import MachineMonitor
from pneufdd.monitor.metrics import MonitorMetrics
from pneufdd.monitor.publish import Publishers
from pneufdd.monitor.publish_mqtt import MqttPublisher
from pneufdd.monitor.publish_opcua import OpcUaPublisher, ensure_certificate
from pneufdd.monitor.sources import ReplaySource
from pneufdd.monitor.stream import run_stream

PASSWORD = "correct horse battery"
BASIC256SHA256 = "http://opcfoundation.org/UA/SecurityPolicy#Basic256Sha256"


def _users(folder: Path) -> Path:
    path = folder / "users.toml"
    entry = {"role": "viewer", "password_hash": hash_password(PASSWORD)}
    path.write_text(tomli_w.dumps({"users": {"scada": entry}}))
    return path


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    with running_mosquitto(tmp_path_factory.mktemp("broker")) as port:
        yield port


@pytest.fixture(scope="module")
def published(tmp_path_factory, request):
    """The monitor run with every publisher; they stay up until the module ends."""
    folder = tmp_path_factory.mktemp("publish")
    try:
        mqtt_port = request.getfixturevalue("broker")
    except pytest.skip.Exception:
        mqtt_port = None
    users = _users(folder)
    opc_port, metrics_port = free_port(), free_port()
    warnings: list[str] = []
    opc = OpcUaPublisher(
        f"opcua://127.0.0.1:{opc_port}?users={users}&certs={folder / 'server'}", warnings.append
    )
    made: list = [opc]
    if mqtt_port is not None:
        made.append(MqttPublisher(f"mqtt://127.0.0.1:{mqtt_port}/plant/line1", warnings.append))
    metrics = MonitorMetrics()
    metrics.serve(metrics_port)
    made.append(metrics)
    hook = Publishers(made, warnings.append)
    db = HistoryDatabase(f"sqlite:///{folder / 'h.db'}")
    monitor = MachineMonitor(reference(), db, publish=hook)
    source = ReplaySource(leak_run(), speed=math.inf)
    stats = run_stream(monitor, source, source.rates_hz, source.lateness_s)
    if mqtt_port is not None:
        made[1].close()  # flush the MQTT messages; the broker keeps them (retained)
    yield {
        "db": db,
        "monitor": monitor,
        "stats": stats,
        "opc_port": opc_port,
        "metrics_port": metrics_port,
        "mqtt_port": mqtt_port,
        "folder": folder,
        "server_cert": opc.cert,
        "warnings": warnings,
    }
    opc.close()
    metrics.close()
    db.close()


def _truth(db: HistoryDatabase) -> dict:
    machine_id = db.machines()[0][0]
    cycles = db.cycle_rows(machine_id)
    active = db.leak_rows(machine_id, active_only=True)
    return {
        "last": cycles[-1],
        "active": {row.location: row for row in active},
        "alarms": db.alarm_rows(machine_id),
    }


def test_the_run_declared_and_located_the_leak(published):
    truth = _truth(published["db"])
    assert published["warnings"] == []
    assert [a["kind"] for a in truth["alarms"]] == ["leak"]
    assert list(truth["active"]) == ["supply"]


def _o6_read(published, nodes: list[str], password: str = PASSWORD) -> dict:
    """Read ``nodes`` with an open62541 client (o6) in its own process (tests/o6_client.py)."""
    if importlib.util.find_spec("o6") is None:
        pytest.skip("o6 (open62541) is not installed: pip install -e '.[dev]'")
    # o6 is imported only by the client's own process: the free o6 build ends the process
    # that imports it ten minutes later, which must never be a pytest worker
    cert, key = ensure_certificate(published["folder"] / "client", "localhost")
    args = {
        "url": f"opc.tcp://127.0.0.1:{published['opc_port']}/pneufdd",
        "cert": str(cert),
        "key": str(key),
        "trust": str(published["server_cert"]),
        "policy": BASIC256SHA256,
        "application_uri": "urn:pneufdd:monitor:server",
        "user": "scada",
        "password": password,
        "nodes": nodes,
    }
    done = subprocess.run(
        [sys.executable, str(Path(__file__).with_name("o6_client.py"))],
        input=json.dumps(args),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def test_an_open62541_client_reads_the_nodes_over_signandencrypt(published):
    names = (
        "State",
        "InAlarm",
        "CycleScore",
        "Cusum",
        "ActiveLeaks",
        "LeakFlowSLPM",
        "AnnualCost",
        "Findings",
        "LastAlarm",
        "LastCycle",
    )
    ns = "ns=2;s=festo-dsd"
    nodes = [f"{ns}.{n}" for n in names] + [
        f"{ns}.Leaks.supply.FlowSLPM",
        f"{ns}.Leaks.supply.Location",
    ]
    answer = _o6_read(published, nodes)
    assert "values" in answer, answer
    got = answer["values"]
    read = {name: got[f"{ns}.{name}"] for name in names}
    truth = _truth(published["db"])
    leak = truth["active"]["supply"]
    assert read["State"] == "leak"
    assert read["InAlarm"] is True
    assert read["ActiveLeaks"] == 1
    assert read["CycleScore"] == pytest.approx(truth["last"]["score"], rel=1e-12)
    assert read["Cusum"] == pytest.approx(truth["last"]["cusum"], rel=1e-12)
    assert read["LeakFlowSLPM"] == pytest.approx(leak.flow_slpm, rel=1e-12)
    assert got[f"{ns}.Leaks.supply.FlowSLPM"] == pytest.approx(leak.flow_slpm, rel=1e-12)
    assert got[f"{ns}.Leaks.supply.Location"] == "supply"
    assert read["AnnualCost"] == pytest.approx(leak.annual_cost, rel=1e-12)
    assert [f["location"] for f in json.loads(read["Findings"])] == ["supply"]
    assert json.loads(read["LastAlarm"])["locations"] == truth["alarms"][-1]["locations"]
    assert read["LastCycle"] == pytest.approx(truth["last"]["start"], abs=1e-3)


def test_the_server_offers_only_basic256sha256_signandencrypt_and_checks_passwords(published):
    from asyncua import Client

    async def endpoints() -> list:
        client = Client(f"opc.tcp://127.0.0.1:{published['opc_port']}/pneufdd")
        return list(await client.connect_and_get_server_endpoints())

    found = asyncio.run(endpoints())
    assert {(e.SecurityMode.value, e.SecurityPolicyUri) for e in found} == {(3, BASIC256SHA256)}
    assert {t.TokenType.name for e in found for t in e.UserIdentityTokens} == {"UserName"}
    refused = _o6_read(published, ["ns=2;s=festo-dsd.State"], password="wrong password")
    assert "error" in refused


def test_a_late_mqtt_subscriber_gets_the_retained_state_and_diagnosis(published):
    if published["mqtt_port"] is None:
        pytest.skip("mosquitto is not installed (apt-get install mosquitto)")
    import paho.mqtt.client as mqtt
    from paho.mqtt.enums import CallbackAPIVersion

    got: dict[str, dict] = {}
    done = threading.Event()

    def on_message(_c, _u, message) -> None:
        got[message.topic] = {"retain": message.retain, **json.loads(message.payload)}
        if {f"plant/line1/festo-dsd/{t}" for t in ("state", "diagnosis", "alarm")} <= got.keys():
            done.set()

    client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv5)
    client.on_message = on_message
    client.on_connect = lambda c, *_: c.subscribe("plant/line1/#", qos=1)
    client.connect("127.0.0.1", published["mqtt_port"])
    client.loop_start()
    try:
        assert done.wait(20), f"retained messages missing: {sorted(got)}"
    finally:
        client.loop_stop()
        client.disconnect()
    truth = _truth(published["db"])
    state = got["plant/line1/festo-dsd/state"]
    assert state["retain"] is True
    assert state["schema"] == "pneufdd.state/1"
    assert state["state"] == "leak"
    assert state["score"] == pytest.approx(truth["last"]["score"], rel=1e-12)
    assert state["timestamp"] == pytest.approx(truth["last"]["start"], abs=1e-6)
    assert [f["location"] for f in state["findings"]] == ["supply"]
    assert state["findings"][0]["flow_slpm"] == pytest.approx(
        truth["active"]["supply"].flow_slpm, rel=1e-12
    )
    diagnosis = got["plant/line1/festo-dsd/diagnosis"]
    assert diagnosis["retain"] is True
    assert [x["location"] for x in diagnosis["leaks"]] == ["supply"]
    assert got["plant/line1/festo-dsd/alarm"]["kind"] == "leak"


def test_metrics_parse_and_match_the_history(published):
    from prometheus_client.parser import text_string_to_metric_families

    url = f"http://127.0.0.1:{published['metrics_port']}/metrics"
    with urllib.request.urlopen(url, timeout=10) as response:
        text = response.read().decode()
    samples = {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(text)
        for s in family.samples
    }
    truth = _truth(published["db"])
    machine = ("machine", "festo-dsd")
    stats = published["stats"]
    assert samples[("pneufdd_cycles_total", (machine,))] == stats.cycles - stats.incomplete
    assert samples[("pneufdd_alarms_total", (("kind", "leak"), machine))] == 1
    assert samples[("pneufdd_in_alarm", (machine,))] == 1
    flow = samples[("pneufdd_leak_flow_slpm", (("location", "supply"), machine))]
    assert flow == pytest.approx(truth["active"]["supply"].flow_slpm, rel=1e-12)


def test_publish_options_are_checked_at_start(tmp_path):
    users = _users(tmp_path)
    for url in (
        "opcua://0.0.0.0:4841?anonymous=1",  # anonymous only on the loopback
        "opcua://127.0.0.1:4841",  # neither users nor anonymous
        f"opcua://127.0.0.1:4841?users={users}&color=red",
        "mqtt://user:secret@broker/plant",  # credentials only from the environment
        "mqtt://broker/",  # no topic
        "ftp://broker/x",
    ):
        with pytest.raises(InputError) as caught:
            OpcUaPublisher(url) if url.startswith("opcua") else MqttPublisher(url)
        assert "--publish" in str(caught.value)
        assert "secret" not in str(caught.value)
