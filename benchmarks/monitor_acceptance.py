"""Acceptance measurements of ``pneufdd monitor`` (issues 11 and 32); not part of ``make bench``.

    python benchmarks/monitor_acceptance.py OUT_DIR [delay|false-alarms|life|kill|all] [--seed N]
    python benchmarks/monitor_acceptance.py OUT_DIR o6 [--leak] [--minutes 30] [--speed 1]
        [--port P] [--seed N]
    python benchmarks/monitor_acceptance.py OUT_DIR offpath [--seed N]

Seeds: ``--seed`` + k (default 96_200_000, issue 11's; issue 32's runs used 740_000_000).
The reference is built from two leak-free festo-dsd runs of 12 cycles (seeds N, N + 1)
with the default signatures; the o6 runs use a reference of four leak-free runs of 25
cycles (seeds N .. N + 3) as a PLC publishes them (analog tags at 50 Hz). Every figure
printed names what it counts.
"""

from __future__ import annotations

import json
import math
import os
import random
import signal
import statistics
import subprocess
import sys
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

SEED = 96_200_000


def reference(out: Path) -> Path:
    from pneufdd.diagnosis.recordings import build_reference_from_recordings
    from pneufdd.diagnosis.reference.file import save_reference
    from pneufdd.sim import simulate

    path = out / "ref.pnref"
    if not path.exists():
        refs = [simulate("festo-dsd", cycles=12, seed=SEED + i) for i in range(2)]
        save_reference(build_reference_from_recordings(refs, workers=1), path)
    return path


def _shifted(rec, start: datetime):  # type: ignore[no-untyped-def]
    from pneufdd.recording.model import Recording

    return Recording([rec.info(c) for c in rec.channels], start_time=start, metadata=rec.metadata)


def _monitor(model, url: str):  # type: ignore[no-untyped-def]
    from pneufdd.monitor.alarms import AlarmSinks
    from pneufdd.monitor.database import HistoryDatabase
    from pneufdd.monitor.live import MachineMonitor

    db = HistoryDatabase(url)
    sinks = AlarmSinks()
    return MachineMonitor(model, db, alarm=sinks), sinks, db


def delay(out: Path) -> None:
    """Detection delay of leaks appearing mid-run; location against pneufdd diagnose."""
    from pneufdd.diagnosis.engine import diagnose
    from pneufdd.diagnosis.recordings import run_table
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor.sources import ReplaySource
    from pneufdd.monitor.stream import run_stream
    from pneufdd.sim import simulate
    from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

    model = load_reference(reference(out))
    cases = [("supply", s) for s in (1.0, 3.0, 6.0)]
    for loc in ("DNC_A", "DNC_B", "HMPL_V_A", "HMPL_V_B", "SLT_B"):
        cases += [(loc, s) for s in (1.0, 3.0, 6.0)]
    delays = []
    rows = []
    for k, (loc, size) in enumerate(cases):
        seed = SEED + 100 + k
        appear = 60.0
        sched = LeakSchedule([ScheduledLeak(loc, size, start_s=appear)])
        rec = simulate("festo-dsd", cycles=10, seed=seed, schedule=sched)
        starts = rec.metadata["cycle_start_s"]
        first_leaky = next(i for i, t in enumerate(starts) if t >= appear - 1e-9)
        url = f"sqlite:///{out / f'delay-{k}.db'}"
        for suffix in ("", "-wal", "-shm"):
            Path(str(out / f"delay-{k}.db") + suffix).unlink(missing_ok=True)
        mon, sinks, db = _monitor(model, url)
        src = ReplaySource(rec, math.inf, 1.0)
        declared_at = None
        position = 0

        def seen(outcome, mon=mon):  # type: ignore[no-untyped-def]
            nonlocal declared_at, position
            if declared_at is None and outcome.declared:
                declared_at = position
            position += 1

        run_stream(mon, src, src.rates_hz, 0.0, on_cycle=seen)
        db.close()
        leak_alarm = next((a for a in sinks.sent if a.kind == "leak"), None)
        # pneufdd diagnose on the leaky cycles of the same run
        table = run_table(model, rec)
        keep = table.step_start[:, 0] >= appear - 1e-9
        from pneufdd.features.step_table import StepTable

        leaky = StepTable(
            table.machine,
            table.step_start[keep],
            table.step_end[keep],
            table.channels,
            table.units,
            table.summaries[keep],
        )
        offline = diagnose(model, leaky)
        offline_loc = str(offline.leaks[0].location) if offline.leaks else None
        cycles = None if declared_at is None else declared_at - first_leaky + 1
        if cycles is not None:
            delays.append(cycles)
        row = {
            "seed": seed,
            "location": loc,
            "turns": size,
            "declared_after_cycles": cycles,
            "false_alarm_before_leak": cycles is not None and cycles <= 0,
            "monitor_locations": None if leak_alarm is None else list(leak_alarm.locations),
            "diagnose_location": offline_loc,
            "same_as_diagnose": leak_alarm is not None
            and offline_loc is not None
            and offline_loc in leak_alarm.locations,
            "true_location_in_alarm": leak_alarm is not None and loc in leak_alarm.locations,
        }
        rows.append(row)
        print(json.dumps(row), flush=True)
    missed = sum(1 for r in rows if r["declared_after_cycles"] is None)
    print(
        json.dumps(
            {
                "leak_runs": len(rows),
                "declared": len(delays),
                "missed": missed,
                "median_delay_cycles": statistics.median(delays) if delays else None,
                "max_delay_cycles": max(delays) if delays else None,
                "located_as_diagnose": sum(r["same_as_diagnose"] for r in rows),
                "true_location_in_alarm": sum(r["true_location_in_alarm"] for r in rows),
            }
        ),
        flush=True,
    )


