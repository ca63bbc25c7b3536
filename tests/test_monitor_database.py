"""The history database against a real PostgreSQL server (issue 32, item 5).

Several monitors starting at once on an empty database all open it (the schema is
created once, under a lock), and a password in a history URL is never printed. The
server is ``PNEUFDD_TEST_POSTGRES`` or a throwaway one (``test_monitor_history``'s
fixture); skipped when neither exists.
"""

from __future__ import annotations

import threading
import uuid

import pytest
import sqlalchemy as sa

from pneufdd.monitor import database
from pneufdd.monitor.database import SCHEMA_VERSION, HistoryDatabase, masked_url
from test_monitor_history import postgres_url  # noqa: F401  (the server fixture)


@pytest.fixture
def empty_database(postgres_url):  # noqa: F811
    """A new, empty database on the server; dropped afterwards."""
    name = f"pneufdd_{uuid.uuid4().hex[:12]}"
    admin = sa.create_engine(
        sa.engine.make_url(postgres_url).set(drivername="postgresql+psycopg"),
        isolation_level="AUTOCOMMIT",
    )
    with admin.connect() as conn:
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    try:
        yield sa.engine.make_url(postgres_url).set(database=name)
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


def _start_at_once(url: str, monitors: int) -> list[BaseException]:
    barrier = threading.Barrier(monitors)
    errors: list[BaseException] = []

    def start() -> None:
        barrier.wait()
        try:
            history = HistoryDatabase(url)
            try:
                history.machine_id("festo-dsd")
            finally:
                history.close()
        except BaseException as exc:  # collected: the test names them
            errors.append(exc)

    threads = [threading.Thread(target=start) for _ in range(monitors)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    return errors


@pytest.mark.parametrize("round_", range(3))
def test_monitors_starting_at_once_on_an_empty_postgresql_database(empty_database, round_):
    url = empty_database.render_as_string(hide_password=False)
    errors = _start_at_once(url, monitors=4)
    assert errors == []
    history = HistoryDatabase(url)
    try:
        assert history.schema_version() == SCHEMA_VERSION
        assert history.machines() == [(history.machine_id("festo-dsd"), "festo-dsd")]
        with history.engine.connect() as conn:
            versions = conn.execute(sa.select(database.schema_info.c.version)).all()
        assert versions == [(SCHEMA_VERSION,)]
    finally:
        history.close()


def test_a_url_is_shown_without_its_password():
    assert masked_url("postgresql://ann:s3cret@db.example/history") == (
        "postgresql://ann:***@db.example/history"
    )
    assert masked_url("sqlite:///h.db") == "sqlite:///h.db"
    assert "s3cret" not in masked_url("not a url ann:s3cret@x")


@pytest.mark.parametrize("monitors", [2, 4])
def test_monitors_starting_at_once_on_a_new_sqlite_file(tmp_path, monitors):
    url = f"sqlite:///{tmp_path / 'h.db'}"
    assert _start_at_once(url, monitors) == []
    history = HistoryDatabase(url)
    try:
        assert history.schema_version() == SCHEMA_VERSION
        assert [name for _, name in history.machines()] == ["festo-dsd"]
    finally:
        history.close()


def test_a_password_in_the_history_url_is_never_printed(empty_database, tmp_path, capsys):
    from monitor_data import free_run, reference
    from pneufdd.cli.app import main
    from pneufdd.diagnosis.reference.file import save_reference

    secret = "s3cret-Pw"
    url = empty_database.set(password=secret)  # the test server trusts: accepted, unchecked
    ref = save_reference(reference(), tmp_path / "ref.pnref")
    run = free_run().write(tmp_path / "run.parquet")
    base = ["--reference", str(ref), "--source", f"replay:{run}?speed=max", "--once"]
    log = ["--alarm-log", str(tmp_path / "alarms.jsonl")]
    text = url.render_as_string(hide_password=False)
    assert secret in text
    assert main(["monitor", *base, "--history", text, *log]) == 0
    assert main(["history", "--history", text, "--json"]) == 0
    unreachable = url.update_query_dict({"port": "1"}).render_as_string(hide_password=False)
    assert main(["monitor", *base, "--history", unreachable, *log]) == 2
    assert main(["history", "--history", unreachable]) == 2
    assert main(["monitor", *base, "--history", f"postgresql://ann:{secret}@[x", *log]) == 2
    captured = capsys.readouterr()
    shown = captured.out + captured.err
    assert "monitoring festo-dsd" in shown
    assert "postgres:***@" in shown
    assert secret not in shown


def test_a_version_1_history_gains_the_gaps_table_and_keeps_its_rows(tmp_path):
    url = f"sqlite:///{tmp_path / 'v1.db'}"
    engine = sa.create_engine(url)
    with engine.begin() as conn:  # what pneufdd wrote before schema version 2
        database.MIGRATIONS[0](conn)
        conn.execute(sa.insert(database.schema_info).values(version=1))
        conn.execute(sa.insert(database.machines).values(id=1, name="festo-dsd"))
    engine.dispose()
    history = HistoryDatabase(url)
    try:
        assert history.schema_version() == SCHEMA_VERSION == 4
        assert history.machines() == [(1, "festo-dsd")]
        with history.begin() as conn:
            history.add_gap(conn, 1, 100.0, 130.0, "mqtt://b/x", 2)
        assert history.gap_rows(1) == [
            {"start": 100.0, "end": 130.0, "source": "mqtt://b/x", "cycles_lost": 2}
        ]
    finally:
        history.close()
