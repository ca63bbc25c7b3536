"""Watch a running machine: stream -> cycles -> scores -> CUSUM -> diagnosis -> history.

:class:`MachineMonitor` takes completed cycles (:class:`~pneufdd.monitor.cycles.CompletedCycle`)
one at a time. Each is scored with the reference's per-cycle statistic (the one
``pneufdd diagnose`` uses), fed to the CUSUM of :mod:`pneufdd.monitor.sequential`,
and recorded with the detector state in one database transaction. When a leak is
declared, the cycles since the change point are located, sized and costed by the
same engine as ``pneufdd diagnose`` (:func:`pneufdd.diagnosis.engine.diagnose`); the
estimate is repeated after 5, 10 and 20 cycles and every 20 cycles after, on the
newest :data:`WINDOW` cycles. Leaks are tracked by location through their life
(``new`` -> ``growing``/``stable`` -> ``repaired``).

Only a bounded window of per-cycle summaries is kept in memory (:data:`WINDOW`
cycles); everything else is in the database. After a restart the detector resumes
from the state stored with the newest recorded cycle, and cycles already recorded
are skipped (their summaries refill the window), so a replay fed twice, or resumed
after a crash, records each cycle once and continues as if never stopped; a
re-estimate that falls due while the window holds too few cycles (a restart on a
live source) waits for them.
"""

from __future__ import annotations

import json
import math
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from typing import Any

from pneufdd.diagnosis.cost import CostSettings
from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.monitor.alarms import Alarm, AlarmSinks
from pneufdd.monitor.cycles import CompletedCycle, concatenate_rows
from pneufdd.monitor.database import HistoryDatabase
from pneufdd.monitor.estimates import EstimateJob, EstimateWorker, Timed, decode_job, encode_job
from pneufdd.monitor.sequential import CusumDecision, CusumDetector, CusumState

__all__ = ["WINDOW", "CycleOutcome", "MachineMonitor", "MonitorStats"]

WINDOW = 20
"""Cycles of summaries kept in memory for locating and sizing [-]."""
REESTIMATE_AT = (5, 10, 20)
"""Cycles after the change point at which a declared leak is re-estimated; then every 20."""
REESTIMATE_MIN_CYCLES = 2
"""Cycles a re-estimate needs in the window; a due re-estimate waits for them [-]."""
CONTIGUOUS_S = 0.05
"""A cycle starting within this of the stored newest cycle's end continues it [s]."""
GROWTH_RATIO = 1.2
"""A leak whose estimate rises by this factor over its previous one is growing [-]."""


@dataclass(frozen=True)
class CycleOutcome:
    """What one cycle did: its score, the CUSUM, and any alarm."""

    start: float
    score: float
    cusum: float
    recorded: bool
    alarms: tuple[Alarm, ...] = ()
    """Alarms raised with this cycle, after those of the estimates stored since the
    previous cycle (a located leak's alarm comes once its estimate is stored)."""
    gap_s: float = 0.0
    """Time without a cycle before this one (0: it follows the previous cycle) [s]."""
    cycles_lost: int = 0
    """Cycles estimated lost in that gap [-]."""
    incomplete: tuple[tuple[str, float], ...] = ()
    """Channels the source lost samples of in this cycle, with the share received [-]:
    the cycle was skipped (not scored, not recorded; :mod:`pneufdd.monitor.completeness`)."""
    declared: bool = False
    """The CUSUM declared a leak with this cycle; its location and size follow (the
    estimate runs beside the ingestion, :mod:`pneufdd.monitor.estimates`)."""


@dataclass
class _Tracked:
    id: int
    location: str
    state: str
    flow_slpm: float
    annual_cost: float


@dataclass
class _Running:
    """An estimate decided and stored, its result not yet stored."""

    job: EstimateJob
    future: Future[Timed] | None


@dataclass
class MonitorStats:
    """Counters of a monitoring session."""

    cycles: int = 0
    recorded: int = 0
    skipped: int = 0
    """Cycles already in the history (a replay fed again, a restart)."""
    judged: int = 0
    """Cycles scored into the CUSUM in this session (not start-up, not skipped)."""
    startup: int = 0
    """Start-up cycles: recorded, not judged."""
    alarms: int = 0
    diagnoses: int = 0
    gaps: int = 0
    cycles_lost: int = 0
    incomplete: int = 0
    """Cycles skipped because the source lost samples in them."""
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)


