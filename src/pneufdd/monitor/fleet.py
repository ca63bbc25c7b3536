"""The history as the dashboard reads it: a fleet summary from aggregates, one machine's page.

The fleet summary never reads every cycle: the newest cycle and the detector state come
from ``monitor_state`` (one row per machine, written with each cycle), the cycles of
the last 24 hours are counted on the cycles' primary-key index ``(machine_id,
start_ms)`` (a range per machine, not a scan), and leaks, alarms and gaps are small
tables read through their indexes. A machine's page reads its newest cycles only
(:data:`MAX_CYCLES_SHOWN`, newest first through the same index).

Writes of the dashboard and the monitor's start-up: :func:`save_machine_info` (the
description, thresholds and step names a monitor knows), :func:`acknowledge`; a repair
marked by an operator is :meth:`~pneufdd.monitor.database.HistoryDatabase.mark_repaired`,
the same as ``pneufdd history --repaired``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa

from pneufdd.monitor.database import (
    HistoryDatabase,
    acknowledgements,
    alarms,
    cycles,
    diagnoses,
    gaps,
    leaks,
    machine_info,
    machines,
    monitor_state,
)

__all__ = [
    "MAX_CYCLES_SHOWN",
    "FleetRow",
    "MachineInfo",
    "acknowledge",
    "alarm_list",
    "change_stamp",
    "cycle_series",
    "diagnosis_of_alarm",
    "fleet_summary",
    "leak_trends",
    "load_machine_info",
    "save_machine_info",
]

MAX_CYCLES_SHOWN = 2000
"""Newest cycles a machine's page reads and charts [-]."""
DAY_S = 86_400.0


@dataclass(frozen=True)
class FleetRow:
    """One machine in the fleet view."""

    machine_id: int
    name: str
    in_alarm: bool
    cusum: float | None
    last_cycle: float | None
    """Start of the newest recorded cycle [s since 1970-01-01 UTC]."""
    cycles_24h: int
    active_leaks: int
    leak_flow_slpm: float
    """Sum of the active leaks' flow while pressurised [SLPM: 0 degC, 1013 mbar]."""
    annual_cost: float
    """Sum of the active leaks' annual cost [$/yr]."""
    locations: tuple[str, ...]
    open_alarms: int
    """Leak alarms nobody acknowledged [-]."""
    alarms_total: int
    gaps: int
    cycles_lost: int
    last_gap_end: float | None

    @property
    def state(self) -> str:
        """``leak``, ``leak-free`` or ``no data``."""
        if self.last_cycle is None:
            return "no data"
        return "leak" if self.in_alarm or self.active_leaks else "leak-free"

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form (``/api/fleet``)."""
        return {
            "machine": self.name,
            "state": self.state,
            "in_alarm": self.in_alarm,
            "cusum": self.cusum,
            "last_cycle": self.last_cycle,
            "cycles_24h": self.cycles_24h,
            "active_leaks": self.active_leaks,
            "leak_flow_slpm": self.leak_flow_slpm,
            "annual_cost": self.annual_cost,
            "locations": list(self.locations),
            "open_alarms": self.open_alarms,
            "alarms_total": self.alarms_total,
            "gaps": self.gaps,
            "cycles_lost": self.cycles_lost,
        }


@dataclass(frozen=True)
class MachineInfo:
    """What a monitor stored of its machine at start (schema version 3)."""

    description: dict[str, Any]
    """The machine description's TOML mapping (empty: none)."""
    cusum_threshold: float | None
    cycle_threshold: float | None
    steps: tuple[str, ...]
    """Name of each PLC step, in order."""


def save_machine_info(
    db: HistoryDatabase,
    machine_id: int,
    time: float,
    description: Mapping[str, Any],
    cusum_threshold: float | None,
    cycle_threshold: float | None,
    steps: Sequence[str] = (),
) -> None:
    """Store (replace) what the monitor knows of the machine: description, thresholds."""

    def num(x: float | None) -> float | None:
        return None if x is None or not math.isfinite(x) else float(x)

    values = {
        "machine_id": machine_id,
        "time": time,
        "description": json.dumps(dict(description), allow_nan=False),
        "cusum_threshold": num(cusum_threshold),
        "cycle_threshold": num(cycle_threshold),
        "steps": json.dumps(list(steps)),
    }
    with db.begin() as conn:
        conn.execute(sa.delete(machine_info).where(machine_info.c.machine_id == machine_id))
        conn.execute(sa.insert(machine_info).values(**values))


