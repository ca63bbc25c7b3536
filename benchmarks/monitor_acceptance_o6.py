"""Issue 32's acceptance over an open62541 server (o6), and where the estimate should run.

Run through ``benchmarks/monitor_acceptance.py OUT_DIR o6|offpath`` (module docstring).

``o6``: a festo-dsd run of ``minutes`` of machine time, its tags as a PLC publishes
them (analog at 50 Hz, PLC signals at 100 Hz), written in real time (``speed`` 1) into
an open62541 server in a process of its own (``tests/o6_plc.py``); ``pneufdd monitor
--once`` watches it through the server's revised subscription limits (queue 100 per
tag, 100 ms publishing). The free o6 build ends its process 10 minutes after it
started: the server is started again at once on the same address, and writes from
where the machine is by then (what it would have written meanwhile is lost, as with a
server that restarts under a running PLC). ``--leak``: a 4-turn DNC_B leak appears
halfway. Printed: cycles in the run, judged, start-up, skipped for lost samples,
gaps and cycles lost, server restarts, reconnections, alarms; with the leak, the
cycles from its onset to the alarm (usable ones: recorded and judged), the location
and group, and the size against the twin's truth.

``offpath``: the monitor's ingestion (segmentation and scores of a 20-cycle replay at
full speed) alone, beside an estimate running without pause in a worker thread, and
beside one in a worker process, alternated three times; the wall time of each.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))


REFERENCE_RECORDINGS = 4
REFERENCE_CYCLES = 25
"""The o6 runs' reference: 4 leak-free recordings of 25 cycles (the issue 9 campaign
design; with three or more recordings the detector cross-validates by recording)."""


def o6_reference(out: Path, seed: int) -> Path:
    """festo-dsd reference of leak-free runs as a PLC publishes them (seeds seed + i)."""
    from monitor_data import as_plc_tags
    from pneufdd.diagnosis.recordings import build_reference_from_recordings
    from pneufdd.diagnosis.reference.file import save_reference
    from pneufdd.sim import simulate

    path = out / f"o6-ref-{REFERENCE_RECORDINGS}x{REFERENCE_CYCLES}.pnref"
    if not path.exists():
        refs = [
            as_plc_tags(simulate("festo-dsd", cycles=REFERENCE_CYCLES, seed=seed + i))
            for i in range(REFERENCE_RECORDINGS)
        ]
        save_reference(build_reference_from_recordings(refs, workers=1), path)
    return path


def _tags(path: Path, analog: tuple[str, ...], digital: tuple[str, ...]) -> Path:
    lines = ["lateness_s = 1.0", 'end = "ns=1;s=ReplayDone"']
    for name in (*analog, *digital):
        rate = 50.0 if name in analog else 100.0
        lines += [f"[channels.{name}]", f'node = "ns=1;s={name}"', f"rate_hz = {rate:g}"]
    path.write_text("\n".join(lines) + "\n")
    return path


class _Server:
    """The o6 server, started again whenever its process ends before the run's end."""

    def __init__(self, settings: dict[str, Any]) -> None:
        self.settings = settings
        self.restarts: list[float] = []
        self.finished = threading.Event()
        self.thread = threading.Thread(target=self._keep, daemon=True)
        self.thread.start()

    def _keep(self) -> None:
        from o6_plc import O6Plc

        first = True
        while not self.finished.is_set():
            if not first:
                self.restarts.append(time.time())
            first = False
            plc = O6Plc(self.settings)
            if plc.wait_played():
                self.finished.set()
            plc.stop()


