"""The dashboard's fleet page on 100 machines and a year of history (issue 36).

A SQLite history is filled with 100 machines, each with a year of cycles: the last
24 hours at festo-dsd's rate (one cycle every 14.75 s, 5,858 cycles) and the rest of
the year at one cycle every 10 minutes (52,416; a full year at the real rate would be
2.1 million cycles per machine, 210 million rows, more than this benchmark may write),
with leaks, size estimates, alarms, gaps and the detector state of each. The fleet page
(``GET /`` of ``pneufdd serve``, served by uvicorn over HTTP, best of 5) is timed
against

- the same rows read from the database with SQL alone (the fleet summary's queries:
  every machine's state, newest cycle, cycles of the last 24 h, active leaks, alarms
  and gaps), so the ratio is what the web layer adds; target: the page <= 1 s;
- every cycle of the year read from the database, what a page that scanned the cycles
  would at least cost (the fleet page must stay far below it).

``PNEUFDD_BENCH_DASHBOARD_MACHINES`` changes the number of machines (default 100).
"""

from __future__ import annotations

import json
import os
import socket
import sqlite3
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

from common import BenchResult, best_time

MACHINES = int(os.environ.get("PNEUFDD_BENCH_DASHBOARD_MACHINES", "100"))
DAY_S = 86_400.0
YEAR_S = 365 * DAY_S
CYCLE_S = 14.75
SPARSE_S = 600.0


def _fill(path: Path, now: float) -> int:
    """The history of the benchmark; the number of cycle rows."""
    from pneufdd.monitor.database import HistoryDatabase

    HistoryDatabase(f"sqlite:///{path}").close()  # schema
    con = sqlite3.connect(path)
    rows = 0
    with con:
        for m in range(MACHINES):
            con.execute("INSERT INTO machines (id, name) VALUES (?, ?)", (m + 1, f"line-{m:03d}"))
            sparse = [now - YEAR_S + k * SPARSE_S for k in range(int((YEAR_S - DAY_S) / SPARSE_S))]
            dense = [now - DAY_S + k * CYCLE_S for k in range(int(DAY_S / CYCLE_S))]
            starts = sparse + dense
            con.executemany(
                "INSERT INTO cycles VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [
                    (m + 1, round(t * 1000), t, CYCLE_S, 1.0 + (k % 7) / 7, 0.1, 0.02, 6.9e5)
                    for k, t in enumerate(starts)
                ],
            )
            rows += len(starts)
            in_alarm = m % 4 == 0
            state = {"cusum": {"up": 3.0 if in_alarm else 0.0, "in_alarm": in_alarm}}
            con.execute(
                "INSERT INTO monitor_state VALUES (?, ?, ?)",
                (m + 1, round(starts[-1] * 1000), json.dumps(state)),
            )
            for j, location in enumerate(("supply", "DNC_A", "DNC_B")):
                state_text = "stable" if in_alarm and j == 0 else "repaired"
                leak = con.execute(
                    "INSERT INTO leaks (machine_id, location, state, first_seen, last_seen, "
                    "repaired_at, flow_slpm, annual_cost, confidence, cost_to_date) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (
                        m + 1,
                        location,
                        state_text,
                        now - 90 * DAY_S,
                        now,
                        None,
                        40.0 + j,
                        400.0 + j,
                        0.8,
                        50.0,
                    ),
                ).lastrowid
                con.executemany(
                    "INSERT INTO leak_sizes VALUES (?, ?, ?, ?)",
                    [(leak, now - 90 * DAY_S + k * DAY_S, 40.0 + j, 400.0) for k in range(90)],
                )
                con.execute(
                    "INSERT INTO alarms (machine_id, time, kind, data) VALUES (?, ?, ?, ?)",
                    (m + 1, now - 90 * DAY_S + j, "leak", json.dumps({"locations": [location]})),
                )
            con.executemany(
                "INSERT INTO gaps (machine_id, start, end, source, cycles_lost) "
                "VALUES (?, ?, ?, ?, ?)",
                [
                    (m + 1, now - k * 30 * DAY_S, now - k * 30 * DAY_S + 60, "mqtt://b/x", 4)
                    for k in range(1, 6)
                ],
            )
    con.execute("ANALYZE")
    con.close()
    return rows


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def run() -> list[BenchResult]:
    import uvicorn

    from pneufdd.monitor.database import HistoryDatabase
    from pneufdd.monitor.fleet import fleet_summary
    from pneufdd.web.app import ServeSettings, create_app

    now = time.time()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fleet.db"
        began = time.perf_counter()
        rows = _fill(path, now)
        print(
            f"   filled {MACHINES} machines, {rows:,} cycles in "
            f"{time.perf_counter() - began:.1f} s",
            file=sys.stderr,
            flush=True,
        )
        url = f"sqlite:///{path}"
        port = _free_port()
        server = uvicorn.Server(
            uvicorn.Config(
                create_app(ServeSettings(url, port=port)),
                host="127.0.0.1",
                port=port,
                log_level="warning",
                access_log=False,
            )
        )
        thread = threading.Thread(target=server.run)
        thread.start()
        try:
            while not server.started:
                time.sleep(0.05)

            def page() -> None:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=60) as r:
                    assert b"line-000" in r.read()

            page()  # first request: templates compiled, connections opened
            page_s = best_time(page, repeat=5)
            db = HistoryDatabase(url)
            rows_s = best_time(lambda: fleet_summary(db, now), repeat=5)

            def every_cycle() -> None:
                with db.engine.connect() as conn:
                    conn.exec_driver_sql("SELECT machine_id, start_ms, score FROM cycles").all()

            scan_s = best_time(every_cycle, repeat=1)
            db.close()
        finally:
            server.should_exit = True
            thread.join(30)
    name = f"fleet page, {MACHINES} machines, {rows:,} cycles (target <= 1 s)"
    return [
        BenchResult(name, page_s, "s", "the same rows read with SQL", rows_s),
        BenchResult(name, page_s, "s", "every cycle of the year read", scan_s),
    ]
