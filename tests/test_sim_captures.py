"""The twin writes field recordings: triggered captures, quantised channels (issue 33)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import InputError
from pneufdd.recording.model import Recording
from pneufdd.sim import run_simulation
from pneufdd.sim.captures import crop, cut_captures, quantize, simulate_captures

RIG = Path(__file__).parent / "data" / "triggered-rig.toml"


def test_captures_start_at_their_trigger_with_the_previous_solenoid_on() -> None:
    res = run_simulation(RIG, cycles=5, seed=1, keep_outputs=False)
    caps = cut_captures(res.recording, files=3, pre_trigger_s=0.2)
    assert len(caps) == 2  # 1 warm-up cycle, then a skipped cycle between captures
    run_starts = res.step_start[:, 0]
    for cap in caps:
        begin = cap.metadata["capture"]["start_in_run_s"]
        # the capture starts on the 10 ms digital grid at or before trigger - 0.2 s
        assert 0.2 <= cap.metadata["cycle_start_s"][0] < 0.21
        assert len(cap.metadata["cycle_start_s"]) == 2  # ends just inside the next cycle
        assert any(0.2 <= t - begin < 0.21 for t in run_starts)
        _, u_b = cap.channel("U_CYL_B")
        _, u_a = cap.channel("U_CYL_A")
        assert u_b[0] == 1
        assert u_a[0] == 0
        # samples are the run's own, cut on its grid
        _t, p = cap.channel("P_In")
        _t_run, p_run = res.recording.channel("P_In")
        k = round(begin * 1000.0)
        assert np.array_equal(p, p_run[k : k + p.size])
    spans = [
        (
            c.metadata["capture"]["start_in_run_s"],
            c.metadata["capture"]["start_in_run_s"] + c.duration,
        )
        for c in caps
    ]
    assert spans[0][1] <= spans[1][0]  # captures never overlap


def test_fixed_length_capture_ends_mid_step_and_mid_sequence_start() -> None:
    caps = simulate_captures(RIG, files=2, capture_s=1.7, seed=2)
    assert len(caps) == 2
    assert all(abs(c.duration - 1.7) < 0.011 for c in caps)
    res = run_simulation(RIG, cycles=4, seed=3, keep_outputs=False)
    mid = cut_captures(res.recording, files=1, start_in_step=1, step_start=res.step_start)
    assert mid[0].channel("U_CYL_A")[1][0] == 1  # starts in the extend step, solenoid on
    with pytest.raises(InputError, match="step starts"):
        cut_captures(res.recording, files=1, start_in_step=1)


def test_quantize_in_gauge_steps() -> None:
    rec = run_simulation(RIG, cycles=1, seed=1, keep_outputs=False).recording
    q = quantize(rec, {"P_In": 19_000.0}).channel("P_In")[1]
    steps = np.unique(np.round((q - 101_325.0) / 19_000.0, 9))
    assert np.allclose(steps, np.round(steps))
    with pytest.raises(InputError, match="Q_In"):
        quantize(rec, {"Q_In": 1.0})


def test_crop_keeps_each_rate() -> None:
    rec = run_simulation(RIG, cycles=1, seed=1, keep_outputs=False).recording
    part = crop(rec, 0.105, 0.5)
    assert part.channel("P_In")[1].size == 395
    assert part.channel("U_CYL_A")[1].size == 39


def test_cli_writes_one_file_per_capture(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "caps"
    args = ["simulate", "--machine", str(RIG), "--capture", "triggered", "--files", "3"]
    args += ["--pre-trigger-s", "0.2", "--quantize", "P_In=0.19bar", "--out", str(out)]
    assert main(args) == 0
    files = sorted(out.glob("*.parquet"))
    assert [f.name for f in files] == [f"capture_000{k}.parquet" for k in (1, 2, 3)]
    rec = Recording.read(files[0])
    assert rec.channel("U_CYL_B")[1][0] == 1
    assert main(args) == 2
    assert "overwrite" in capsys.readouterr().err
    assert main(["simulate", "--files", "3", "--out", str(tmp_path / "x")]) == 2
    assert "--capture triggered" in capsys.readouterr().err