def load_machine_info(db: HistoryDatabase, machine_id: int) -> MachineInfo | None:
    """The stored machine information; None when no monitor of schema 3 stored any."""
    with db.engine.connect() as conn:
        row = conn.execute(
            sa.select(machine_info).where(machine_info.c.machine_id == machine_id)
        ).first()
    if row is None:
        return None
    return MachineInfo(
        dict(json.loads(row.description)),
        row.cusum_threshold,
        row.cycle_threshold,
        tuple(str(s) for s in json.loads(row.steps)),
    )


def acknowledge(db: HistoryDatabase, alarm_id: int, user: str, time: float) -> bool:
    """Record that ``user`` acknowledged alarm ``alarm_id``; False when unknown or done."""
    with db.begin() as conn:
        known = conn.execute(sa.select(alarms.c.id).where(alarms.c.id == alarm_id)).first()
        done = conn.execute(
            sa.select(acknowledgements.c.alarm_id).where(acknowledgements.c.alarm_id == alarm_id)
        ).first()
        if known is None or done is not None:
            return False
        conn.execute(
            sa.insert(acknowledgements).values(alarm_id=alarm_id, time=time, user=user[:200])
        )
    return True


def change_stamp(db: HistoryDatabase) -> tuple[Any, ...]:
    """A value that changes whenever anything the dashboard shows changes.

    Cheap: maxima of primary keys and one sum over ``monitor_state`` (a row per
    machine), never a scan of the cycles.
    """
    query = sa.select(
        sa.select(sa.func.max(alarms.c.id)).scalar_subquery(),
        sa.select(sa.func.sum(monitor_state.c.last_start_ms)).scalar_subquery(),
        sa.select(sa.func.count()).select_from(monitor_state).scalar_subquery(),
        sa.select(sa.func.max(diagnoses.c.id)).scalar_subquery(),
        sa.select(sa.func.count()).select_from(acknowledgements).scalar_subquery(),
        sa.select(sa.func.count())
        .select_from(leaks)
        .where(leaks.c.state == "repaired")
        .scalar_subquery(),
        sa.select(sa.func.max(leaks.c.id)).scalar_subquery(),
        sa.select(sa.func.max(gaps.c.id)).scalar_subquery(),
    )
    with db.engine.connect() as conn:
        return tuple(conn.execute(query).one())


def fleet_summary(db: HistoryDatabase, now: float) -> list[FleetRow]:
    """Every machine's row of the fleet view, by name (aggregates only, see the module)."""
    since_ms = round((now - DAY_S) * 1000.0)
    recent = (
        sa.select(sa.func.count())
        .select_from(cycles)
        .where(cycles.c.machine_id == machines.c.id, cycles.c.start_ms >= since_ms)
        .scalar_subquery()
    )
    base = (
        sa.select(
            machines.c.id,
            machines.c.name,
            monitor_state.c.last_start_ms,
            monitor_state.c.state,
            recent,
        )
        .select_from(machines.outerjoin(monitor_state))
        .order_by(machines.c.name)
    )
    active = sa.select(
        leaks.c.machine_id, leaks.c.location, leaks.c.flow_slpm, leaks.c.annual_cost
    ).where(leaks.c.state != "repaired")
    open_alarms = (
        sa.select(alarms.c.machine_id, sa.func.count())
        .select_from(alarms.outerjoin(acknowledgements))
        .where(alarms.c.kind == "leak", acknowledgements.c.alarm_id.is_(None))
        .group_by(alarms.c.machine_id)
    )
    all_alarms = sa.select(alarms.c.machine_id, sa.func.count()).group_by(alarms.c.machine_id)
    gap_totals = sa.select(
        gaps.c.machine_id, sa.func.count(), sa.func.sum(gaps.c.cycles_lost), sa.func.max(gaps.c.end)
    ).group_by(gaps.c.machine_id)
    with db.engine.connect() as conn:
        rows = conn.execute(base).all()
        found: dict[int, list[tuple[str, float, float]]] = {}
        for r in conn.execute(active):
            found.setdefault(int(r[0]), []).append((str(r[1]), r[2] or 0.0, r[3] or 0.0))
        unacked = {int(r[0]): int(r[1]) for r in conn.execute(open_alarms)}
        counted = {int(r[0]): int(r[1]) for r in conn.execute(all_alarms)}
        lost = {int(r[0]): (int(r[1]), int(r[2] or 0), r[3]) for r in conn.execute(gap_totals)}
    out = []
    for machine_id, name, last_ms, state_text, recent_count in rows:
        state = json.loads(state_text) if state_text else {}
        cusum = state.get("cusum", {})
        mine = found.get(int(machine_id), [])
        gap = lost.get(int(machine_id), (0, 0, None))
        out.append(
            FleetRow(
                int(machine_id),
                str(name),
                bool(cusum.get("in_alarm", False)),
                cusum.get("up"),
                None if last_ms is None else last_ms / 1000.0,
                int(recent_count or 0),
                len(mine),
                float(sum(x[1] for x in mine)),
                float(sum(x[2] for x in mine)),
                tuple(x[0] for x in mine),
                unacked.get(int(machine_id), 0),
                counted.get(int(machine_id), 0),
                gap[0],
                gap[1],
                gap[2],
            )
        )
    return out


