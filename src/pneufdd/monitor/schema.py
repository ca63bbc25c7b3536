"""The history database's tables and their migrations (schema version :data:`SCHEMA_VERSION`).

``MIGRATIONS[k]`` takes a database from version ``k`` to ``k + 1``;
:class:`~pneufdd.monitor.database.HistoryDatabase` applies them in order on open.
Version 2 adds ``gaps``; version 3 ``machine_info`` and ``acknowledgements`` (the
dashboard's); version 4 ``pending_estimates`` (a location and sizing run decided with a
committed cycle and not yet finished: its input, so that a restart redoes it) and
``alarm_outbox`` (each alarm's delivery to each output: an alarm committed but not yet
delivered when the process died is delivered at the next start).
"""

from __future__ import annotations

from collections.abc import Callable

import sqlalchemy as sa
from sqlalchemy.engine import Connection

__all__ = [
    "MIGRATIONS",
    "SCHEMA_VERSION",
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
    "metadata",
    "monitor_state",
    "pending_estimates",
    "schema_info",
]

metadata = sa.MetaData()

schema_info = sa.Table("schema_info", metadata, sa.Column("version", sa.Integer, nullable=False))
machines = sa.Table(
    "machines",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("name", sa.String(200), nullable=False, unique=True),
)
cycles = sa.Table(
    "cycles",
    metadata,
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), primary_key=True),
    sa.Column("start_ms", sa.BigInteger, primary_key=True, autoincrement=False),
    sa.Column("start", sa.Float, nullable=False),
    sa.Column("duration_s", sa.Float, nullable=False),
    sa.Column("score", sa.Float),
    sa.Column("cusum", sa.Float),
    sa.Column("supply_air_kg", sa.Float),
    sa.Column("supply_pressure_pa", sa.Float),
)
monitor_state = sa.Table(
    "monitor_state",
    metadata,
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), primary_key=True),
    sa.Column("last_start_ms", sa.BigInteger, nullable=False),
    sa.Column("state", sa.Text, nullable=False),
)
alarms = sa.Table(
    "alarms",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("kind", sa.String(20), nullable=False),
    sa.Column("data", sa.Text, nullable=False),
)
diagnoses = sa.Table(
    "diagnoses",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("first_cycle", sa.Float, nullable=False),
    sa.Column("n_cycles", sa.Integer, nullable=False),
    sa.Column("data", sa.Text, nullable=False),
)
leaks = sa.Table(
    "leaks",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False),
    sa.Column("location", sa.String(100), nullable=False),
    sa.Column("state", sa.String(20), nullable=False),
    sa.Column("first_seen", sa.Float, nullable=False),
    sa.Column("last_seen", sa.Float, nullable=False),
    sa.Column("repaired_at", sa.Float),
    sa.Column("flow_slpm", sa.Float),
    sa.Column("annual_cost", sa.Float),
    sa.Column("confidence", sa.Float),
    sa.Column("cost_to_date", sa.Float, nullable=False, default=0.0),
)
leak_sizes = sa.Table(
    "leak_sizes",
    metadata,
    sa.Column("leak_id", sa.Integer, sa.ForeignKey("leaks.id"), nullable=False),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("flow_slpm", sa.Float),
    sa.Column("annual_cost", sa.Float),
)
sa.Index("ix_alarms_machine_time", alarms.c.machine_id, alarms.c.time)
sa.Index("ix_leaks_machine", leaks.c.machine_id, leaks.c.state)
sa.Index("ix_leak_sizes_leak", leak_sizes.c.leak_id, leak_sizes.c.time)
_V1_TABLES = (schema_info, machines, cycles, monitor_state, alarms, diagnoses, leaks, leak_sizes)
gaps = sa.Table(
    "gaps",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False),
    sa.Column("start", sa.Float, nullable=False),
    sa.Column("end", sa.Float, nullable=False),
    sa.Column("source", sa.String(500), nullable=False),
    sa.Column("cycles_lost", sa.Integer, nullable=False),
)
sa.Index("ix_gaps_machine_start", gaps.c.machine_id, gaps.c.start)


def _create_v1(conn: Connection) -> None:
    metadata.create_all(conn, tables=list(_V1_TABLES))


def _add_gaps_v2(conn: Connection) -> None:
    metadata.create_all(conn, tables=[gaps])


machine_info = sa.Table(
    "machine_info",
    metadata,
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), primary_key=True),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("description", sa.Text, nullable=False),
    sa.Column("cusum_threshold", sa.Float),
    sa.Column("cycle_threshold", sa.Float),
    sa.Column("steps", sa.Text, nullable=False),
)
acknowledgements = sa.Table(
    "acknowledgements",
    metadata,
    sa.Column("alarm_id", sa.Integer, sa.ForeignKey("alarms.id"), primary_key=True),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("user", sa.String(200), nullable=False),
)
pending_estimates = sa.Table(
    "pending_estimates",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("machine_id", sa.Integer, sa.ForeignKey("machines.id"), nullable=False),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("job", sa.LargeBinary, nullable=False),
)
alarm_outbox = sa.Table(
    "alarm_outbox",
    metadata,
    sa.Column("alarm_id", sa.Integer, sa.ForeignKey("alarms.id"), primary_key=True),
    sa.Column("output", sa.String(500), primary_key=True),
    sa.Column("payload", sa.Text, nullable=False),
    sa.Column("delivered_at", sa.Float),
)
sa.Index("ix_alarm_outbox_output", alarm_outbox.c.output, alarm_outbox.c.delivered_at)


def _add_machine_info_v3(conn: Connection) -> None:
    metadata.create_all(conn, tables=[machine_info, acknowledgements])


def _add_estimates_and_outbox_v4(conn: Connection) -> None:
    metadata.create_all(conn, tables=[pending_estimates, alarm_outbox])


MIGRATIONS: tuple[Callable[[Connection], None], ...] = (
    _create_v1,
    _add_gaps_v2,
    _add_machine_info_v3,
    _add_estimates_and_outbox_v4,
)
"""``MIGRATIONS[k]`` takes a database from version ``k`` to ``k + 1``."""

SCHEMA_VERSION = len(MIGRATIONS)