def o6_run(out: Path, seed: int, leak: bool, minutes: float, speed: float, port: int) -> None:
    from monitor_data import as_plc_tags, started
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor.cycles import needed_channels
    from pneufdd.monitor.database import HistoryDatabase
    from pneufdd.sim import simulate
    from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

    name = "o6-leak" if leak else "o6-free"
    ref = o6_reference(out, seed)
    model = load_reference(ref)
    analog, digital = needed_channels(model)
    duration = minutes * 60.0
    cycles = math.ceil(duration / 14.75) + 1
    onset = duration / 2.0
    schedule = LeakSchedule([ScheduledLeak("DNC_B", 4.0, start_s=onset)]) if leak else None
    simulated = simulate("festo-dsd", cycles=cycles, seed=seed + 10 + int(leak), schedule=schedule)
    origin = time.time() + 60.0  # the machine's time 0: the monitor is connected by then
    # source time stamps on the wall clock, as a PLC's (the recording starts at origin)
    rec = started(as_plc_tags(simulated), datetime.fromtimestamp(origin, UTC))
    run = out / f"{name}.parquet"
    rec.write(run, overwrite=True)
    db = out / f"{name}.db"
    for suffix in ("", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)
    (out / f"{name}-alarms.jsonl").unlink(missing_ok=True)
    tags = _tags(out / f"{name}-tags.toml", analog, digital)
    settings = {
        "recording": str(run),
        "channels": [*analog, *digital],
        "port": port,
        "speed": speed,
        "origin": origin,
    }
    server = _Server(settings)
    command = [
        sys.executable,
        "-c",
        "import sys; from pneufdd.cli.app import main; sys.exit(main(sys.argv[1:]))",
        "monitor",
        "--reference",
        str(ref),
        "--source",
        f"opcua://127.0.0.1:{port}",
        "--tags",
        str(tags),
        "--history",
        f"sqlite:///{db}",
        "--once",
    ]
    log = out / f"{name}-monitor.log"
    began = time.time()
    with open(log, "w", encoding="utf-8") as handle:
        code = subprocess.run(
            command,
            stdout=handle,
            stderr=subprocess.STDOUT,
            check=False,
            env={**os.environ, "COLUMNS": "1000"},
        ).returncode
    server.finished.set()
    text = log.read_text()
    lines = text.splitlines()
    summary = json.loads(next(x for x in reversed(lines) if x.startswith('{"cycles"')))
    history = HistoryDatabase(f"sqlite:///{db}")
    machine = history.machine_id("festo-dsd")
    rows = history.cycle_rows(machine)
    gaps = history.gap_rows(machine)
    alarms = history.alarm_rows(machine)
    history.close()
    t0 = rec.start_time.timestamp()
    starts = list(rec.metadata["cycle_start_s"])
    report: dict[str, Any] = {
        "run": name,
        "seed": seed + 10 + int(leak),
        "machine_minutes": round(rec.duration / 60.0, 2),
        "wall_minutes": round((time.time() - began) / 60.0, 2),
        "speed": speed,
        "exit_code": code,
        "cycles_in_run": len(starts),
        "cycles_recorded": len(rows),
        "judged": summary["judged"],
        "startup": summary["startup"],
        "skipped_lost_samples": summary["incomplete_skipped"],
        "skipped_said_live": sum(" skipped: " in x for x in lines),
        "gaps": len(gaps),
        "cycles_lost_in_gaps": sum(g["cycles_lost"] for g in gaps),
        "server_restarts": len(server.restarts),
        "reconnections": sum("reconnected to OPC UA" in x for x in lines),
        "alarms": [(a["kind"], a["locations"], a["flow_slpm"]) for a in alarms],
        "granted_problems": [x for x in lines if x.startswith("OPC UA channel")],
        "notes": [x for x in lines if x.startswith("note:")],
    }
    accounted = len(rows) + summary["incomplete_skipped"] + report["cycles_lost_in_gaps"]
    report["cycles_accounted"] = accounted
    report |= _faithful(model, rec, rows, out / f"{name}-file.db")
    if leak:
        first = next(i for i, t in enumerate(starts) if t >= onset - 1e-9)
        leak_alarm = next((a for a in alarms if a["kind"] == "leak"), None)
        if leak_alarm is not None:
            declared = leak_alarm["timestamp"] - t0
            usable = [r for r in rows if starts[first] - 1e-3 <= r["start"] - t0 <= declared + 1e-3]
            truth = [x["slpm"] for x in rec.metadata["leak_timeline"] if x["cycle"] >= first]
            report |= {
                "onset_cycle": first,
                "declared_at_cycle_start_s": round(declared, 3),
                "usable_cycles_onset_to_alarm": len(usable),
                "located": leak_alarm["locations"],
                "leaks": leak_alarm["leaks"],
                "size_slpm": leak_alarm["flow_slpm"],
                "true_slpm": round(float(sum(truth) / len(truth)), 2) if truth else None,
            }
        report["diagnosis_groups"] = _groups(db)
    print(json.dumps(report), flush=True)


