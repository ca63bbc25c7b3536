"""The fault history: a real database through SQLAlchemy (SQLite by default, PostgreSQL by URL).

Tables (schema version :data:`SCHEMA_VERSION`, migrations in :data:`MIGRATIONS`):

``schema_info``
    the schema version.
``machines``
    one row per machine name.
``cycles``
    one row per completed cycle, keyed by ``(machine_id, start_ms)`` (start in
    milliseconds since 1970-01-01 UTC): start, duration, score, CUSUM, supply air.
    Feeding the same data twice records its cycles once.
``monitor_state``
    the sequential detector's state after the machine's newest cycle; written in the
    same transaction as that cycle, so a restart resumes exactly where the last
    committed cycle left off.
``alarms``
    leaks declared and repairs, with location(s), size, cost and confidence.
``diagnoses``
    every location/sizing run (JSON of :meth:`~pneufdd.diagnosis.findings.Diagnosis.to_dict`).
``leaks``
    tracked leaks with a life: ``new``, ``growing``, ``stable``, ``repaired``.
``leak_sizes``
    every size estimate of a tracked leak over time.
``gaps`` (version 2)
    spans without a recorded cycle between two cycles (an outage of the source, a
    monitor that was away, data that held no complete cycle): start, end, source and
    the cycles lost; recorded with the cycle that ends the gap.
``machine_info`` (version 3)
    what a monitor knows of its machine when it starts: the machine description (JSON
    of the TOML mapping the reference carries), the CUSUM and per-cycle thresholds and
    the PLC steps' names; the dashboard draws the schematic and the score chart from it.
``acknowledgements`` (version 3)
    who acknowledged which alarm, and when.
``pending_estimates`` (version 4)
    a location and sizing run decided with a committed cycle and not yet finished
    (it runs beside the ingestion, :mod:`pneufdd.monitor.estimates`): its input, so
    that a restart redoes it; deleted in the transaction that stores its result.
``alarm_outbox`` (version 4)
    each alarm's payload per output (alarm log, webhook) and when it was delivered:
    written with the alarm, marked once delivered; what a killed monitor had not
    delivered is delivered, oldest first, at the next start.

The tables and migrations are in :mod:`pneufdd.monitor.schema`. A cycle, the detector
state, the cost accrued by the active leaks, any alarm the cycle raised and the input
of any estimate it decided are one transaction; an estimate's result, its leaks, sizes
and alarm are another. A crash (even SIGKILL) loses at most the cycle being processed
and never duplicates one. SQLite runs in WAL mode with
``synchronous=NORMAL``, which survives a killed process (a power cut may lose the last
transactions, never the file's integrity).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine

from pneufdd.errors import InputError, describe
from pneufdd.monitor.schema import (
    MIGRATIONS,
    SCHEMA_VERSION,
    acknowledgements,
    alarm_outbox,
    alarms,
    cycles,
    diagnoses,
    gaps,
    leak_sizes,
    leaks,
    machine_info,
    machines,
    monitor_state,
    pending_estimates,
    schema_info,
)

__all__ = [
    "DEFAULT_HISTORY_URL",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "HistoryDatabase",
    "LeakRow",
    "acknowledgements",
    "alarm_outbox",
    "alarms",
    "cycles",
    "diagnoses",
    "gaps",
    "leak_sizes",
    "leaks",
    "machine_info",
    "machines",
    "masked_url",
    "monitor_state",
    "open_history",
    "pending_estimates",
    "schema_info",
    "sqlite_path",
]
"""The tables (defined in :mod:`pneufdd.monitor.schema`) are re-exported here."""

DEFAULT_HISTORY_URL = "sqlite:///pneufdd-history.db"
SCHEMA_LOCK = 0x706E_6575_6664_6431
"""PostgreSQL advisory lock key held while the schema is created or migrated."""
SCHEMA_ATTEMPTS = 5
"""Tries of a schema step that another process raced (SQLite has no advisory lock)."""


def masked_url(url: str) -> str:
    """``url`` as it may be shown: its password replaced by ``***``.

    Examples
    --------
    >>> masked_url("postgresql://ann:s3cret@db/history")
    'postgresql://ann:***@db/history'
    """
    try:
        return sa.engine.make_url(url).render_as_string(hide_password=True)
    except (sa.exc.ArgumentError, ValueError):
        # not a URL SQLAlchemy reads: hide whatever sits between ':' and '@'
        return re.sub(r":[^:@/]*@", ":***@", url)


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class LeakRow:
    """A tracked leak as stored."""

    id: int
    location: str
    state: str
    first_seen: float
    last_seen: float
    repaired_at: float | None
    flow_slpm: float | None
    annual_cost: float | None
    confidence: float | None
    cost_to_date: float


class HistoryDatabase:
    """The history database at a SQLAlchemy URL (created and migrated on open).

    Parameters
    ----------
    url : str
        ``sqlite:///path/history.db`` or ``postgresql://user@host/db`` (psycopg).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     db = HistoryDatabase(f"sqlite:///{pathlib.Path(d) / 'h.db'}")
    ...     m = db.machine_id("festo-dsd")
    ...     with db.begin() as conn:
    ...         first = db.add_cycle(conn, m, 100.0, 14.8, 0.5, 0.0, 0.01, 6e5)
    ...         again = db.add_cycle(conn, m, 100.0, 14.8, 0.5, 0.0, 0.01, 6e5)
    ...     (first, again, db.cycle_count(m), db.schema_version())
    ...     db.close()
    (True, False, 1, 4)
    """

    def __init__(self, url: str) -> None:
        self.url = url
        self.engine: Engine = _engine(url)
        self._machines: dict[str, int] = {}
        self._statements: dict[tuple[str, str], Any] = {}
        try:
            self.migrate()
        except (sa.exc.OperationalError, sa.exc.DatabaseError) as exc:
            # a folder, a file that is no database, an unreachable server
            self.engine.dispose()
            reason = str(getattr(exc, "orig", exc)).splitlines()[0]
            password = sa.engine.make_url(url).password
            if password:
                reason = reason.replace(str(password), "***")
            raise InputError(
                describe("--history", masked_url(url), "a database that can be opened")
                + f" ({reason})"
            ) from exc

    # ----------------------------------------------------------- schema
    def schema_version(self) -> int:
        """Version of the stored schema (0: empty database)."""
        with self.engine.connect() as conn:
            return _stored_version(conn)

    def check_writable(self) -> None:
        """Refuse, before any work, a database this process may not write (issue 39).

        A no-op update in a transaction that is rolled back: a read-only file or
        connection, or a user without write rights, fails here and not at the first
        cycle recorded.

        Raises
        ------
        InputError
            Naming the URL and the database's reason.
        """
        try:
            with self.engine.connect() as conn:
                conn.execute(sa.update(schema_info).values(version=schema_info.c.version))
                conn.rollback()
        except (sa.exc.OperationalError, sa.exc.DatabaseError) as exc:
            reason = str(getattr(exc, "orig", exc)).splitlines()[0]
            raise InputError(
                describe("--history", self.url, "a database this user may write") + f" ({reason})"
            ) from exc

    def migrate(self) -> None:
        """Bring the schema to :data:`SCHEMA_VERSION` (each step one transaction).

        Safe when several monitors open an empty database at once: on PostgreSQL each
        step runs under an advisory lock (:data:`SCHEMA_LOCK`) and reads the version
        again inside it, so one process creates the schema and the others find it; on
        SQLite, whose DDL takes the database lock, a step that lost such a race (the
        table already exists) is retried from the version then stored.
        """
        for attempt in range(SCHEMA_ATTEMPTS):
            try:
                while self._migrate_step():
                    pass
                return
            except sa.exc.DatabaseError as exc:
                raced = isinstance(exc, sa.exc.IntegrityError) or "already exists" in str(exc)
                if not raced or attempt == SCHEMA_ATTEMPTS - 1:
                    raise

    def _migrate_step(self) -> bool:
        """One migration step in one transaction; False when the schema is current."""
        with self.engine.begin() as conn:
            if conn.dialect.name == "postgresql":
                conn.execute(sa.text("SELECT pg_advisory_xact_lock(:key)"), {"key": SCHEMA_LOCK})
            elif conn.dialect.name == "sqlite":
                # take the write lock before reading the version: two deferred
                # transactions that both read and then write deadlock, and SQLite answers
                # one of them "database is locked" at once instead of waiting its timeout
                conn.exec_driver_sql("BEGIN IMMEDIATE")
            version = _stored_version(conn)
            if version > SCHEMA_VERSION:
                raise InputError(
                    describe(
                        f"schema version of history {masked_url(self.url)!r}",
                        version,
                        f"<= {SCHEMA_VERSION} (a newer pneufdd wrote it)",
                    )
                )
            if version == SCHEMA_VERSION:
                return False
            MIGRATIONS[version](conn)
            conn.execute(sa.delete(schema_info))
            conn.execute(sa.insert(schema_info).values(version=version + 1))
            return True

    def begin(self) -> Any:
        """A transaction (context manager yielding a connection)."""
        return self.engine.begin()

    def close(self) -> None:
        """Release the connections."""
        self.engine.dispose()

    # ----------------------------------------------------------- writes
    def machine_id(self, name: str) -> int:
        """The id of machine ``name`` (created when new)."""
        if name in self._machines:
            return self._machines[name]
        with self.engine.begin() as conn:
            # monitors of one machine may start at once: insert unless present, then read
            conn.execute(_insert(conn, machines).values(name=name).on_conflict_do_nothing())
            found = conn.execute(
                sa.select(machines.c.id).where(machines.c.name == name)
            ).scalar_one()
        self._machines[name] = int(found)
        return int(found)

    def add_cycle(
        self,
        conn: Connection,
        machine_id: int,
        start: float,
        duration_s: float,
        score: float,
        cusum: float,
        supply_air_kg: float | None,
        supply_pressure_pa: float | None,
    ) -> bool:
        """Record a cycle; False (and nothing written) when it is already recorded."""
        values = {
            "machine_id": machine_id,
            "start_ms": round(start * 1000.0),
            "start": start,
            "duration_s": duration_s,
            "score": _num(score),
            "cusum": _num(cusum),
            "supply_air_kg": _num(supply_air_kg),
            "supply_pressure_pa": _num(supply_pressure_pa),
        }
        key = ("add_cycle", conn.dialect.name)
        stmt = self._statements.get(key)
        if stmt is None:  # built once: a statement per cycle costs more than its execution
            stmt = _insert(conn, cycles).on_conflict_do_nothing().returning(cycles.c.start_ms)
            self._statements[key] = stmt
        return conn.execute(stmt, values).first() is not None

    def save_state(
        self, conn: Connection, machine_id: int, last_start: float, state: dict[str, Any]
    ) -> None:
        """Store the detector state after the cycle starting at ``last_start``."""
        text = json.dumps(state, allow_nan=False)
        ms = round(last_start * 1000.0)
        key = ("save_state", conn.dialect.name)
        stmt = self._statements.get(key)
        if stmt is None:
            insert = _insert(conn, monitor_state)
            stmt = insert.on_conflict_do_update(
                index_elements=[monitor_state.c.machine_id],
                set_={
                    "last_start_ms": insert.excluded.last_start_ms,
                    "state": insert.excluded.state,
                },
            )
            self._statements[key] = stmt
        conn.execute(stmt, {"machine_id": machine_id, "last_start_ms": ms, "state": text})

    def load_state(self, machine_id: int) -> tuple[float, dict[str, Any]] | None:
        """The newest cycle's start [s] and the detector state after it; None when new."""
        with self.engine.connect() as conn:
            row = conn.execute(
                sa.select(monitor_state.c.last_start_ms, monitor_state.c.state).where(
                    monitor_state.c.machine_id == machine_id
                )
            ).first()
        if row is None:
            return None
        return row[0] / 1000.0, dict(json.loads(row[1]))

    def add_alarm(
        self, conn: Connection, machine_id: int, time: float, kind: str, data: dict[str, Any]
    ) -> int:
        """Record an alarm (``kind``: ``leak`` or ``repaired``); its id."""
        return int(
            conn.execute(
                sa.insert(alarms)
                .values(
                    machine_id=machine_id,
                    time=time,
                    kind=kind,
                    data=json.dumps(data, allow_nan=False),
                )
                .returning(alarms.c.id)
            ).scalar_one()
        )

    def update_alarm(self, conn: Connection, alarm_id: int, data: dict[str, Any]) -> None:
        """Replace an alarm's data (a declaration once its leak is located and sized)."""
        text = json.dumps(data, allow_nan=False)
        conn.execute(sa.update(alarms).where(alarms.c.id == alarm_id).values(data=text))

    # ----------------------------------------------------------- alarm outbox
    def add_outbox(
        self, conn: Connection, alarm_id: int, outputs: Sequence[str], payload: str
    ) -> None:
        """Queue an alarm's ``payload`` for each of ``outputs`` (in the alarm's transaction)."""
        for output in outputs:
            conn.execute(
                sa.insert(alarm_outbox).values(
                    alarm_id=alarm_id, output=output[:500], payload=payload
                )
            )

    def undelivered(self, machine_id: int, output: str, limit: int = 1000) -> list[tuple[int, str]]:
        """Alarms of a machine not yet delivered to ``output``, oldest first: (id, payload)."""
        query = (
            sa.select(alarm_outbox.c.alarm_id, alarm_outbox.c.payload)
            .join(alarms, alarms.c.id == alarm_outbox.c.alarm_id)
            .where(
                alarms.c.machine_id == machine_id,
                alarm_outbox.c.output == output[:500],
                alarm_outbox.c.delivered_at.is_(None),
            )
            .order_by(alarm_outbox.c.alarm_id)
            .limit(limit)
        )
        with self.engine.connect() as conn:
            return [(int(r[0]), str(r[1])) for r in conn.execute(query)]

    def undelivered_counts(self, machine_id: int) -> dict[str, int]:
        """Alarms of a machine not yet delivered, per output."""
        query = (
            sa.select(alarm_outbox.c.output, sa.func.count())
            .join(alarms, alarms.c.id == alarm_outbox.c.alarm_id)
            .where(alarms.c.machine_id == machine_id, alarm_outbox.c.delivered_at.is_(None))
            .group_by(alarm_outbox.c.output)
        )
        with self.engine.connect() as conn:
            return {str(r[0]): int(r[1]) for r in conn.execute(query)}

    def mark_delivered(self, alarm_id: int, output: str, time: float) -> None:
        """Note that alarm ``alarm_id`` reached ``output`` at ``time`` [s since 1970]."""
        with self.engine.begin() as conn:
            conn.execute(
                sa.update(alarm_outbox)
                .where(alarm_outbox.c.alarm_id == alarm_id, alarm_outbox.c.output == output[:500])
                .values(delivered_at=time)
            )

    # ----------------------------------------------------------- estimates
    def add_pending_estimate(
        self, conn: Connection, machine_id: int, time: float, job: bytes
    ) -> int:
        """Store a location and sizing run's input until its result is stored; its id."""
        return int(
            conn.execute(
                sa.insert(pending_estimates)
                .values(machine_id=machine_id, time=time, job=job)
                .returning(pending_estimates.c.id)
            ).scalar_one()
        )

    def pending_estimate_rows(self, machine_id: int) -> list[tuple[int, bytes]]:
        """Runs decided but not finished (a killed monitor's), oldest first: (id, input)."""
        query = (
            sa.select(pending_estimates.c.id, pending_estimates.c.job)
            .where(pending_estimates.c.machine_id == machine_id)
            .order_by(pending_estimates.c.id)
        )
        with self.engine.connect() as conn:
            return [(int(r[0]), bytes(r[1])) for r in conn.execute(query)]

    def remove_pending_estimate(self, conn: Connection, pending_id: int) -> None:
        """Drop a run's input (in the transaction that stores its result)."""
        conn.execute(sa.delete(pending_estimates).where(pending_estimates.c.id == pending_id))

    def add_diagnosis(
        self,
        conn: Connection,
        machine_id: int,
        time: float,
        first_cycle: float,
        n_cycles: int,
        data: dict[str, Any],
    ) -> None:
        """Record a location and sizing run."""
        conn.execute(
            sa.insert(diagnoses).values(
                machine_id=machine_id,
                time=time,
                first_cycle=first_cycle,
                n_cycles=n_cycles,
                data=json.dumps(data, allow_nan=False),
            )
        )

    def new_leak(
        self,
        conn: Connection,
        machine_id: int,
        location: str,
        time: float,
        flow_slpm: float,
        annual_cost: float,
        confidence: float,
    ) -> int:
        """Start tracking a leak; its id."""
        leak_id = conn.execute(
            sa.insert(leaks)
            .values(
                machine_id=machine_id,
                location=location,
                state="new",
                first_seen=time,
                last_seen=time,
                flow_slpm=_num(flow_slpm),
                annual_cost=_num(annual_cost),
                confidence=_num(confidence),
                cost_to_date=0.0,
            )
            .returning(leaks.c.id)
        ).scalar_one()
        self.add_size(conn, int(leak_id), time, flow_slpm, annual_cost)
        return int(leak_id)

    def add_size(
        self, conn: Connection, leak_id: int, time: float, flow_slpm: float, annual_cost: float
    ) -> None:
        """Record a size estimate of a tracked leak."""
        conn.execute(
            sa.insert(leak_sizes).values(
                leak_id=leak_id, time=time, flow_slpm=_num(flow_slpm), annual_cost=_num(annual_cost)
            )
        )

    def update_leak(self, conn: Connection, leak_id: int, **values: Any) -> None:
        """Change stored fields of a tracked leak."""
        clean = {k: (_num(v) if isinstance(v, float) else v) for k, v in values.items()}
        conn.execute(sa.update(leaks).where(leaks.c.id == leak_id).values(**clean))

    def accrue_cost(
        self, conn: Connection, leak_ids: Sequence[int], amounts: Sequence[float], time: float
    ) -> None:
        """Add ``amounts`` [$] to the cost to date of the leaks ``leak_ids``."""
        for leak_id, amount in zip(leak_ids, amounts, strict=True):
            if not math.isfinite(amount):
                continue
            conn.execute(
                sa.update(leaks)
                .where(leaks.c.id == leak_id)
                .values(cost_to_date=leaks.c.cost_to_date + amount, last_seen=time)
            )

    def add_gap(
        self,
        conn: Connection,
        machine_id: int,
        start: float,
        end: float,
        source: str,
        cycles_lost: int,
    ) -> None:
        """Record a span without cycles (``start`` to ``end`` [s since 1970-01-01 UTC])."""
        conn.execute(
            sa.insert(gaps).values(
                machine_id=machine_id,
                start=start,
                end=end,
                source=source[:500],
                cycles_lost=int(cycles_lost),
            )
        )

    def gap_rows(self, machine_id: int, since: float | None = None) -> list[dict[str, Any]]:
        """Gaps of a machine, oldest first: start, end, source, cycles_lost."""
        query = sa.select(gaps.c.start, gaps.c.end, gaps.c.source, gaps.c.cycles_lost).where(
            gaps.c.machine_id == machine_id
        )
        if since is not None:
            query = query.where(gaps.c.end >= since)
        with self.engine.connect() as conn:
            return [dict(r._mapping) for r in conn.execute(query.order_by(gaps.c.start))]

    def mark_repaired(self, machine: str, location: str, time: float) -> int:
        """The operator marks the active leak(s) at ``location`` repaired; how many."""
        machine_id = self.machine_id(machine)
        with self.engine.begin() as conn:
            result = conn.execute(
                sa.update(leaks)
                .where(
                    leaks.c.machine_id == machine_id,
                    leaks.c.location == location,
                    leaks.c.state != "repaired",
                )
                .values(state="repaired", repaired_at=time)
            )
        return int(result.rowcount)

    # ----------------------------------------------------------- reads
    def machines(self) -> list[tuple[int, str]]:
        """Every machine: (id, name)."""
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(machines.c.id, machines.c.name).order_by(machines.c.name))
            return [(int(r[0]), str(r[1])) for r in rows]

    def cycle_count(self, machine_id: int, since: float | None = None) -> int:
        """Cycles recorded for a machine (since ``since``)."""
        query = (
            sa.select(sa.func.count()).select_from(cycles).where(cycles.c.machine_id == machine_id)
        )
        if since is not None:
            query = query.where(cycles.c.start >= since)
        with self.engine.connect() as conn:
            return int(conn.execute(query).scalar_one())

    def cycle_span(self, machine_id: int, since: float | None = None) -> tuple[float, float] | None:
        """First and last cycle start [s since 1970-01-01 UTC]."""
        query = sa.select(sa.func.min(cycles.c.start), sa.func.max(cycles.c.start)).where(
            cycles.c.machine_id == machine_id
        )
        if since is not None:
            query = query.where(cycles.c.start >= since)
        with self.engine.connect() as conn:
            row = conn.execute(query).first()
        if row is None or row[0] is None:
            return None
        return float(row[0]), float(row[1])

    def cycle_starts(self, machine_id: int) -> list[float]:
        """Start of every recorded cycle, in order [s since 1970-01-01 UTC]."""
        with self.engine.connect() as conn:
            rows = conn.execute(
                sa.select(cycles.c.start_ms)
                .where(cycles.c.machine_id == machine_id)
                .order_by(cycles.c.start_ms)
            )
            return [r[0] / 1000.0 for r in rows]

    def cycle_rows(self, machine_id: int, since: float | None = None) -> list[dict[str, Any]]:
        """Every recorded cycle as a dict."""
        query = sa.select(cycles).where(cycles.c.machine_id == machine_id)
        if since is not None:
            query = query.where(cycles.c.start >= since)
        with self.engine.connect() as conn:
            return [dict(r._mapping) for r in conn.execute(query.order_by(cycles.c.start_ms))]

    def alarm_rows(self, machine_id: int, since: float | None = None) -> list[dict[str, Any]]:
        """Alarms of a machine, oldest first."""
        query = sa.select(alarms).where(alarms.c.machine_id == machine_id)
        if since is not None:
            query = query.where(alarms.c.time >= since)
        with self.engine.connect() as conn:
            rows = conn.execute(query.order_by(alarms.c.time, alarms.c.id))
            return [{"time": r.time, "kind": r.kind, **json.loads(r.data)} for r in rows]

    def diagnosis_count(self, machine_id: int) -> int:
        """Location and sizing runs recorded for a machine."""
        with self.engine.connect() as conn:
            return int(
                conn.execute(
                    sa.select(sa.func.count())
                    .select_from(diagnoses)
                    .where(diagnoses.c.machine_id == machine_id)
                ).scalar_one()
            )

    def leak_rows(self, machine_id: int, active_only: bool = False) -> list[LeakRow]:
        """Tracked leaks of a machine, oldest first."""
        query = sa.select(leaks).where(leaks.c.machine_id == machine_id)
        if active_only:
            query = query.where(leaks.c.state != "repaired")
        with self.engine.connect() as conn:
            rows = conn.execute(query.order_by(leaks.c.first_seen, leaks.c.id))
            return [
                LeakRow(
                    int(r.id),
                    str(r.location),
                    str(r.state),
                    float(r.first_seen),
                    float(r.last_seen),
                    None if r.repaired_at is None else float(r.repaired_at),
                    r.flow_slpm,
                    r.annual_cost,
                    r.confidence,
                    float(r.cost_to_date),
                )
                for r in rows
            ]

    def leak_sizes(self, leak_id: int) -> list[tuple[float, float | None, float | None]]:
        """Size estimates of a leak over time: (time, flow [SLPM], annual cost [$])."""
        with self.engine.connect() as conn:
            rows = conn.execute(
                sa.select(leak_sizes.c.time, leak_sizes.c.flow_slpm, leak_sizes.c.annual_cost)
                .where(leak_sizes.c.leak_id == leak_id)
                .order_by(leak_sizes.c.time)
            )
            return [(float(r[0]), r[1], r[2]) for r in rows]

    def integrity_ok(self) -> bool:
        """SQLite: ``PRAGMA integrity_check`` says ok; other databases: True."""
        if self.engine.dialect.name != "sqlite":
            return True
        with self.engine.connect() as conn:
            return str(conn.exec_driver_sql("PRAGMA integrity_check").scalar()) == "ok"


