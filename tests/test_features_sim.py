"""Acceptance on simulated festo-dsd runs: stroke times and the signs of Table 4.5."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pneufdd.sim")

from pneufdd.features import TABLE_4_5, TABLE_44_NAMES, feature_matrix
from simdata import run

# Where the simulator's physics moves a Table 4.4 feature against Table 4.5 (both
# leak sizes 0 -> 4 turns); the reasons are in docs/signals.md. Keys: (leak class,
# feature number 1..13) -> the simulator's sign.
SIM_DISAGREES = {
    ("extend", 5): "-",
    ("extend", 9): "-",
    ("extend", 10): "-",
    ("retract", 2): "-",
    ("retract", 8): "+",
    ("retract", 11): "-",
    ("supply", 6): "-",
    ("supply", 8): "-",
}
LOCATION = {"extend": "DNC_A", "retract": "DNC_B", "supply": "supply"}


def _stroke_errors(leaks, seed) -> np.ndarray:
    """Estimated minus true stroke time [s] of every DNC stroke of every complete cycle."""
    res = run(20, leaks, seed)
    df = feature_matrix(res.recording, groups=["motion"])
    # The simulator records the idle machine after the last cycle: all 20 are complete.
    assert len(df) == 20, df.attrs["rejected"]
    truth = {(s.cycle, s.direction): s.duration for s in res.strokes if s.actuator == "DNC"}
    cycles = df.index.get_level_values("cycle") - 1
    errors = []
    for motion, direction in (("extend", 1), ("retract", -1)):
        true = np.array([truth[(c, direction)] for c in cycles])
        errors.append(df[f"DNC.t_s_{motion}_s"].to_numpy() - true)
    return np.concatenate(errors)


# The seeds below are not those the estimator was developed on (exploration: seeds
# 100-109, 20 cycles each, leak-free and 4-turn DNC_A, DNC_B, supply leaks; the
# figures are in docs/signals.md).


def test_stroke_times_against_the_simulator_ground_truth() -> None:
    # Target: within 10 ms of the simulator's stroke time (start of sustained travel
    # to end stop). LVDT noise (1.2 mm at 1 kHz) limits the start estimate; on the
    # 400 exploration strokes 99.5 % are within 10 ms, median 2.0 ms, 95th
    # percentile 6.2 ms, worst 12.8 ms.
    err = np.abs(np.concatenate([_stroke_errors((), 1), _stroke_errors((), 11)]))
    assert err.size == 4 * 20
    assert np.median(err) < 0.004
    assert np.percentile(err, 95) < 0.009
    assert np.mean(err < 0.010) >= 0.97
    assert err.max() < 0.016


def test_stroke_times_with_leaks() -> None:
    # With 4-turn leaks the acceleration builds up more slowly and the start estimate
    # scatters more; on the 1200 exploration strokes >= 98.8 % per condition are
    # within 10 ms, 95th percentile <= 7.8 ms, worst 15.0 ms.
    err = np.abs(
        np.concatenate(
            [
                _stroke_errors((("DNC_B", 4.0),), 2),
                _stroke_errors((("DNC_A", 4.0), ("supply", 2.0)), 3),
                _stroke_errors((("supply", 4.0),), 4),
            ]
        )
    )
    assert err.size == 3 * 2 * 20
    assert np.median(err) < 0.005
    assert np.percentile(err, 95) < 0.010
    assert np.mean(err < 0.010) >= 0.95
    assert err.max() < 0.020


@pytest.fixture(scope="module")
def signs() -> dict[str, str]:
    """Sign of each Table 4.4 feature's change from no leak to a 4-turn leak."""
    runs = [run(15, (), 1, both=True).recording]
    for k, cls in enumerate(("extend", "retract", "supply")):
        runs.append(run(15, ((LOCATION[cls], 4.0),), 2 + k, both=True).recording)
    df = feature_matrix(runs, groups=["table44"])
    cols = [f"DNC.{n}" for n in TABLE_44_NAMES]
    by = df.groupby(level="recording")[cols]
    mean, std, count = by.mean(), by.std(), by.count()
    out = {}
    for k, cls in enumerate(("extend", "retract", "supply"), start=1):
        s = ""
        for c in cols:
            delta = mean.loc[k, c] - mean.loc[0, c]
            noise = np.hypot(std.loc[k, c], std.loc[0, c]) / np.sqrt(count.loc[0, c])
            s += "0" if abs(delta) < 3 * noise else ("+" if delta > 0 else "-")
        out[cls] = s
    return out


@pytest.mark.parametrize("cls", ["extend", "retract", "supply"])
def test_table_4_5_signs(signs: dict[str, str], cls: str) -> None:
    table, sim = TABLE_4_5[cls], signs[cls]
    for j, (expected, got) in enumerate(zip(table, sim, strict=True), start=1):
        if expected == "0":
            continue  # "no correlation or uncertain": nothing to check
        assert got == SIM_DISAGREES.get((cls, j), expected), (cls, j, table, sim)


@pytest.mark.parametrize(("leaks", "seed"), [((), 1), ((("DNC_B", 4.0),), 2)])
def test_last_cycle_final_step_is_comparable(leaks, seed) -> None:
    # The recording runs on 0.3 s after the last cycle (RUN_END_IDLE_S); the last
    # step of the data ends when its awaited switch is on plus the step's median gap
    # in the other cycles, so its duration and air equal the other cycles' within
    # their scatter (ending it with the data added 0.3 s and ~0.09 SL).
    from pneufdd.signals import segment

    rec = run(20, leaks, seed).recording
    seg = segment(rec)
    assert len(seg.complete) == 20
    duration = np.array([c.steps[57].duration_s for c in seg.complete])
    assert seg.complete[-1].end_s < rec.duration - 0.2
    # durations come from 100 Hz edges: one digital sample of tolerance
    assert duration[:-1].min() - 0.0101 <= duration[-1] <= duration[:-1].max() + 0.0101
    df = feature_matrix(rec, groups=["air"])
    for col in ("step58.air_SL", "DNC.air_extend_SL"):
        v = df[col].to_numpy()
        others = v[:-1]
        assert abs(v[-1] - np.median(others)) <= 3.0 * others.std(), (col, v[-1], others)
