"""Every restart recovers (issue 32, item 3): killed anywhere in a leak's life, restarted.

A 40-cycle festo-dsd run whose supply leak appears (cycle 8) and is repaired (cycle 32)
is replayed into a SQLite history without interruption; then the monitor is killed at
every cycle boundary and at every write inside every cycle's transaction (and inside
the location and sizing runs), restarted on the same replay, and the final history
must equal the uninterrupted one: each cycle once, the same scores and CUSUM, the same
alarms, diagnoses, leak lives, size estimates and costs. The kill is an exception
raised at that point (``_Killed``, a ``BaseException`` like ``KeyboardInterrupt``): the
open transaction rolls back, as SQLite's journal discards it after a SIGKILL, and the
restart builds a new monitor on a new connection. The replay is segmented once (the
stream is deterministic: a restarted replay yields the same cycles), and location and
sizing results are memoised by their input table, so each kill point costs about a
second. Seeds: 41_000 + 20 (run), 41_000 + 21 (random kills).
"""

from __future__ import annotations

import functools
import json
import math
import random
from collections.abc import Callable, Sequence
from typing import Any

import pytest
import sqlalchemy as sa

from monitor_data import SEED, reference, started
from pneufdd.monitor import database, estimates
from pneufdd.monitor.cycles import CompletedCycle
from pneufdd.monitor.database import HistoryDatabase
from pneufdd.monitor.live import CycleOutcome, MachineMonitor, MonitorStats
from pneufdd.monitor.sources import ReplaySource
from pneufdd.monitor.stream import run_stream
from pneufdd.recording import Recording
from pneufdd.sim import simulate
from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak

CYCLES = 40
SITES = (
    "add_cycle",
    "add_alarm",
    "add_pending_estimate",
    "accrue_cost",
    "save_state",
    "add_diagnosis",
    "new_leak",
    "add_size",
    "update_leak",
    "update_alarm",
    "remove_pending_estimate",
)
"""The history's writes inside a cycle's transaction and inside the transaction that
stores an estimate's result, each a kill point."""


class _Killed(BaseException):
    """The process dies here."""


@functools.cache
def life_run() -> Recording:
    """4 turns on the supply from 100 s (cycle 8) to 470 s (repaired from cycle 32)."""
    schedule = LeakSchedule([ScheduledLeak("supply", 4.0, start_s=100.0, repair_s=470.0)])
    return started(simulate("festo-dsd", cycles=CYCLES, seed=SEED + 20, schedule=schedule))


class _Collect:
    """Stands in for the monitor to keep the replay's completed cycles."""

    def __init__(self) -> None:
        self.model = reference()
        self.stats = MonitorStats()
        self.cycles: list[CompletedCycle] = []

    busy = False

    def process(self, cycle: CompletedCycle) -> CycleOutcome:
        self.cycles.append(cycle)
        return CycleOutcome(cycle.start, math.nan, math.nan, False)

    def poll(self) -> int:
        return 0

    def settle(self) -> None:
        return None


@pytest.fixture(scope="module")
def stream() -> list[CompletedCycle]:
    source = ReplaySource(life_run(), speed=math.inf)
    collect = _Collect()
    run_stream(collect, source, source.rates_hz, source.lateness_s)  # type: ignore[arg-type]
    assert len(collect.cycles) == CYCLES
    return collect.cycles


@pytest.fixture(scope="module", autouse=True)
def memoised_diagnosis():
    """The engine is deterministic: one run per distinct window of cycles."""
    done: dict[bytes, Any] = {}
    engine = estimates.diagnose

    def diagnose(model: Any, table: Any, cost: Any, **options: Any) -> Any:
        key = table.features().tobytes() + table.durations.tobytes()
        if key not in done:
            done[key] = engine(model, table, cost, **options)
        return done[key]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(estimates, "diagnose", diagnose)
        yield


def _open(url: str) -> MachineMonitor:
    # estimates inline: the engine runs when the next new cycle needs its result, so
    # every kill point is reached in the same order in every run
    return MachineMonitor(reference(), HistoryDatabase(url), estimates="inline")