class MachineMonitor:
    """Sequential leak detection and fault history for one machine.

    Parameters
    ----------
    model : ReferenceModel
        The machine's leak-free reference.
    history : HistoryDatabase
        Where cycles, alarms, diagnoses and leaks are recorded.
    machine : str, optional
        Name in the history (default: the reference's machine).
    arl0 : float
        In-control average run length of the CUSUM [cycles].
    cost : CostSettings, optional
        Economic inputs of eq. 1.1.
    alarm : callable, optional
        Called with every :class:`Alarm` after it is committed. An
        :class:`~pneufdd.monitor.alarms.AlarmSinks` is attached to the history: each
        alarm is queued for each of its outputs in the alarm's transaction and marked
        once delivered (the outbox; a restart delivers what was not).
    source : str
        What the cycles come from (a gap's ``source`` in the history; no password).
    estimates : str
        Where locating and sizing run (:data:`pneufdd.monitor.estimates.MODES`):
        ``process`` (a worker process) or ``thread`` beside the ingestion, ``inline``
        on the caller's thread when the next cycle needs the result.
    publish : callable, optional
        Called with the monitor and each cycle's :class:`CycleOutcome` after the cycle
        is committed (:class:`pneufdd.monitor.publish.Publishers`: OPC UA, MQTT, metrics).
    """

    def __init__(
        self,
        model: ReferenceModel,
        history: HistoryDatabase,
        machine: str | None = None,
        arl0: float = 1.0e6,
        cost: CostSettings | None = None,
        alarm: Callable[[Alarm], None] | None = None,
        source: str = "",
        estimates: str = "process",
        publish: Callable[[MachineMonitor, CycleOutcome], None] | None = None,
    ) -> None:
        self.publish = publish
        self.model = model
        self.source = source
        self.history = history
        self.machine = machine or model.machine
        self.detector = model.detector
        self.cusum = CusumDetector.from_reference(self.detector, arl0=arl0)
        self.cost = cost or CostSettings()
        self.alarm = alarm
        self.worker = EstimateWorker(model, self.cost, estimates)
        self.machine_id = history.machine_id(self.machine)
        self.window: deque[CompletedCycle] = deque(maxlen=WINDOW)
        # the first complete cycles of a stream are start-up cycles, as in a file
        # (DetectionSettings.startup_cycles): recorded, but neither judged nor used
        # for the size estimates
        self._startup_left = int(model.settings.startup_cycles)
        self.stats = MonitorStats()
        self.state = CusumState()
        self.last_start = -math.inf
        # end of the newest recorded cycle (None: unknown); a first new cycle that starts
        # there continues the history (the machine ran on): it is no start-up cycle
        self.last_end: float | None = None
        self.alarm_cycles = 0
        self.episode_start: float | None = None
        # a re-estimate fell due while the window held too few cycles (after a restart)
        self.estimate_pending = False
        stored = history.load_state(self.machine_id)
        if stored is not None:
            self.last_start = stored[0]
            self.state = CusumState.from_dict(stored[1]["cusum"])
            self.alarm_cycles = int(stored[1].get("alarm_cycles", 0))
            self.episode_start = stored[1].get("episode_start")
            self.last_end = stored[1].get("last_end")
            self.estimate_pending = bool(stored[1].get("estimate_pending", False))
        self.tracked: dict[str, _Tracked] = {
            row.location: _Tracked(
                row.id,
                row.location,
                row.state,
                row.flow_slpm if row.flow_slpm is not None else math.nan,
                row.annual_cost if row.annual_cost is not None else math.nan,
            )
            for row in history.leak_rows(self.machine_id, active_only=True)
        }
        q_in = "Q_In" in model.channels
        p_in = "P_In" in model.channels
        self._q = model.channels.index("Q_In") if q_in else None
        self._p = model.channels.index("P_In") if p_in else None
        # estimates decided with a committed cycle whose result is not yet stored, in
        # order; a killed monitor's are in the history and run again now
        self._running: deque[_Running] = deque()
        self._decided: list[EstimateJob] = []
        self._stored_alarms: list[Alarm] = []  # of estimates, for the next cycle's outcome
        for pending_id, data in history.pending_estimate_rows(self.machine_id):
            job = replace(decode_job(data), pending_id=pending_id)
            self._running.append(_Running(job, self.worker.start(job)))
        # the alarm outbox: every alarm is queued for each output in its transaction
        self.outputs: tuple[str, ...] = ()
        if isinstance(alarm, AlarmSinks):
            self.outputs = alarm.attach(history, self.machine_id)

    # ------------------------------------------------------------ per cycle
    def process(self, cycle: CompletedCycle) -> CycleOutcome:
        """Score, decide, record (one transaction), then raise the alarms.

        A new cycle is taken only once the estimates decided before it are stored
        (:meth:`settle`: waits for a running one), so the history does not depend on
        how long an estimate took. The monitor's memory changes only with a committed
        transaction: an exception inside it (a database error, an interruption) leaves
        the monitor as it was before the cycle, which is also what a restart finds in
        the history.
        """
        self.stats.cycles += 1
        if cycle.start > self.last_start + 5e-4:
            self.settle()
        memory = self._memory()
        try:
            outcome = self._process(cycle)
        except BaseException:
            self._recall(memory)
            raise
        self._start_decided()
        if self.publish is not None:  # the one publish hook: after the commit
            self.publish(self, outcome)
        return outcome

    def skip_incomplete(
        self, cycle: CompletedCycle, short: Sequence[tuple[str, float]]
    ) -> CycleOutcome:
        """Count a cycle the source lost samples of, without scoring or recording it.

        Its time stays without a recorded cycle, so the next recorded cycle stores
        the gap (section Gaps of ``docs/monitor.md``).
        """
        self.stats.cycles += 1
        self.stats.incomplete += 1
        return CycleOutcome(cycle.start, math.nan, self.state.up, False, incomplete=tuple(short))

    @property
    def busy(self) -> bool:
        """An estimate runs beside the ingestion: new cycles should wait (:meth:`poll`)."""
        return self.worker.concurrent and bool(self._running)

    def poll(self) -> int:
        """Store the results of the estimates that have finished, in order; how many."""
        done = 0
        while self._running and self._running[0].future is not None:
            if not self._running[0].future.done():
                break
            self._store_estimate(self._running.popleft())
            done += 1
        return done

    def settle(self) -> None:
        """Store the result of every estimate decided so far (waiting for them)."""
        while self._running:
            self._store_estimate(self._running.popleft())

    def close(self) -> None:
        """Store what is still running and release the worker."""
        try:
            self.settle()
        finally:
            self.worker.close()

    def _process(self, cycle: CompletedCycle) -> CycleOutcome:
        startup = self._is_startup(cycle)
        if cycle.start <= self.last_start + 5e-4:
            # already recorded (a replay fed again, a restart): its summaries rebuild
            # the window the sizes are estimated from, as when it was first judged
            if not startup:
                self.window.append(cycle)
            self.stats.skipped += 1
            return CycleOutcome(cycle.start, math.nan, self.state.up, False)
        table = cycle.table
        score = float(self.detector.score_samples(table.features())[0])
        gap_s, lost, gap_from = 0.0, 0, self.last_end
        if gap_from is not None and cycle.start - gap_from > CONTIGUOUS_S:
            # cycles missing between the newest recorded one and this one (an outage,
            # a monitor that was away, data that held no complete cycle)
            gap_s = cycle.start - gap_from
            typical = sorted(c.duration_s for c in self.window) or [cycle.duration_s]
            lost = max(1, round(gap_s / typical[len(typical) // 2]))
        if startup:
            decision = CusumDecision(None, 0.0, self.state)
        else:
            decision = self.cusum.update(self.state, score, cycle.start)
            self.window.append(cycle)
        if self.state.in_alarm:
            self.alarm_cycles += 1
        pending: list[Alarm] = []
        supply_air = float(table.cycle_integral("Q_In")[0]) if self._q is not None else None
        supply_p = float(table.cycle_mean("P_In")[0]) if self._p is not None else None
        with self.history.begin() as conn:
            recorded = self.history.add_cycle(
                conn,
                self.machine_id,
                cycle.start,
                cycle.duration_s,
                score,
                self.state.up,
                supply_air,
                supply_p,
            )
            if recorded:
                if lost and gap_from is not None:
                    self.history.add_gap(
                        conn, self.machine_id, gap_from, cycle.start, self.source, lost
                    )
                pending += self._decide(conn, cycle, decision)
                state = {
                    "cusum": self.state.to_dict(),
                    "alarm_cycles": self.alarm_cycles,
                    "episode_start": self.episode_start,
                    "last_end": cycle.start + cycle.duration_s,
                    "estimate_pending": self.estimate_pending,
                }
                self.history.save_state(conn, self.machine_id, cycle.start, state)
        self.last_start = cycle.start
        self.last_end = cycle.start + cycle.duration_s
        if recorded:
            self.stats.recorded += 1
            self.stats.startup += startup
            self.stats.judged += not startup
            if lost:
                self.stats.gaps += 1
                self.stats.cycles_lost += lost
        else:
            self.stats.skipped += 1
            gap_s, lost = 0.0, 0
            self._decided.clear()
        self._raise(pending)
        alarms, self._stored_alarms = (*self._stored_alarms, *pending), []
        return CycleOutcome(
            cycle.start,
            score,
            self.state.up,
            recorded,
            alarms,
            gap_s,
            lost,
            declared=recorded and decision.event == "leak",
        )

    def _decide(self, conn: Any, cycle: CompletedCycle, decision: CusumDecision) -> list[Alarm]:
        """Alarms, estimates and cost of a recorded cycle (inside its transaction).

        An estimate is only decided here (its input stored, :meth:`_decide_estimate`);
        it runs after the commit, and the cycle's cost accrues when its result is
        stored, at the sizes it finds.
        """
        pending: list[Alarm] = []
        estimate = False
        if decision.event == "leak":
            self.alarm_cycles, self.estimate_pending = 1, False
            self._decide_estimate(conn, cycle, declared=True)
            estimate = True
        elif decision.event == "repaired":
            pending.append(self._repaired(conn, cycle))
            self.alarm_cycles, self.episode_start = 0, None
            self.estimate_pending = False
        elif self.state.in_alarm and (_due(self.alarm_cycles) or self.estimate_pending):
            # after a restart on a live source the window starts empty (the first
            # cycle may be a start-up cycle, kept out of it): a due re-estimate waits
            # until the window holds enough cycles, instead of failing on none
            if len(self.window) >= REESTIMATE_MIN_CYCLES:
                self.estimate_pending = False
                self._decide_estimate(conn, cycle, declared=False)
                estimate = True
            else:
                self.estimate_pending = True
        if self.tracked and not estimate:
            self._accrue(conn, cycle.start, cycle.duration_s)
        return pending

    def _accrue(self, conn: Any, time: float, duration_s: float) -> None:
        """Add one cycle's cost to every tracked leak."""
        rate = duration_s / (self.cost.hours * 3600.0)
        ids = [t.id for t in self.tracked.values()]
        amounts = [t.annual_cost * rate for t in self.tracked.values()]
        self.history.accrue_cost(conn, ids, amounts, time)

    def _is_startup(self, cycle: CompletedCycle) -> bool:
        """Whether ``cycle`` is one of the stream's start-up cycles (counted down).

        The first complete cycles a monitor sees are start-up cycles, whether already
        recorded or not (a replay fed again skips its first cycle as it judged it the
        first time). A new cycle that starts where the newest recorded cycle ended
        continues the history: the machine ran on while the monitor was away, and
        neither it nor any later cycle is a start-up cycle.
        """
        if self._startup_left <= 0:
            return False
        if (
            self.last_end is not None
            and cycle.start > self.last_start + 5e-4
            and abs(cycle.start - self.last_end) <= CONTIGUOUS_S
        ):
            self._startup_left = 0
            return False
        self._startup_left -= 1
        return True

    def _memory(self) -> tuple[Any, ...]:
        tracked = {k: replace(v) for k, v in self.tracked.items()}
        return (
            replace(self.state),
            self.alarm_cycles,
            self.episode_start,
            self.estimate_pending,
            self._startup_left,
            tracked,
            list(self.window),
        )

    def _recall(self, memory: tuple[Any, ...]) -> None:
        (
            self.state,
            self.alarm_cycles,
            self.episode_start,
            self.estimate_pending,
            self._startup_left,
            self.tracked,
            window,
        ) = memory
        self.window.clear()
        self.window.extend(window)
        self._decided.clear()

    def _since_change(self) -> list[CompletedCycle]:
        """Cycles since the change point of the current episode, at most the newest 10.

        The change-point cycle itself is left out once two cycles follow it: a leak
        usually appears during a cycle, so that cycle is part leak-free, part leaky,
        and its transient matches no leak signature (a 3-turn DNC_A leak appearing
        mid-cycle made the localisation explain 0 % of a 3-cycle window).
        """
        rows = list(self.window)
        if self.episode_start is not None:
            since = [c for c in rows if c.start >= self.episode_start - 5e-4]
            if len(since) >= 3:
                since = since[1:]
            rows = since if len(since) >= 2 else rows[-2:]
        return rows[-(WINDOW // 2) :]

    # ------------------------------------------------------------ estimates
    def _decide_estimate(self, conn: Any, cycle: CompletedCycle, declared: bool) -> None:
        """Store an estimate's input with its cycle (and a declaration's alarm row).

        The declaration's alarm is recorded now, with its cycle, marked ``estimate:
        running`` until the result replaces its data; it is delivered then. The job
        starts once the cycle's transaction has committed (:meth:`_start_decided`).
        """
        if declared:
            self.episode_start = self.state.change_start
        rows = self._since_change()
        table = concatenate_rows([c.table for c in rows])
        alarm_id = None
        if declared:
            placeholder = Alarm(
                self.machine,
                cycle.start,
                "leak",
                (),
                math.nan,
                math.nan,
                math.nan,
                self.state.change_start,
                len(rows),
            )
            data = _alarm_data(placeholder) | {"estimate": "running"}
            alarm_id = self.history.add_alarm(conn, self.machine_id, cycle.start, "leak", data)
        job = EstimateJob(
            cycle.start,
            cycle.duration_s,
            declared,
            rows[0].start,
            table,
            self.state.change_start,
            alarm_id,
        )
        pending_id = self.history.add_pending_estimate(
            conn, self.machine_id, cycle.start, encode_job(job)
        )
        self._decided.append(replace(job, pending_id=pending_id))

    def _start_decided(self) -> None:
        """Start the estimates the committed cycle decided; store those already done."""
        for job in self._decided:
            self._running.append(_Running(job, self.worker.start(job)))
        self._decided.clear()
        if self.worker.concurrent:
            self.poll()

    def _store_estimate(self, running: _Running) -> None:
        """Store an estimate's result in one transaction (the monitor's memory changes
        only once it has committed), then raise its alarms."""
        job = running.job
        result = self.worker.result(job, running.future)
        tracked = {k: replace(v) for k, v in self.tracked.items()}
        pending: list[Alarm] = []
        try:
            with self.history.begin() as conn:
                data = result.to_dict()
                self.history.add_diagnosis(
                    conn, self.machine_id, job.time, job.first_cycle, job.n_cycles, data
                )
                new_locations = self._track(conn, result, job.time)
                if job.declared or new_locations:
                    pending.append(self._located(conn, result, job))
                if self.tracked:  # the deciding cycle's cost, at the sizes just found
                    self._accrue(conn, job.time, job.duration_s)
                self.history.remove_pending_estimate(conn, job.pending_id)
        except BaseException:
            self.tracked = tracked
            raise
        self.stats.diagnoses += 1
        self._raise(pending)
        self._stored_alarms += pending

    def _track(self, conn: Any, result: Diagnosis, time: float) -> list[str]:
        new = []
        for leak in result.leaks:
            location = str(leak.location)
            known = self.tracked.get(location)
            if known is None:
                leak_id = self.history.new_leak(
                    conn,
                    self.machine_id,
                    location,
                    time,
                    leak.flow_slpm,
                    leak.annual_cost,
                    leak.confidence,
                )
                self.tracked[location] = _Tracked(
                    leak_id, location, "new", leak.flow_slpm, leak.annual_cost
                )
                new.append(location)
                continue
            ratio = leak.flow_slpm / known.flow_slpm if known.flow_slpm > 0 else math.inf
            known.state = "growing" if ratio >= GROWTH_RATIO else "stable"
            known.flow_slpm, known.annual_cost = leak.flow_slpm, leak.annual_cost
            self.history.add_size(conn, known.id, time, leak.flow_slpm, leak.annual_cost)
            self.history.update_leak(
                conn,
                known.id,
                state=known.state,
                flow_slpm=float(leak.flow_slpm),
                annual_cost=float(leak.annual_cost),
                confidence=float(leak.confidence),
                last_seen=time,
            )
        return new

    # ------------------------------------------------------------ alarms
    def _repaired(self, conn: Any, cycle: CompletedCycle) -> Alarm:
        gone = list(self.tracked.values())
        for leak in gone:
            self.history.update_leak(conn, leak.id, state="repaired", repaired_at=cycle.start)
        self.tracked.clear()
        item = Alarm(
            self.machine,
            cycle.start,
            "repaired",
            tuple(t.location for t in gone),
            0.0,
            0.0,
            math.nan,
            None,
            self.state.cycles,
        )
        alarm_id = self.history.add_alarm(
            conn, self.machine_id, cycle.start, "repaired", _alarm_data(item)
        )
        return self._queue(conn, item, alarm_id)

    def _located(self, conn: Any, result: Diagnosis, job: EstimateJob) -> Alarm:
        """The alarm of a located estimate: the declaration's row filled in, or a new
        row for a location a re-estimate found."""
        leaks = tuple(
            {
                "location": str(x.location),
                "flow_slpm": _num(x.flow_slpm),
                "annual_cost": _num(x.annual_cost),
                "confidence": _num(x.confidence),
            }
            for x in result.leaks
        )
        item = Alarm(
            self.machine,
            job.time,
            "leak",
            tuple(str(x.location) for x in result.leaks) or ("unknown",),
            float(sum(x.flow_slpm for x in result.leaks)) if result.leaks else math.nan,
            float(result.total_annual_cost) if result.leaks else math.nan,
            float(min(x.confidence for x in result.leaks)) if result.leaks else math.nan,
            job.change_start,
            job.n_cycles,
            leaks,
        )
        if job.alarm_id is not None:
            self.history.update_alarm(conn, job.alarm_id, _alarm_data(item))
            return self._queue(conn, item, job.alarm_id)
        alarm_id = self.history.add_alarm(
            conn, self.machine_id, job.time, "leak", _alarm_data(item)
        )
        return self._queue(conn, item, alarm_id)

    def _queue(self, conn: Any, item: Alarm, alarm_id: int) -> Alarm:
        """Queue an alarm for every output in its transaction (the outbox)."""
        item = replace(item, id=alarm_id)
        if self.outputs:
            payload = json.dumps(item.to_dict(), allow_nan=False)
            self.history.add_outbox(conn, alarm_id, self.outputs, payload)
        return item

    def _raise(self, pending: Sequence[Alarm]) -> None:
        """After the commit: count the alarms and hand them to the outputs."""
        for item in pending:
            self.stats.alarms += 1
            if self.alarm is not None:
                self.alarm(item)


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


def _alarm_data(item: Alarm) -> dict[str, Any]:
    data = item.to_dict()
    for key in ("kind", "machine", "id"):
        data.pop(key, None)
    return data


def _due(cycles_in_alarm: int) -> bool:
    return cycles_in_alarm in REESTIMATE_AT or (
        cycles_in_alarm > REESTIMATE_AT[-1] and cycles_in_alarm % WINDOW == 0
    )