def cycle_series(
    db: HistoryDatabase, machine_id: int, limit: int = MAX_CYCLES_SHOWN
) -> list[dict[str, Any]]:
    """The newest ``limit`` cycles of a machine, oldest first (start, duration, score, cusum)."""
    query = (
        sa.select(cycles.c.start, cycles.c.duration_s, cycles.c.score, cycles.c.cusum)
        .where(cycles.c.machine_id == machine_id)
        .order_by(cycles.c.start_ms.desc())
        .limit(limit)
    )
    with db.engine.connect() as conn:
        rows = [dict(r._mapping) for r in conn.execute(query)]
    return rows[::-1]


def alarm_list(db: HistoryDatabase, machine_id: int, limit: int = 200) -> list[dict[str, Any]]:
    """The newest alarms of a machine, newest first, with id and acknowledgement."""
    query = (
        sa.select(
            alarms.c.id,
            alarms.c.time,
            alarms.c.kind,
            alarms.c.data,
            acknowledgements.c.time.label("ack_time"),
            acknowledgements.c.user.label("ack_user"),
        )
        .select_from(alarms.outerjoin(acknowledgements))
        .where(alarms.c.machine_id == machine_id)
        .order_by(alarms.c.time.desc(), alarms.c.id.desc())
        .limit(limit)
    )
    with db.engine.connect() as conn:
        return [
            {
                **json.loads(r.data),  # the alarm log's object (its "time" is ISO text)
                "id": int(r.id),
                "time": float(r.time),
                "kind": str(r.kind),
                "ack_time": r.ack_time,
                "ack_user": r.ack_user,
            }
            for r in conn.execute(query)
        ]


def diagnosis_of_alarm(db: HistoryDatabase, alarm_id: int) -> tuple[str, dict[str, Any]] | None:
    """(machine name, the diagnosis document) of a leak alarm; None when it has none.

    An alarm and the location and sizing run that raised it are written in one
    transaction with the same machine and time (``MachineMonitor._estimate``).
    """
    with db.engine.connect() as conn:
        alarm = conn.execute(
            sa.select(alarms.c.machine_id, alarms.c.time, machines.c.name)
            .select_from(alarms.join(machines))
            .where(alarms.c.id == alarm_id)
        ).first()
        if alarm is None:
            return None
        row = conn.execute(
            sa.select(diagnoses.c.data, diagnoses.c.first_cycle, diagnoses.c.n_cycles)
            .where(diagnoses.c.machine_id == alarm.machine_id, diagnoses.c.time == alarm.time)
            .order_by(diagnoses.c.id.desc())
        ).first()
    if row is None:
        return None
    data = dict(json.loads(row.data))
    data["window"] = {"first_cycle": row.first_cycle, "cycles": row.n_cycles, "time": alarm.time}
    return str(alarm.name), data


def leak_trends(db: HistoryDatabase, machine_id: int) -> list[dict[str, Any]]:
    """Every tracked leak of a machine with its size estimates over time."""
    out = []
    for row in db.leak_rows(machine_id):
        sizes = db.leak_sizes(row.id)
        out.append(
            {
                "location": row.location,
                "state": row.state,
                "first_seen": row.first_seen,
                "repaired_at": row.repaired_at,
                "flow_slpm": row.flow_slpm,
                "annual_cost": row.annual_cost,
                "confidence": row.confidence,
                "cost_to_date": row.cost_to_date,
                "sizes": [
                    {"time": float(t), "flow_slpm": f, "annual_cost": c} for t, f, c in sizes
                ],
            }
        )
    return out
