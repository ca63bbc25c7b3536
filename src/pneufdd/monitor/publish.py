"""Results back to the plant: one snapshot per cycle, handed to every publisher.

:class:`Publishers` is the monitor's publish hook (``MachineMonitor(publish=...)``):
after each cycle's transaction has committed it builds the machine's **snapshot**
(:func:`snapshot`) and gives it, with the newest diagnosis document when a location
and sizing run was added, to each publisher: OPC UA
(:mod:`pneufdd.monitor.publish_opcua`), MQTT (:mod:`pneufdd.monitor.publish_mqtt`),
Prometheus (:class:`pneufdd.monitor.metrics.MonitorMetrics`). A publisher that fails
is reported through ``warn`` and never stops the monitor, nor the other publishers.

The snapshot (JSON; the MQTT ``state`` message, schema ``pneufdd.state/1``,
``docs/monitor.md`` section Publishing):

``schema``, ``machine``, ``time`` (ISO, UTC) and ``timestamp`` of the cycle's start,
``state`` (``leak``, ``leak-free`` or ``start-up``), ``in_alarm``, ``score`` (null for
a skipped or start-up cycle), ``cusum``, ``cusum_threshold``, ``cycle_threshold``,
``recorded``, ``skipped_incomplete``, ``last_cycle``, ``findings`` (per active leak:
``location``, ``state``, ``flow_slpm`` [SLPM: 0 degC, 1013 mbar], ``annual_cost``
[$/yr]), ``last_alarm`` (the alarm log's object, or null) and ``new_alarms`` (the
alarms of this cycle).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any, Protocol

import sqlalchemy as sa

from pneufdd.monitor.database import diagnoses

if TYPE_CHECKING:
    from pneufdd.monitor.live import CycleOutcome, MachineMonitor

__all__ = ["SNAPSHOT_SCHEMA", "Publisher", "Publishers", "snapshot"]

SNAPSHOT_SCHEMA = "pneufdd.state/1"


class Publisher(Protocol):
    """Something that shows the machine's state outside pneufdd."""

    name: str

    def publish(self, state: Mapping[str, Any], diagnosis: Mapping[str, Any] | None) -> None:
        """Show one cycle's snapshot (and a new diagnosis document, when there is one)."""

    def close(self) -> None:
        """Stop (flush what is pending)."""


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def snapshot(
    monitor: MachineMonitor, outcome: CycleOutcome, last_alarm: Mapping[str, Any] | None
) -> dict[str, Any]:
    """The machine's state after ``outcome`` (format in the module docstring)."""
    in_alarm = bool(monitor.state.in_alarm)
    scored = math.isfinite(outcome.score)
    if in_alarm or monitor.tracked:
        state = "leak"
    else:
        state = "leak-free" if scored or outcome.incomplete else "start-up"
    return {
        "schema": SNAPSHOT_SCHEMA,
        "machine": monitor.machine,
        "time": datetime.fromtimestamp(outcome.start, UTC).isoformat(),
        "timestamp": outcome.start,
        "state": state,
        "in_alarm": in_alarm,
        "score": _num(outcome.score),
        "cusum": float(outcome.cusum),
        "cusum_threshold": float(monitor.cusum.decision_threshold),
        "cycle_threshold": _num(float(monitor.detector.threshold_)),
        "recorded": bool(outcome.recorded),
        "skipped_incomplete": bool(outcome.incomplete),
        "last_cycle": outcome.start,
        "findings": [
            {
                "location": t.location,
                "state": t.state,
                "flow_slpm": _num(t.flow_slpm),
                "annual_cost": _num(t.annual_cost),
            }
            for t in monitor.tracked.values()
        ],
        "last_alarm": None if last_alarm is None else dict(last_alarm),
        "new_alarms": [a.to_dict() for a in outcome.alarms],
    }


class Publishers:
    """The publish hook of :class:`~pneufdd.monitor.live.MachineMonitor`.

    Parameters
    ----------
    publishers : sequence of Publisher
        Where each snapshot goes.
    warn : callable, optional
        Called with a message when a publisher fails.
    """

    def __init__(
        self, publishers: Sequence[Publisher], warn: Callable[[str], None] | None = None
    ) -> None:
        self.publishers = list(publishers)
        self.warn = warn
        self.last_alarm: dict[str, Any] | None = None
        self._diagnoses = 0  # location and sizing runs of this session already shown

    def __call__(self, monitor: MachineMonitor, outcome: CycleOutcome) -> None:
        """Publish the state after one processed cycle (called once it is committed)."""
        if not self.publishers:
            return
        if outcome.alarms:
            self.last_alarm = outcome.alarms[-1].to_dict()
        diagnosis = None
        if monitor.stats.diagnoses != self._diagnoses:
            diagnosis = self._newest_diagnosis(monitor)
            self._diagnoses = monitor.stats.diagnoses
        state = snapshot(monitor, outcome, self.last_alarm)
        for publisher in self.publishers:
            try:
                publisher.publish(state, diagnosis)
            except Exception as exc:  # a publisher never stops the monitor
                if self.warn is not None:
                    self.warn(f"{publisher.name} failed: {type(exc).__name__}: {exc}")

    @staticmethod
    def _newest_diagnosis(monitor: MachineMonitor) -> dict[str, Any] | None:
        with monitor.history.engine.connect() as conn:
            row = conn.execute(
                sa.select(diagnoses.c.time, diagnoses.c.data)
                .where(diagnoses.c.machine_id == monitor.machine_id)
                .order_by(diagnoses.c.id.desc())
                .limit(1)
            ).first()
        if row is None:
            return None
        data = dict(json.loads(row.data))
        data.update(
            machine=monitor.machine,
            time=datetime.fromtimestamp(row.time, UTC).isoformat(),
            timestamp=row.time,
        )
        return data

    def close(self) -> None:
        """Close every publisher (errors reported, not raised)."""
        for publisher in self.publishers:
            try:
                publisher.close()
            except Exception as exc:
                if self.warn is not None:
                    self.warn(f"{publisher.name} did not close cleanly: {exc}")
