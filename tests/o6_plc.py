"""A PLC stand-in: an open62541 server (``o6``) in a process of its own, writing a recording's tags.

The free o6 build shuts down the process that imported it 10 minutes after the import,
so it never runs in a test's (or a monitor's) process: :class:`O6Plc` starts this file
as a child process. The child serves every channel of the recording as
``ns=1;s=<channel>`` and an end tag ``ns=1;s=ReplayDone``, and writes every analog
sample and every digital change with its source time stamp (the recording's start time
plus the sample time) at ``speed`` times real time.

Settings (one JSON object, the child's only argument): ``recording`` (a Parquet file),
``channels``, ``port``, ``speed``, ``done`` (the end tag's value at start: true as left
by an earlier run), ``burst`` ([channel, from, to] s: that channel's samples in the span
are written at once, more than the server's queue holds), ``bad`` ([channel, from, to]:
written with status Bad), ``origin`` (live mode: the wall-clock time [s since 1970] at
which the recording's time 0 is written; the child starts at once where the recording
is now, as a PLC that kept running while its server was down, and ends at its end).

Protocol: the child prints ``ready <port>`` once serving; then (not live) ``play`` on its
standard input plays the recording once, setting the end tag false first and true after
(``played`` is printed), and ``stop`` or the end of its input ends it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve()


def _events(rec: Any, channels: list[str], settings: dict[str, Any]) -> list[tuple]:
    from pneufdd.recording.model import ANALOG

    burst, bad = settings.get("burst"), settings.get("bad")
    events = []
    for name in channels:
        info = rec.info(name)
        v = np.asarray(info.values, dtype=np.float64)
        k = np.arange(1, v.size) if info.kind == ANALOG else np.flatnonzero(np.diff(v)) + 1
        t = info.t0 + k / info.rate_hz
        due = t.copy()
        if burst is not None and name == burst[0]:
            due[(t >= burst[1]) & (t <= burst[2])] = burst[1]
        flag = np.zeros(t.size, dtype=bool)
        if bad is not None and name == bad[0]:
            flag = (t >= bad[1]) & (t <= bad[2])
        columns = (due.tolist(), t.tolist(), [name] * t.size, v[k].tolist(), flag.tolist())
        events += zip(*columns, strict=True)
    events.sort()
    return events


def _serve(settings: dict[str, Any]) -> None:
    import o6

    from pneufdd.recording import Recording

    rec = Recording.read(settings["recording"])
    channels = list(settings["channels"])
    speed = float(settings.get("speed", 1.0))
    t0 = rec.start_time.timestamp()
    server = o6.Server(port=int(settings["port"]))
    server.start()

    def value(v: object, t: float, bad: bool = False) -> object:
        stamp = o6.DateTime(datetime.fromtimestamp(t0 + t, UTC))
        if bad:
            return o6.DataValue(
                value=v, status=o6.StatusCode.BAD_SENSOR_FAILURE, sourceTimestamp=stamp
            )
        return o6.DataValue(value=v, sourceTimestamp=stamp)

    origin = settings.get("origin")
    now_s = 0.0 if origin is None else max(0.0, (time.time() - float(origin)) * speed)
    nodes = {}
    for name in channels:
        info = rec.info(name)
        i = min(int(np.floor((now_s - info.t0) * info.rate_hz)), len(info.values) - 1)
        i = max(i, 0)
        node = server.addVariable(name, server.objectsNode, 0.0, nodeId=f"ns=1;s={name}")
        node(value(float(info.values[i]), info.t0 + i / info.rate_hz))
        nodes[name] = node
    done = server.addVariable(
        "ReplayDone",
        server.objectsNode,
        bool(settings.get("done", False)),
        nodeId="ns=1;s=ReplayDone",
    )
    events = _events(rec, channels, settings)
    print(f"ready {settings['port']}", flush=True)

    def play(start_wall: float, skip_s: float) -> None:
        done(False)
        for due, t, name, v, flag in events:
            if due < skip_s:
                continue
            wait = start_wall + due / speed - time.time()
            if wait > 0:
                time.sleep(wait)
            nodes[name](value(v, t, flag))
        time.sleep(0.5)
        done(True)

    if origin is not None:
        play(float(origin), now_s)
        print("played", flush=True)
        time.sleep(5.0)
        return
    for line in sys.stdin:
        if line.strip() == "play":
            play(time.time(), 0.0)
            print("played", flush=True)
        elif line.strip() == "stop":
            break
    server.stop()


class O6Plc:
    """The stand-in PLC in a child process (:func:`_serve`); ``url`` is the monitor's source."""

    def __init__(self, settings: dict[str, Any]) -> None:
        self.settings = dict(settings)
        self.port = int(settings["port"])
        self.url = f"opcua://127.0.0.1:{self.port}"
        self.proc = subprocess.Popen(
            [sys.executable, str(HERE), json.dumps(self.settings)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith("ready"):
                break
        else:
            raise RuntimeError(f"the o6 server did not start (exit {self.proc.wait()})")

    def play(self) -> None:
        """Play the recording once (returns when played)."""
        assert self.proc.stdin is not None
        assert self.proc.stdout is not None
        self.proc.stdin.write("play\n")
        self.proc.stdin.flush()
        for line in self.proc.stdout:
            if line.startswith("played"):
                return
        raise RuntimeError(f"the o6 server ended while playing (exit {self.proc.wait()})")

    def wait_played(self) -> bool:
        """Live mode: wait for the child to end; whether it played to the recording's end."""
        assert self.proc.stdout is not None
        played = any(line.startswith("played") for line in self.proc.stdout)
        self.proc.wait()
        return played

    def stop(self) -> None:
        """End the server."""
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write("stop\n")
                self.proc.stdin.close()
                self.proc.wait(10)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait(10)
        if self.proc.stdout is not None:
            self.proc.stdout.close()


if __name__ == "__main__":
    _serve(json.loads(sys.argv[1]))