def _feed(
    url: str, cycles: Sequence[CompletedCycle], kill: Callable[[str, int], bool] | None = None
) -> list[tuple[int, str]]:
    """Run a monitor over ``cycles``; ``kill(site, k)`` True kills it there.

    Returns every (cycle, site) the run reached. Raises ``_Killed`` when killed.
    """
    monitor = _open(url)
    history = monitor.history
    reached: list[tuple[int, str]] = []
    index = 0

    def hooked(site: str, method: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            reached.append((index, site))
            if kill is not None and kill(site, index):
                raise _Killed(site)  # before the write
            result = method(*args, **kwargs)
            if kill is not None and kill(site + "+", index):
                raise _Killed(site + "+")  # after it, the transaction still open
            return result

        return call

    for site in SITES:
        setattr(history, site, hooked(site, getattr(history, site)))
    engine = estimates.diagnose

    def diagnosing(*args: Any, **options: Any) -> Any:
        reached.append((index, "diagnose"))
        if kill is not None and kill("diagnose", index):
            raise _Killed("diagnose")
        return engine(*args, **options)

    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(estimates, "diagnose", diagnosing)
            for index, cycle in enumerate(cycles):
                if kill is not None and kill("boundary", index):
                    raise _Killed("boundary")
                monitor.process(cycle)
            monitor.settle()
    finally:
        history.close()
    return reached


def _dump(url: str) -> dict[str, Any]:
    """The whole history, database ids replaced by what they stand for."""
    history = HistoryDatabase(url)
    try:
        with history.engine.connect() as conn:

            def rows(table: sa.Table, *order: Any) -> list[dict[str, Any]]:
                return [dict(r._mapping) for r in conn.execute(sa.select(table).order_by(*order))]

            leaks = rows(database.leaks, database.leaks.c.id)
            name = {x["id"]: (x["location"], x["first_seen"]) for x in leaks}
            sizes = rows(
                database.leak_sizes, database.leak_sizes.c.leak_id, database.leak_sizes.c.time
            )
            for row in [*leaks, *sizes]:
                row["leak"] = name[row.pop("id", None) or row.pop("leak_id")]
            alarms = rows(database.alarms, database.alarms.c.id)
            diagnoses = rows(database.diagnoses, database.diagnoses.c.id)
            for row in [*alarms, *diagnoses]:
                row.pop("id")
                row["data"] = json.loads(row["data"])
            state = rows(database.monitor_state, database.monitor_state.c.machine_id)
            for row in state:
                row["state"] = json.loads(row["state"])
            return {
                "cycles": rows(database.cycles, database.cycles.c.start_ms),
                "state": state,
                "alarms": alarms,
                "diagnoses": diagnoses,
                "leaks": leaks,
                "leak_sizes": sizes,
                "pending": rows(database.pending_estimates, database.pending_estimates.c.id),
                "integrity": history.integrity_ok(),
            }
    finally:
        history.close()


@pytest.fixture(scope="module")
def uninterrupted(stream, tmp_path_factory) -> dict[str, Any]:
    url = f"sqlite:///{tmp_path_factory.mktemp('restart') / 'clean.db'}"
    reached = _feed(url, stream)
    history = _dump(url)
    history["reached"] = reached
    return history


def test_the_uninterrupted_run_lives_a_whole_leak(uninterrupted):
    kinds = [a["kind"] for a in uninterrupted["alarms"]]
    assert kinds == ["leak", "repaired"]
    (leak,) = uninterrupted["leaks"]
    assert leak["location"] == "supply"
    assert leak["state"] == "repaired"
    # declared, then re-estimated 5, 10 and 20 cycles later: four size estimates
    assert len(uninterrupted["diagnoses"]) == 4
    assert len(uninterrupted["leak_sizes"]) == 4
    assert len(uninterrupted["cycles"]) == CYCLES
    assert uninterrupted["pending"] == []  # every estimate's result stored
    assert uninterrupted["integrity"]


def _points(reached: list[tuple[int, str]], index: int) -> list[tuple[str, int]]:
    """The kill points of cycle ``index``: its boundary, then before and after every write
    of its transaction and inside its location and sizing run, in the order reached."""
    points = [("boundary", index)]
    for k, site in dict.fromkeys(reached):
        if k == index:
            points += [(site, k)] if site == "diagnose" else [(site, k), (site + "+", k)]
    return points


def _killed_and_restarted(url: str, stream: list[CompletedCycle], points: list[tuple[str, int]]):
    """Kill at each point in turn (each restart on the same replay), then run to the end."""
    for point in points:
        with pytest.raises(_Killed):  # the restart reaches the point: it took the same path
            _feed(url, stream, kill=lambda site, k, p=point: (site, k) == p)
    _feed(url, stream)
    return _dump(url)


def _same(got: dict[str, Any], expected: dict[str, Any], what: object) -> None:
    for key in ("cycles", "state", "alarms", "diagnoses", "leaks", "leak_sizes", "pending"):
        assert got[key] == expected[key], (what, key)
    assert got["integrity"]


@pytest.mark.parametrize("index", range(CYCLES + 1))
def test_killed_at_a_cycle_boundary_or_inside_its_transaction_the_restart_recovers(
    index, stream, uninterrupted, tmp_path
):
    """Cycle ``index``: killed before it, then at every write of its transaction."""
    points = _points(uninterrupted["reached"], index)
    if index == CYCLES:  # after the last cycle: the replay again records nothing new
        points = []
        _feed(f"sqlite:///{tmp_path / 'h.db'}", stream)
    got = _killed_and_restarted(f"sqlite:///{tmp_path / 'h.db'}", stream, points)
    _same(got, uninterrupted, points)


def test_twenty_kills_at_random_points_of_the_leak_life(stream, uninterrupted, tmp_path):
    everything = [p for k in range(CYCLES) for p in _points(uninterrupted["reached"], k)]
    rng = random.Random(SEED + 21)
    chosen = sorted(rng.sample(range(len(everything)), 20))
    points = [everything[i] for i in chosen]
    assert len({k for _, k in points}) >= 10  # spread over the life
    got = _killed_and_restarted(f"sqlite:///{tmp_path / 'h.db'}", stream, points)
    _same(got, uninterrupted, points)


def test_cycles_missing_between_two_recorded_ones_are_stored_as_a_gap(stream, tmp_path, capsys):
    """A live source that lost cycles 4 and 5 (an outage, or a monitor killed and restarted
    on a live source): the gap, its source and the cycles lost are in the history."""
    from pneufdd.cli.app import main

    url = f"sqlite:///{tmp_path / 'h.db'}"
    monitor = MachineMonitor(reference(), HistoryDatabase(url), source="mqtt://broker:1883/x")
    outcomes = [monitor.process(c) for c in stream[:4]]
    monitor.history.close()
    assert [o.cycles_lost for o in outcomes] == [0, 0, 0, 0]
    restarted = MachineMonitor(reference(), HistoryDatabase(url), source="mqtt://broker:1883/x")
    cusum = restarted.state.up
    after = [restarted.process(c) for c in stream[6:8]]
    restarted.history.close()
    assert [o.cycles_lost for o in after] == [2, 0]
    assert after[0].gap_s == pytest.approx(stream[6].start - stream[4].start)
    assert after[0].cusum == cusum  # a start-up cycle: the data before it is lost
    assert main(["history", "--history", url, "--json"]) == 0
    (entry,) = json.loads(capsys.readouterr().out)["machines"]
    (gap,) = entry["gaps"]
    assert gap["source"] == "mqtt://broker:1883/x"
    assert gap["cycles_lost"] == 2
    assert entry["cycles"]["count"] == 6
    assert main(["history", "--history", url]) == 0
    assert "1 gaps (2 cycles lost)" in capsys.readouterr().out
