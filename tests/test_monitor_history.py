"""The fault history through ``pneufdd monitor --once`` and ``pneufdd history`` (real SQLite).

PostgreSQL is exercised against a real server: ``PNEUFDD_TEST_POSTGRES`` (a URL), else a
throwaway server started from the installed binaries; skipped when neither exists.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import sqlite3
import subprocess
import tempfile
import threading
import typing
from http.server import BaseHTTPRequestHandler, HTTPServer
from pathlib import Path

import pytest

from monitor_data import SEED, leak_run, reference
from pneufdd.cli.app import main
from pneufdd.diagnosis.reference.file import save_reference
from pneufdd.monitor.database import SCHEMA_VERSION, HistoryDatabase


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("monitor")
    ref = save_reference(reference(), folder / "ref.pnref")
    run = leak_run().write(folder / "run.parquet")
    return {"ref": ref, "run": run, "folder": folder}


class _Hook(BaseHTTPRequestHandler):
    received: typing.ClassVar[list[dict]] = []

    def do_POST(self) -> None:
        body = self.rfile.read(int(self.headers["Content-Length"]))
        _Hook.received.append(json.loads(body))
        self.send_response(204)
        self.end_headers()

    def log_message(self, *args: object) -> None:
        return None


def _monitor(files, db, *extra):
    return main(
        [
            "monitor",
            "--reference",
            str(files["ref"]),
            "--source",
            f"replay:{files['run']}?speed=max",
            "--history",
            f"sqlite:///{db}",
            "--once",
            "--alarm-log",
            str(files["folder"] / "alarms.jsonl"),
            *extra,
        ]
    )


def test_monitor_records_cycles_once_raises_a_located_alarm_and_posts_it(files, capsys):
    server = HTTPServer(("127.0.0.1", 0), _Hook)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    db = files["folder"] / "h.db"
    try:
        url = f"http://127.0.0.1:{server.server_port}/alarm"
        code = _monitor(files, db, "--webhook", url)
    finally:
        server.shutdown()
        server.server_close()
    out = capsys.readouterr().out
    assert code == 1  # a leak is active at the end
    assert "LEAK at supply" in out
    (posted,) = _Hook.received
    logged = [json.loads(x) for x in (files["folder"] / "alarms.jsonl").read_text().splitlines()]
    assert logged == [posted]
    assert posted["machine"] == "festo-dsd"
    assert posted["locations"] == ["supply"]
    for key in ("time", "flow_slpm", "annual_cost", "confidence"):
        assert posted[key] is not None
    # 4 turns on the supply is about 130 SLPM at the festo-dsd's pressure (Table 3.3)
    assert 60.0 < posted["flow_slpm"] < 260.0
    # declared within 3 cycles of the first leaky cycle (the 4th, starting at 44.3 s)
    starts = leak_run().metadata["cycle_start_s"]
    first = next(i for i, t in enumerate(starts) if t >= 40.0)
    t0 = leak_run().start_time.timestamp()
    declared = [i for i, t in enumerate(starts) if abs(t0 + t - posted["timestamp"]) < 0.05]
    assert declared
    assert 1 <= declared[0] - first + 1 <= 3
    history = HistoryDatabase(f"sqlite:///{db}")
    machine = history.machine_id("festo-dsd")
    assert history.cycle_count(machine) == len(starts)
    assert history.schema_version() == SCHEMA_VERSION
    assert history.integrity_ok()
    history.close()
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    # the same replay again: nothing new is recorded, no new alarm
    assert _monitor(files, db) == 1
    history = HistoryDatabase(f"sqlite:///{db}")
    assert history.cycle_count(machine) == len(starts)
    assert len(history.alarm_rows(machine)) == 1
    history.close()


def test_history_command_prints_json_and_draws_a_figure(files, capsys, tmp_path):
    db = tmp_path / "h.db"
    _monitor(files, db)
    capsys.readouterr()
    figure = tmp_path / "history.png"
    code = main(["history", "--history", f"sqlite:///{db}", "--json", "--figure", str(figure)])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    (entry,) = report["machines"]
    starts = leak_run().metadata["cycle_start_s"]
    assert entry["machine"] == "festo-dsd"
    assert entry["cycles"]["count"] == len(starts)
    assert entry["cycles"]["first"].startswith("2026-03-01T06:00:00")
    (leak,) = entry["leaks"]
    assert leak["location"] == "supply"
    assert leak["state"] in ("new", "stable", "growing")
    assert leak["sizes"]
    assert leak["cost_to_date"] > 0
    assert [a["kind"] for a in entry["alarms"]] == ["leak"]
    assert figure.stat().st_size > 10_000
    # never overwrite a figure; --since filters; unknown machine is bad input
    assert main(["history", "--history", f"sqlite:///{db}", "--figure", str(figure)]) == 2
    code = main(["history", "--history", f"sqlite:///{db}", "--since", "2027-01-01"])
    assert code == 0
    assert "0 cycles" in capsys.readouterr().out
    assert main(["history", "--history", f"sqlite:///{db}", "--machine", "nope"]) == 2
    # the operator marks the leak repaired
    code = main(
        [
            "history",
            "--history",
            f"sqlite:///{db}",
            "--machine",
            "festo-dsd",
            "--repaired",
            "supply",
            "--json",
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    report = json.loads(text[text.index("{") :])
    assert report["machines"][0]["leaks"][0]["state"] == "repaired"


def test_the_alarm_log_goes_beside_a_sqlite_history_never_into_the_working_folder(
    files, tmp_path, monkeypatch, capsys
):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    db = tmp_path / "plant" / "line1.db"
    db.parent.mkdir()
    args = ["--reference", str(files["ref"]), "--source", f"replay:{files['run']}?speed=max"]
    assert main(["monitor", *args, "--history", f"sqlite:///{db}", "--once"]) == 1
    (logged,) = [json.loads(x) for x in (db.parent / "line1-alarms.jsonl").read_text().splitlines()]
    assert logged["kind"] == "leak"
    assert "line1-alarms.jsonl" in capsys.readouterr().err.replace("\n", "")  # said at start
    assert main(["history", "--history", f"sqlite:///{db}", "--json"]) == 0
    assert main(["history", "--history", f"sqlite:///{db}", "--json"]) == 0  # again: no clash
    assert list(work.iterdir()) == []  # nothing written where the commands ran


def test_bad_sources_and_urls_are_input_errors(files, tmp_path):
    base = ["monitor", "--reference", str(files["ref"]), "--once"]
    assert main([*base, "--source", "ftp://x"]) == 2
    assert main([*base, "--source", f"replay:{tmp_path / 'missing.parquet'}"]) == 2
    assert main([*base, "--source", f"replay:{files['run']}", "--history", "oracle://x"]) == 2


def _postgres_binaries() -> Path | None:
    found = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"))
    return found[-1].parent if found else None


@pytest.fixture(scope="module")
def postgres_url(tmp_path_factory):
    """A real PostgreSQL: ``PNEUFDD_TEST_POSTGRES``, else a throwaway server started here
    from the installed binaries (as user ``postgres`` when the tests run as root)."""
    url = os.environ.get("PNEUFDD_TEST_POSTGRES")
    if url:
        yield url
        return
    bins = _postgres_binaries()
    if bins is None:
        pytest.skip("PostgreSQL is not installed (set PNEUFDD_TEST_POSTGRES to use a server)")
    folder = Path(tempfile.mkdtemp(prefix="pneufdd-pg-"))
    data = folder / "data"
    as_user: list[str] = []
    if os.geteuid() == 0:  # initdb refuses root
        try:
            shutil.chown(folder, "postgres")
        except LookupError:
            shutil.rmtree(folder, ignore_errors=True)
            pytest.skip("running as root and there is no postgres user")
        as_user = ["runuser", "-u", "postgres", "--"]
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [*as_user, *args], capture_output=True, text=True, timeout=120, check=False
        )

    init = run(str(bins / "initdb"), "-D", str(data), "-A", "trust", "-U", "postgres")
    if init.returncode != 0:
        shutil.rmtree(folder, ignore_errors=True)
        pytest.skip(f"initdb failed: {init.stderr.strip()[:200]}")
    options = f"-p {port} -k {folder} -c listen_addresses=''"
    log = folder / "server.log"
    start = subprocess.run(  # the server keeps no pipe of ours open: it logs to a file
        [
            *as_user,
            str(bins / "pg_ctl"),
            "-D",
            str(data),
            "-l",
            str(log),
            "-o",
            options,
            "-w",
            "start",
        ],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        timeout=120,
        check=False,
    )
    if start.returncode != 0:
        text = log.read_text() if log.exists() else ""
        shutil.rmtree(folder, ignore_errors=True)
        pytest.skip(f"PostgreSQL did not start: {text.strip()[-200:]}")
    try:
        yield f"postgresql://postgres@/postgres?host={folder}&port={port}"
    finally:
        run(str(bins / "pg_ctl"), "-D", str(data), "-m", "fast", "-w", "stop")
        shutil.rmtree(folder, ignore_errors=True)


def test_postgresql_history_when_a_server_runs(postgres_url):
    import sqlalchemy as sa

    from pneufdd.monitor import database

    history = HistoryDatabase(postgres_url)
    try:
        name = f"pg-test-{SEED}-{os.getpid()}"
        machine = history.machine_id(name)
        with history.begin() as conn:
            assert history.add_cycle(conn, machine, 1.0e9, 14.8, 0.5, 0.0, 0.01, 6e5)
            assert not history.add_cycle(conn, machine, 1.0e9, 14.8, 0.5, 0.0, 0.01, 6e5)
            history.save_state(conn, machine, 1.0e9, {"cusum": {"up": 1.0}})
            history.save_state(conn, machine, 1.0e9 + 15, {"cusum": {"up": 2.0}})
        assert history.cycle_count(machine) == 1
        assert history.load_state(machine) == (1.0e9 + 15, {"cusum": {"up": 2.0}})
        assert history.schema_version() == SCHEMA_VERSION
    finally:
        with history.begin() as conn:
            for table in (database.monitor_state, database.cycles):
                conn.execute(sa.delete(table).where(table.c.machine_id == machine))
            conn.execute(sa.delete(database.machines).where(database.machines.c.id == machine))
        history.close()


def test_history_prints_a_markup_machine_name_as_text(files, capsys, tmp_path):
    # a machine named like rich markup is printed as it is, not parsed (issue 39)
    db = tmp_path / "h.db"
    assert _monitor(files, db, "--machine", "cell[/]") == 1
    capsys.readouterr()
    assert main(["history", "--history", f"sqlite:///{db}"]) == 0
    out = capsys.readouterr().out
    assert "cell[/]: " in out
    assert "supply" in out
