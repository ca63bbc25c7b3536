"""What a live MQTT source's payloads say about themselves (issue 32, items 1 and 4).

``pneufdd monitor`` runs as a user runs it, in its own process, against a mosquitto
broker started here; the test publishes a leak-free festo-dsd run as 2 s payloads:

- with sequence numbers, one payload never sent, one sent twice and two swapped:
  the missing payload makes the cycle it falls in skipped and reported (never scored),
  the repeat is dropped and counted, the swapped pair is sorted in; exit 0;
- with a first payload 1000 s newer than the rest (a source clock that jumped back):
  every later sample is late, which is said while the monitor runs; no cycle is
  judged, and the run says so and exits 2 instead of 0 ("no leak").
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from monitor_data import free_run, reference
from pneufdd.diagnosis.reference.file import save_reference
from pneufdd.monitor.cycles import needed_channels
from pneufdd.monitor.database import HistoryDatabase
from test_monitor_brokers import _payloads, mosquitto  # noqa: F401  (the broker fixture)


class _Monitor:
    """``pneufdd monitor --once`` in a process of its own; its standard error, line by line."""

    def __init__(self, args: list[str]) -> None:
        code = "import sys; from pneufdd.cli.app import main; sys.exit(main(sys.argv[1:]))"
        self.proc = subprocess.Popen(
            [sys.executable, "-c", code, "monitor", *args],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=os.environ | {"COLUMNS": "1000"},  # one line per message
        )
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, text: str, timeout: float = 120.0) -> None:
        end = time.monotonic() + timeout
        while not any(text in line for line in self.lines):
            assert self.proc.poll() is None, self.lines
            assert time.monotonic() < end, f"never saw {text!r}: {self.lines}"
            time.sleep(0.05)

    def finish(self, timeout: float = 300.0) -> int:
        code = self.proc.wait(timeout)
        self.reader.join(10)
        assert self.proc.stderr is not None
        self.proc.stderr.close()
        return code

    def summary(self) -> dict:
        return json.loads(next(x for x in reversed(self.lines) if x.startswith('{"cycles"')))


@pytest.fixture(scope="module")
def ref_file(tmp_path_factory) -> Path:
    return save_reference(reference(), tmp_path_factory.mktemp("sequence") / "ref.pnref")


def _start(ref: Path, tmp_path: Path, port: int, topic: str) -> _Monitor:
    tags = tmp_path / f"{topic}.toml"
    tags.write_text("lateness_s = 5.0\n")  # a swapped pair of 2 s payloads is sorted in
    return _Monitor(
        [
            "--reference",
            str(ref),
            "--source",
            f"mqtt://127.0.0.1:{port}/{topic}?client_id={topic}",
            "--tags",
            str(tags),
            "--history",
            f"sqlite:///{tmp_path / f'{topic}.db'}",
            "--once",
        ]
    )


def _publish(port: int, topic: str, bodies: list[bytes]) -> None:
    from paho.mqtt import publish

    msgs = [{"topic": topic, "payload": b, "qos": 1} for b in bodies]
    publish.multiple(msgs, hostname="127.0.0.1", port=port)


def test_sequence_gaps_repeats_and_swaps_and_a_clock_that_jumped_back(
    mosquitto,  # noqa: F811
    ref_file,
    tmp_path,
):
    port = mosquitto
    rec = free_run()
    analog, digital = needed_channels(reference())
    payloads = _payloads(rec, (*analog, *digital), block_s=2.0)
    starts = rec.metadata["cycle_start_s"]
    numbered = [json.dumps({"seq": k, **json.loads(p)}).encode() for k, p in enumerate(payloads)]
    lost = next(k for k in range(len(payloads)) if 2 * k > starts[2] + 4)  # in cycle 3
    repeat, swap = 8, next(k for k in range(len(payloads)) if 2 * k > starts[3] + 4)
    sent = [p for k, p in enumerate(numbered) if k != lost]
    sent.insert(repeat, numbered[repeat])  # sent twice
    i = sent.index(numbered[swap])
    sent[i], sent[i + 1] = sent[i + 1], sent[i]
    # the second run: one sample per channel 1000 s after the run, then the run itself
    t0 = rec.start_time.timestamp()
    ahead = {c: {"times": [t0 + 1000.0], "values": [0.0]} for c in (*analog, *digital)}
    gapped, jumped = (
        _start(ref_file, tmp_path, port, "seq"),
        _start(ref_file, tmp_path, port, "jump"),
    )
    gapped.wait_for("subscribed to MQTT topic")
    jumped.wait_for("subscribed to MQTT topic")
    _publish(port, "seq", [*sent, json.dumps({"end": True}).encode()])
    _publish(port, "jump", [json.dumps({"channels": ahead}).encode(), *payloads[:12]])
    jumped.wait_for("late samples dropped")  # said while it runs, before the end
    _publish(port, "jump", [json.dumps({"end": True}).encode()])

    assert gapped.finish() == 0, gapped.lines
    text = " ".join(" ".join(gapped.lines).split())
    assert f"MQTT payloads {lost}..{lost} missing (sequence numbers)" in text
    assert "dropped a duplicate MQTT payload (sequence number 8 came before)" in text
    assert "MQTT sequence numbers: 1 missing, 1 duplicate, 1 out of order" in text
    assert "samples arrived out of order and were sorted in" in text
    assert "connection lost" not in text  # a normal end is no lost connection
    summary = gapped.summary()
    assert summary["alarms"] == 0
    assert "local - sample" in summary["clock_offsets"]
    assert not [x for x in gapped.lines if "late samples" in x]
    # the cycle the lost payload falls in is never scored: skipped for lost samples, or
    # (its PLC signals broken) not complete at all and recorded as a gap; every cycle of
    # the run is accounted for
    history = HistoryDatabase(f"sqlite:///{tmp_path / 'seq.db'}")
    machine = history.machine_id("festo-dsd")
    rows = history.cycle_rows(machine)
    gone = (t0 + 2.0 * lost, t0 + 2.0 * lost + 2.0)
    assert not [r for r in rows if r["start"] < gone[1] and r["start"] + r["duration_s"] > gone[0]]
    lost_cycles = sum(g["cycles_lost"] for g in history.gap_rows(machine))
    history.close()
    assert len(rows) == summary["recorded"]
    assert len(rows) + summary["incomplete_skipped"] + lost_cycles == len(starts)
    assert summary["judged"] == len(rows) - 1  # all recorded but the start-up cycle

    assert jumped.finish() == 2, jumped.lines
    text = "\n".join(jumped.lines)
    said = text.index("late samples dropped")
    assert said < text.index('{"cycles"')
    assert "no cycle was judged" in text
    assert "says nothing about leaks" in text
    summary = jumped.summary()
    assert summary["judged"] == 0
    assert summary["leak_active"] is False
    assert np.isfinite(summary["seconds"])