def false_alarms(out: Path, cycles: int = 2000, per_run: int = 200) -> None:
    """Alarms over ``cycles`` leak-free cycles streamed as one machine's history."""
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor.sources import ReplaySource
    from pneufdd.monitor.stream import run_stream
    from pneufdd.sim import simulate

    model = load_reference(reference(out))
    path = out / "false-alarms.db"
    for suffix in ("", "-wal", "-shm"):
        Path(str(path) + suffix).unlink(missing_ok=True)
    mon, sinks, db = _monitor(model, f"sqlite:///{path}")
    start = datetime(2026, 1, 1, tzinfo=UTC)
    scores: list[float] = []
    peak = 0.0
    for k in range(math.ceil(cycles / per_run)):
        rec = simulate("festo-dsd", cycles=per_run, seed=SEED + 1000 + k)
        rec = _shifted(rec, start)
        start += timedelta(seconds=rec.duration + 60.0)
        src = ReplaySource(rec, math.inf, 1.0)

        def seen(outcome):  # type: ignore[no-untyped-def]
            nonlocal peak
            if outcome.recorded:
                scores.append(outcome.score)
                peak = max(peak, outcome.cusum)

        run_stream(mon, src, src.rates_hz, 0.0, on_cycle=seen)
        print(
            json.dumps(
                {"runs": k + 1, "cycles": len(scores), "alarms": len(sinks.sent), "peak": peak}
            ),
            flush=True,
        )
    det = model.detector
    s = np.array(scores)
    print(
        json.dumps(
            {
                "leak_free_cycles": len(scores),
                "alarms": len(sinks.sent),
                "cusum_threshold": mon.cusum.decision_threshold,
                "cusum_peak": peak,
                "per_cycle_threshold": det.threshold_,
                "cycles_over_per_cycle_threshold": int(np.sum(s > det.threshold_)),
                "score_mean": float(np.mean(s)),
                "reference_cv_score_mean": float(np.mean(det.reference_scores_)),
            }
        ),
        flush=True,
    )
    db.close()


