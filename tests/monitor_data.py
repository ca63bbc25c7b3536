"""Shared data of the monitor tests: a fast festo-dsd reference and runs (cached per process).

Seeds: 41_000 + k. The reference uses the supply sensors (P_In, Q_In) and a short
signature ladder so that it builds in seconds; the runs are a few cycles.
"""

from __future__ import annotations

import contextlib
import functools
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from pneufdd.diagnosis.recordings import build_reference_from_recordings
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.physics.units import slpm_to_kg_s
from pneufdd.recording import ANALOG, Channel, Recording
from pneufdd.sim import simulate
from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

SEED = 41_000
START = datetime(2026, 3, 1, 6, 0, tzinfo=UTC)


PLC_ANALOG_HZ = 50.0
"""Rate of analog tags as a PLC publishes them: the lowest analog rate the recording
checks accept (docs/data-quality.md) [Hz]."""


def free_port() -> int:
    """A TCP port free on the loopback interface now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def as_plc_tags(rec: Recording) -> Recording:
    """Analog channels as a PLC would publish them: block means at :data:`PLC_ANALOG_HZ`."""
    channels = []
    for name in rec.channels:
        info = rec.info(name)
        if info.kind != ANALOG:
            channels.append(info)
            continue
        n = round(info.rate_hz / PLC_ANALOG_HZ)
        values = np.asarray(info.values, dtype=np.float64)
        blocks = values[: values.size // n * n].reshape(-1, n).mean(axis=1)
        channels.append(Channel(name, blocks, PLC_ANALOG_HZ, info.unit, ANALOG, info.t0))
    return Recording(channels, start_time=rec.start_time, metadata=rec.metadata)


def _build(refs: list[Recording], channels: list[str]) -> ReferenceModel:
    return build_reference_from_recordings(
        refs,
        channels,
        signature_mass_flows=(slpm_to_kg_s(30.0), slpm_to_kg_s(120.0)),
        signature_cycles=1,
        uncertainty_plants=0,
        workers=1,
    )


@functools.cache
def reference(channels: tuple[str, ...] = ("P_In", "Q_In")) -> ReferenceModel:
    refs = [simulate("festo-dsd", cycles=8, seed=SEED + i) for i in range(2)]
    return _build(refs, list(channels))


@functools.cache
def plc_reference() -> ReferenceModel:
    """The supply-sensor reference of recordings whose analog tags a PLC publishes."""
    refs = [as_plc_tags(simulate("festo-dsd", cycles=8, seed=SEED + i)) for i in range(2)]
    return _build(refs, ["P_In", "Q_In"])


def started(rec: Recording, start: datetime = START) -> Recording:
    """The recording as if it started at ``start`` (wall clock)."""
    return Recording([rec.info(c) for c in rec.channels], start_time=start, metadata=rec.metadata)


@functools.cache
def leak_run(cycles: int = 7, appear_s: float = 40.0, seed: int = SEED + 10) -> Recording:
    """Supply leak of 4 turns appearing at ``appear_s`` (first cycle starting then)."""
    schedule = LeakSchedule([ScheduledLeak("supply", 4.0, start_s=appear_s)])
    return started(simulate("festo-dsd", cycles=cycles, seed=seed, schedule=schedule))


@functools.cache
def free_run(cycles: int = 5, seed: int = SEED + 11) -> Recording:
    return started(simulate("festo-dsd", cycles=cycles, seed=seed))


@contextlib.contextmanager
def running_mosquitto(folder: Path) -> Iterator[int]:
    """A mosquitto broker (MQTT 5) on a free loopback port; the test is skipped without it.

    amqtt (in-process) keeps no sessions, so persistent sessions and retained state are
    tested against mosquitto (``apt-get install mosquitto``, best effort in .ci/run).
    """
    binary = shutil.which("mosquitto") or next(
        (str(p) for p in (Path("/usr/sbin/mosquitto"),) if p.exists()), None
    )
    if binary is None:
        pytest.skip("mosquitto is not installed (apt-get install mosquitto)")
    port = free_port()
    config = folder / "mosquitto.conf"
    config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
    proc = subprocess.Popen(
        [binary, "-c", str(config)],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        end = time.monotonic() + 20
        while True:
            with socket.socket() as s, contextlib.suppress(OSError):
                s.connect(("127.0.0.1", port))
                break
            assert proc.poll() is None, "mosquitto exited"
            assert time.monotonic() < end, "mosquitto did not start"
            time.sleep(0.1)
        yield port
    finally:
        proc.terminate()
        proc.wait(10)