def _stored_version(conn: Connection) -> int:
    if not sa.inspect(conn).has_table("schema_info"):
        return 0
    value = conn.execute(sa.select(schema_info.c.version)).scalar()
    return int(value or 0)


def _insert(conn: Connection, table: sa.Table) -> Any:
    name = conn.dialect.name
    if name == "sqlite":
        from sqlalchemy.dialects.sqlite import insert as sqlite_insert

        return sqlite_insert(table)
    if name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert as pg_insert

        return pg_insert(table)
    raise InputError(describe("history database", name, ["sqlite", "postgresql"]))


def _engine(url: str) -> Engine:
    try:
        parsed = sa.engine.make_url(url)
    except sa.exc.ArgumentError:
        raise InputError(
            describe("--history", masked_url(url), "a SQLAlchemy URL such as sqlite:///history.db")
        ) from None
    backend = parsed.get_backend_name()
    if backend not in ("sqlite", "postgresql"):
        raise InputError(describe("--history database", backend, ["sqlite", "postgresql"]))
    if backend == "postgresql" and parsed.drivername == "postgresql":
        parsed = parsed.set(drivername="postgresql+psycopg")
    if backend == "sqlite":
        engine = sa.create_engine(parsed, connect_args={"timeout": SQLITE_TIMEOUT_S})

        @sa.event.listens_for(engine, "connect")
        def _pragmas(dbapi_conn: Any, _record: Any) -> None:
            cursor = dbapi_conn.cursor()
            _write_ahead_log(cursor)
            cursor.execute("PRAGMA synchronous=NORMAL")
            cursor.execute("PRAGMA foreign_keys=ON")
            cursor.close()

        return engine
    try:
        return sa.create_engine(parsed, pool_pre_ping=True)
    except ModuleNotFoundError as exc:
        raise InputError(
            describe("PostgreSQL driver", "missing", "pip install 'pneufdd[postgresql]'")
        ) from exc


