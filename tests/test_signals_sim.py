"""Acceptance on simulated festo-dsd runs: segmentation and synchronisation (5.3.1)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("pneufdd.sim")

from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.signals import (
    align_cycles,
    ensemble,
    sample_bounds,
    segment,
    step_ensembles,
)
from simdata import damage, run

END_REASON = "step 58: awaited switch S_DNC_B did not rise before the recording ended"


def _check_100(seg, truth_starts, n_full: int) -> None:
    """100 cycles of 58 steps; starts within one 100 Hz sample of the simulator's."""
    cycles = seg.cycles[:n_full]
    assert [len(c.steps) for c in cycles] == [58] * n_full
    starts = np.array([[s.start_s for s in c.steps] for c in cycles])
    err = starts - truth_starts[:n_full]
    assert err.min() >= -1e-9
    assert err.max() <= 0.0100001
    # The simulator records the idle machine after the last cycle (RUN_END_IDLE_S),
    # so every cycle, the last one included, is verified complete.
    assert all(c.complete for c in cycles), [c.reason for c in cycles if not c.complete]


def test_58_steps_in_each_of_100_simulated_cycles() -> None:
    res = run(100)
    seg = segment(res.recording)
    assert len(seg.cycles) == 100
    _check_100(seg, res.step_start, 100)
    assert len(seg.complete) == 100
    # The learned sequence (no machine description) finds the same steps.
    learned = segment(res.recording.with_metadata({}))
    assert [c.steps[0].start_s for c in learned.cycles] == [c.start_s for c in seg.cycles]


def test_100_cycles_with_bounce_nan_gaps_and_truncated_last_cycle() -> None:
    res = run(100)
    cut = float(res.step_start[-1, 30]) + 0.05
    rec = damage(res.recording, seed=3, bounce=True, nan_fraction=0.01, truncate_s=cut)
    seg = segment(rec)
    assert len(seg.cycles) == 100
    _check_100(seg, res.step_start, 99)
    assert [c.complete for c in seg.cycles[:99]] == [True] * 99
    assert seg.cycles[-1].reason == "truncated: the recording ends after step 31 of 58"


def test_fig_5_6_raw_step_3_difference_negative_and_fig_5_7_synchronised_not() -> None:
    ref = run(10, (), seed=1).recording
    leak = run(10, (("DNC_B", 1.0),), seed=2).recording
    sref, sleak = segment(ref), segment(leak)
    rc, lc = sref.complete, sleak.complete
    raw_ref = ensemble(align_cycles(ref, "Q_In", rc)).mean
    raw_leak = ensemble(align_cycles(leak, "Q_In", lc)).mean
    s, e = sample_bounds(rc, 1000.0)
    a, b = int(np.median(s[:, 2] - s[:, 0])), int(np.median(e[:, 2] - s[:, 0]))
    raw = kg_s_to_slpm(raw_leak[a:b] - raw_ref[a:b])
    assert raw.min() < 0.0  # Fig. 5.6
    ref3 = step_ensembles(ref, "Q_In", rc)[2].mean
    leak3 = step_ensembles(leak, "Q_In", lc)[2].mean
    n = min(ref3.size, leak3.size)
    synced = kg_s_to_slpm(leak3[:n] - ref3[:n])
    assert np.nanmin(synced) > 0.0  # Fig. 5.7


@settings(max_examples=10)
@given(
    seed=st.integers(0, 10_000),
    bounce=st.booleans(),
    nan_fraction=st.sampled_from([0.0, 0.01]),
    cut_step=st.integers(1, 57),
)
def test_segmentation_property_on_simulated_data(
    seed: int, bounce: bool, nan_fraction: float, cut_step: int
) -> None:
    res = run(100)
    cut = float(res.step_start[-1, cut_step]) + 0.005
    rec = damage(res.recording, seed, bounce, nan_fraction, cut)
    seg = segment(rec)
    _check_100(seg, res.step_start, 99)
    assert [c.complete for c in seg.cycles] == [True] * 99 + [False]


def test_steps_command_on_a_simulated_parquet_file(tmp_path, capsys) -> None:
    import json

    from pneufdd.cli.app import main

    res = run(3, (("supply", 2.0),), seed=5)
    path = res.recording.write(tmp_path / "run.parquet")
    assert main(["steps", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [len(c["steps"]) for c in d["cycles"]] == [58, 58, 58]
    assert [c["complete"] for c in d["cycles"]] == [True, True, True]
    assert d["rejected"] == []
    assert d["cycles"][0]["steps"][1]["actuators"] == ["DNC", "DRQD", "HMPL_H"]


def test_steps_command_rejects_a_recording_cut_before_the_last_switch(tmp_path, capsys) -> None:
    import json

    from pneufdd.cli.app import main

    res = run(3, (("supply", 2.0),), seed=5)
    # Cut 0.1 s after the last step fired: DNC is still extending, S_DNC_B not yet on.
    cut = float(res.step_start[-1, -1]) + 0.1
    path = damage(res.recording, 0, False, 0.0, cut).write(tmp_path / "cut.parquet")
    assert main(["steps", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [len(c["steps"]) for c in d["cycles"]] == [58, 58, 58]
    assert [c["complete"] for c in d["cycles"]] == [True, True, False]
    assert d["rejected"][0]["reason"] == END_REASON
    # The unverified last step keeps the data's end as its end.
    assert d["cycles"][2]["steps"][-1]["duration_s"] == pytest.approx(0.1, abs=0.011)