def _faithful(model: Any, rec: Any, rows: list[dict[str, Any]], db: Path) -> dict[str, Any]:
    """The live run's recorded cycles against the same recording replayed from its file:
    every cycle the server delivered whole scores exactly as the file's."""
    from pneufdd.monitor.database import HistoryDatabase
    from pneufdd.monitor.live import MachineMonitor
    from pneufdd.monitor.sources import ReplaySource
    from pneufdd.monitor.stream import run_stream

    for suffix in ("", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)
    history = HistoryDatabase(f"sqlite:///{db}")
    monitor = MachineMonitor(model, history, estimates="inline")
    scores: dict[int, float] = {}
    source = ReplaySource(rec, math.inf, 1.0)
    run_stream(
        monitor,
        source,
        source.rates_hz,
        0.0,
        on_cycle=lambda o: scores.__setitem__(round(o.start * 100), o.score),
    )
    monitor.close()
    history.close()
    same, differ = 0, []
    for row in rows:
        file_score = scores.get(round(row["start"] * 100))
        if file_score is None or row["score"] is None:
            continue
        if abs(row["score"] - file_score) <= 1e-9 * max(1.0, abs(file_score)):
            same += 1
        else:
            differ.append(
                (round(row["start"] - rec.start_time.timestamp(), 2), row["score"], file_score)
            )
    return {"cycles_scored_as_the_file": same, "cycles_scored_otherwise": differ}


def _groups(db: Path) -> list[list[str]]:
    import sqlalchemy as sa

    from pneufdd.monitor import database

    engine = sa.create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        rows = conn.execute(sa.select(database.diagnoses.c.data)).all()
    engine.dispose()
    return [
        [str(g) for leak in json.loads(r[0])["leaks"] for g in leak["ambiguity_group"]]
        for r in rows
    ]


def offpath(out: Path, seed: int) -> None:
    """Ingestion alone, beside an estimate in a thread, beside one in a process."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

    from monitor_acceptance import reference
    from pneufdd.diagnosis.cost import CostSettings
    from pneufdd.diagnosis.recordings import run_table
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor import estimates
    from pneufdd.monitor.live import CycleOutcome, MonitorStats
    from pneufdd.monitor.sources import ReplaySource
    from pneufdd.monitor.stream import run_stream
    from pneufdd.sim import simulate
    from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

    model = load_reference(reference(out))
    leaky = simulate(
        "festo-dsd",
        cycles=6,
        seed=seed + 4000,
        schedule=LeakSchedule([ScheduledLeak("DNC_B", 4.0, start_s=0.0)]),
    )
    table = run_table(model, leaky)
    rec = simulate("festo-dsd", cycles=20, seed=seed + 4001)

    class _Score:
        stats = MonitorStats()
        busy = False

        def __init__(self) -> None:
            self.model = model

        def process(self, cycle: Any) -> CycleOutcome:
            model.detector.score_samples(cycle.table.features())
            return CycleOutcome(cycle.start, 0.0, 0.0, False)

        def poll(self) -> int:
            return 0

        def settle(self) -> None:
            return None

    def ingest() -> float:
        src = ReplaySource(rec, math.inf, 1.0)
        began = time.perf_counter()
        run_stream(_Score(), src, src.rates_hz, 0.0)  # type: ignore[arg-type]
        return time.perf_counter() - began

    cost = CostSettings()
    pools: dict[str, Any] = {
        "thread": ThreadPoolExecutor(1),
        "process": ProcessPoolExecutor(
            1,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=estimates._keep,
            initargs=(model, cost),
        ),
    }
    pools["process"].submit(estimates._run_kept, table).result()  # started, compiled
    ingest()
    walls: dict[str, list[float]] = {"alone": [], "thread": [], "process": []}
    engine: dict[str, list[float]] = {"thread": [], "process": []}
    for _ in range(3):
        for mode in ("alone", "thread", "process"):
            stop = threading.Event()

            def loop(mode: str = mode, stop: threading.Event = stop) -> None:
                while not stop.is_set():
                    if mode == "thread":
                        timed = pools[mode].submit(estimates._run, model, table, cost).result()
                    else:
                        timed = pools[mode].submit(estimates._run_kept, table).result()
                    engine[mode].append(timed.ended - timed.began)

            worker = None
            if mode != "alone":
                worker = threading.Thread(target=loop)
                worker.start()
                time.sleep(0.5)
            walls[mode].append(ingest())
            stop.set()
            if worker is not None:
                worker.join()
    for pool in pools.values():
        pool.shutdown()
    print(
        json.dumps(
            {
                "replay_s": round(rec.duration, 2),
                "ingest_wall_s": {k: [round(x, 2) for x in v] for k, v in walls.items()},
                "estimate_wall_s": {k: [round(x, 2) for x in v] for k, v in engine.items()},
            }
        ),
        flush=True,
    )