def life(out: Path) -> None:
    """A leak appears, grows and is repaired: what the history shows."""
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor.sources import ReplaySource
    from pneufdd.monitor.stream import run_stream
    from pneufdd.sim import simulate
    from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

    model = load_reference(reference(out))
    sched = LeakSchedule(
        [ScheduledLeak("DNC_B", 1.5, start_s=60.0, growth_per_s=1.5 / 60.0, repair_s=260.0)]
    )
    rec = simulate("festo-dsd", cycles=26, seed=SEED + 2000, schedule=sched)
    path = out / "life.db"
    for suffix in ("", "-wal", "-shm"):
        Path(str(path) + suffix).unlink(missing_ok=True)
    mon, sinks, db = _monitor(model, f"sqlite:///{path}")
    src = ReplaySource(rec, math.inf, 1.0)
    run_stream(mon, src, src.rates_hz, 0.0)
    for row in db.leak_rows(mon.machine_id):
        sizes = [round(f or 0.0, 1) for _, f, _ in db.leak_sizes(row.id)]
        print(json.dumps({"location": row.location, "state": row.state, "sizes_slpm": sizes}))
    print(json.dumps({"alarms": [a.message() for a in sinks.sent]}))
    truth = [(t["cycle"], round(t["slpm"], 1)) for t in rec.metadata["leak_timeline"]]
    print(json.dumps({"true_timeline_cycle_slpm": truth}))
    db.close()