SQLITE_TIMEOUT_S = 30.0
"""How long a SQLite connection waits for another writer's lock [s]."""


def _write_ahead_log(cursor: Any) -> None:
    """Put a SQLite database in WAL mode, waiting for another process doing the same.

    Switching a new database's journal takes its exclusive lock, and SQLite answers a
    second process switching at the same moment "database is locked" at once instead
    of waiting its busy timeout; that process tries again until the timeout.
    """
    import sqlite3
    import time

    deadline = time.monotonic() + SQLITE_TIMEOUT_S
    while True:
        try:
            cursor.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


def sqlite_path(url: str) -> Path | None:
    """The file of a ``sqlite:///`` history URL; None for other databases and memory.

    Examples
    --------
    >>> sqlite_path("sqlite:///data/h.db")
    PosixPath('data/h.db')
    >>> sqlite_path("postgresql://ann@db/history") is None
    True
    """
    try:
        parsed = sa.engine.make_url(url)
    except (sa.exc.ArgumentError, ValueError):
        return None
    if parsed.get_backend_name() != "sqlite" or parsed.database in (None, "", ":memory:"):
        return None
    return Path(parsed.database)


def open_history(url: str | None = None) -> HistoryDatabase:
    """Open (create, migrate) the history at ``url`` (default :data:`DEFAULT_HISTORY_URL`)."""
    return HistoryDatabase(url or DEFAULT_HISTORY_URL)
