"""Leak schedules in the twin: appear at a time, grow, are repaired; ground truth stored."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import InputError
from pneufdd.recording import Recording
from pneufdd.sim import simulate
from pneufdd.sim.schedule import LeakSchedule, ScheduledLeak, schedule_from_options

SEED = 41_500  # this file's seeds: SEED + k


def _cycle_air(rec: Recording) -> np.ndarray:
    """Mean supply flow of every cycle [kg/s]."""
    t, q = rec.channel("Q_In")
    starts = [*rec.metadata["cycle_start_s"], rec.duration]
    return np.array([q[(t >= a) & (t < b)].mean() for a, b in itertools.pairwise(starts)])


def test_a_leak_takes_effect_in_the_first_cycle_starting_after_it_appears_until_repaired():
    schedule = LeakSchedule(
        [ScheduledLeak("supply", 3.0, start_s=20.0, growth_per_s=0.02, repair_s=50.0)]
    )
    rec = simulate("festo-dsd", cycles=5, seed=SEED, schedule=schedule)
    starts = rec.metadata["cycle_start_s"]
    timeline = rec.metadata["leak_timeline"]
    leaky = [row["cycle"] for row in timeline]
    expected = [i for i, t in enumerate(starts) if 20.0 <= t < 50.0]
    assert leaky == expected == [2, 3]  # cycles start at ~0, 14.8, 29.6, 44.3, 59.1 s
    # growth: size = 3 + 0.02 (t - 20) at each cycle's start
    for row in timeline:
        assert row["size"] == pytest.approx(3.0 + 0.02 * (row["cycle_start_s"] - 20.0))
    assert timeline[1]["slpm"] > timeline[0]["slpm"]
    assert rec.metadata["leak_schedule"][0]["repair_s"] == 50.0
    air = _cycle_air(rec)
    free = simulate("festo-dsd", cycles=5, seed=SEED)
    base = _cycle_air(free)
    extra = air - base
    # the leak adds supply flow only in the scheduled cycles; the first and last are clean
    assert abs(extra[0]) < 1e-6
    assert abs(extra[1]) < 1e-6
    assert extra[2] > 2e-4
    assert extra[3] > extra[2]
    assert abs(extra[4]) < 0.1 * extra[2]


def test_schedule_validation_names_the_problem():
    with pytest.raises(InputError, match="repair time"):
        ScheduledLeak("supply", 1.0, start_s=10.0, repair_s=5.0)
    with pytest.raises(InputError, match="twice"):
        LeakSchedule([ScheduledLeak("supply", 1.0), ScheduledLeak("supply", 2.0)])
    with pytest.raises(InputError, match="both constant and scheduled"):
        simulate(
            "festo-dsd",
            cycles=1,
            leaks={"supply": 1},
            schedule=LeakSchedule([ScheduledLeak("supply", 1.0, start_s=5.0)]),
        )
    with pytest.raises(InputError, match="leak-growth"):
        schedule_from_options([], ["DNC_B=1/min"], [])


def test_simulate_command_with_a_schedule(tmp_path):
    out = tmp_path / "run.parquet"
    code = main(
        [
            "simulate",
            "--cycles",
            "3",
            "--seed",
            str(SEED + 1),
            "--leak",
            "DNC_B=2@10s",
            "--leak-growth",
            "DNC_B=0.6/min",
            "--leak-repair",
            "DNC_B@40s",
            "--leak",
            "supply=1",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    meta = Recording.read(out).metadata
    assert meta["leak_schedule"][0]["growth_per_s"] == pytest.approx(0.01)
    assert [row["cycle"] for row in meta["leak_timeline"]] == [1, 2]
    assert meta["leaks"][0]["location"] == "supply"
    assert main(["simulate", "--leak", "DNC_B=2@soon", "--out", str(tmp_path / "x.parquet")]) == 2