def history_dump(url: str) -> dict[str, object]:
    """A whole history, database ids replaced by what they stand for (to compare two)."""
    import sqlalchemy as sa

    from pneufdd.monitor import database
    from pneufdd.monitor.database import HistoryDatabase

    history = HistoryDatabase(url)
    try:
        with history.engine.connect() as conn:

            def rows(table: sa.Table, *order: object) -> list[dict[str, object]]:
                query = sa.select(table).order_by(*order)  # type: ignore[arg-type]
                return [dict(r._mapping) for r in conn.execute(query)]

            leaks = rows(database.leaks, database.leaks.c.id)
            name = {x["id"]: (x["location"], x["first_seen"]) for x in leaks}
            sizes = rows(database.leak_sizes, database.leak_sizes.c.leak_id)
            for row in leaks:
                row["leak"] = name[row.pop("id")]
            for row in sizes:
                row["leak"] = name[row.pop("leak_id")]
            found: dict[str, object] = {"leaks": leaks, "leak_sizes": sizes}
            for table in (database.alarms, database.diagnoses):
                found[table.name] = [
                    {k: (json.loads(v) if k == "data" else v) for k, v in r.items() if k != "id"}
                    for r in rows(table, table.c.id)
                ]
            found["cycles"] = rows(database.cycles, database.cycles.c.start_ms)
            found["state"] = rows(database.monitor_state, database.monitor_state.c.machine_id)
            found["pending_estimates"] = rows(
                database.pending_estimates, database.pending_estimates.c.id
            )
            found["integrity"] = history.integrity_ok()
            return found
    finally:
        history.close()


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def kill(out: Path, kills: int = 20, cycles: int = 40, ref: Path | None = None) -> None:
    """SIGKILL the monitor at random moments of a leak's life (a 4-turn DNC_B leak from
    100 s, repaired at 470 s) during a replay; restart each time; compare the history.

    A restart is *stuck* when it ends (not killed) with exit code 2 or 3, or records
    nothing although cycles are missing; the final history must equal an uninterrupted
    run's (cycles, scores, CUSUM, state, alarms, diagnoses, leaks, sizes, costs, no
    estimate left pending). The alarm log beside the history must hold every alarm of
    the clean run's (the outbox delivers what a killed monitor had not; a kill between
    the log's write and its mark repeats a line: counted). Worker processes of a killed
    monitor still alive 5 s later are counted as orphans.
    """
    from pneufdd.sim import simulate
    from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

    ref = ref or reference(out)
    run = out / "kill-life-run.parquet"
    if not run.exists():
        schedule = LeakSchedule([ScheduledLeak("DNC_B", 4.0, start_s=100.0, repair_s=470.0)])
        simulate("festo-dsd", cycles=cycles, seed=SEED + 3000, schedule=schedule).write(run)
    exe = [sys.executable, "-c", "import sys; from pneufdd.cli.app import main; sys.exit(main())"]

    def command(db: Path) -> list[str]:
        return [
            *exe,
            "monitor",
            "--reference",
            str(ref),
            "--source",
            f"replay:{run}?speed=max",
            "--history",
            f"sqlite:///{db}",
            "--once",
        ]

    clean = out / "kill-clean.db"
    killed = out / "kill.db"
    for p in (clean, killed):
        for suffix in ("", "-wal", "-shm"):
            Path(str(p) + suffix).unlink(missing_ok=True)
        (p.parent / f"{p.stem}-alarms.jsonl").unlink(missing_ok=True)
    began = time.perf_counter()
    subprocess.run(command(clean), check=False, capture_output=True)
    full = time.perf_counter() - began
    rng = random.Random(SEED + 3001)
    moments, codes, stuck, orphans = [], [], 0, 0
    for _ in range(kills):
        proc = subprocess.Popen(
            command(killed), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        moment = rng.uniform(0.5, full)
        moments.append(round(moment, 2))
        time.sleep(moment)
        children = _children(proc.pid)
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        code = proc.wait()
        codes.append(code)
        stuck += code in (2, 3)
        time.sleep(5.0)
        orphans += sum(Path(f"/proc/{c}").exists() for c in children)
    done = subprocess.run(command(killed), check=False, capture_output=True)
    stuck += done.returncode in (2, 3)
    expected = history_dump(f"sqlite:///{clean}")
    got = history_dump(f"sqlite:///{killed}")
    differ = [k for k in expected if k != "integrity" and expected[k] != got[k]]

    def logged(db: Path) -> list[tuple[object, ...]]:
        path = db.parent / f"{db.stem}-alarms.jsonl"
        lines = path.read_text().splitlines() if path.exists() else []
        return [
            (x["id"], x["kind"], x["timestamp"], tuple(x["locations"]))
            for x in map(json.loads, lines)
        ]

    clean_log, killed_log = logged(clean), logged(killed)
    log_missing = [a for a in clean_log if a not in killed_log]
    log_repeats = len(killed_log) - len(set(killed_log))
    print(
        json.dumps(
            {
                "kills": kills,
                "kill_moments_s": moments,
                "exit_codes": codes,
                "full_run_s": round(full, 2),
                "final_exit_code": done.returncode,
                "restarts_stuck": stuck,
                "expected_cycles": len(expected["cycles"]),  # type: ignore[arg-type]
                "recorded_cycles": len(got["cycles"]),  # type: ignore[arg-type]
                "alarms": [a["kind"] for a in got["alarms"]],  # type: ignore[attr-defined,index]
                "histories_identical": not differ,
                "tables_that_differ": differ,
                "integrity_check_ok": got["integrity"],
                "alarm_log_lines_clean": len(clean_log),
                "alarm_log_lines_killed": len(killed_log),
                "alarm_log_missing": len(log_missing),
                "alarm_log_repeated_lines": log_repeats,
                "orphan_worker_processes": orphans,
            }
        ),
        flush=True,
    )


def main() -> int:
    import argparse

    global SEED
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("what", nargs="?", default="all")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--leak", action="store_true")
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument("--port", type=int, default=48_400)
    args = parser.parse_args()
    SEED = args.seed
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    if args.what == "o6":
        from monitor_acceptance_o6 import o6_run

        o6_run(out, SEED, args.leak, args.minutes, args.speed, args.port)
        return 0
    if args.what == "offpath":
        from monitor_acceptance_o6 import offpath

        offpath(out, SEED)
        return 0
    for name, func in (
        ("delay", delay),
        ("false-alarms", false_alarms),
        ("life", life),
        ("kill", kill),
    ):
        if args.what in (name, "all"):
            print(f"== {name}", flush=True)
            func(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
