"""Triggered captures pooled, honest references (issue 33, items 2 and 5), from the CLI."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from pneufdd.cli.app import main
from pneufdd.diagnosis.captures import SESSION_GAP_S
from pneufdd.diagnosis.reference.file import load_reference
from pneufdd.diagnosis.reference.honesty import clopper_pearson, reference_honesty
from pneufdd.sim import as_exported
from pneufdd.sim.captures import quantize, simulate_captures

RIG = Path(__file__).parent / "data" / "triggered-rig.toml"


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 reference captures and 4 run captures of the rig, P_In quantised, as exported."""
    root = tmp_path_factory.mktemp("rig")
    for folder, files, seed in (("ref", 12, 1), ("run", 4, 2)):
        (root / folder).mkdir()
        caps = simulate_captures(RIG, files=files, pre_trigger_s=0.2, capture_s=2.6, seed=seed)
        for k, cap in enumerate(caps):
            quantize(as_exported(cap), {"P_In": 19_000.0}).write(
                root / folder / f"c{k:02d}.parquet"
            )
    return root


def test_reference_from_a_folder_of_one_cycle_captures(
    rig: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ref = rig / "rig.pnref"
    code = main(
        [
            "reference",
            "build",
            str(rig / "ref"),
            "--machine",
            str(RIG),
            "--no-signatures",
            "--out",
            str(ref),
        ]
    )
    err = " ".join(capsys.readouterr().err.split())
    assert code == 0, err
    assert "12 leak-free cycles" in err
    assert "12 of 12 recording(s) start at a cycle start" in err
    assert "P_In is quantised in steps of 1.9e+04 Pa" in err
    # one acquisition: one session, and the report says what that leaves unmeasured
    assert "0 of 12 independent cycles in 12 recording(s) of 1 session(s); 95 % " in err
    assert "interval 0.00-26.46 %" in err
    assert "captures come from 1 session(s)" in err
    assert "this one has 12 in 12" in err
    model = load_reference(ref)
    assert model.settings.quantum("P_In") == pytest.approx(19_000.0)
    assert model.detector.scale_[model.feature_names.index("P_In.min@1")] >= 19_000.0
    honesty = reference_honesty(model)
    assert honesty.cycles == 12
    assert honesty.recordings == 12
    assert honesty.sessions == 1
    # pooled diagnosis of held-out healthy captures; and a single capture on its own
    out = rig / "pooled.json"
    code = main(["diagnose", str(rig / "run"), "--pool", "--reference", str(ref)])
    code = main(
        [
            "diagnose",
            str(rig / "run" / "*.parquet"),
            "--pool",
            "--reference",
            str(ref),
            "--json",
            str(out),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    assert json.loads(out.read_text())["cycles_analyzed"] == 4
    one = str(rig / "run" / "c00.parquet")
    assert main(["diagnose", one, "--reference", str(ref)]) == 0
    assert "(1 cycles;" in " ".join(capsys.readouterr().out.split())
    assert main(["diagnose", one, "--reference", str(ref), "--startup-cycles", "1"]) == 2
    assert "--pool" in " ".join(capsys.readouterr().err.split())


def test_machine_draft_from_one_cycle_captures(
    rig: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files = [str(p) for p in sorted((rig / "ref").glob("*.parquet"))[:3]]
    out = rig / "draft.toml"
    assert main(["machine", "draft", *files, "--out", str(out)]) == 0, capsys.readouterr().err
    text = out.read_text()
    assert 'do = [{ set = "U_CYL_A" }, { reset = "U_CYL_B" }]' in text


def test_duplicated_captures_are_refused(rig: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dup = rig / "dup"
    shutil.copytree(rig / "ref", dup)
    shutil.copy(dup / "c00.parquet", dup / "c99.parquet")
    code = main(
        [
            "reference",
            "build",
            str(dup),
            "--machine",
            str(RIG),
            "--no-signatures",
            "--out",
            str(rig / "dup.pnref"),
        ]
    )
    assert code == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "c99.parquet has the same samples as" in err
    assert "c00.parquet" in err


def test_steps_with_the_machine_shows_a_one_cycle_capture(
    rig: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    one = str(rig / "ref" / "c03.parquet")
    assert main(["steps", one]) == 2  # one cycle: nothing to learn a sequence from
    assert "repeating pattern" in capsys.readouterr().err
    assert main(["steps", one, "--machine", str(RIG), "--json"]) == 0
    found = json.loads(capsys.readouterr().out)
    assert [c["complete"] for c in found["cycles"]] == [True]
    assert found["cycles"][0]["steps"][0]["start_s"] == pytest.approx(0.2, abs=0.011)


def test_clopper_pearson_matches_the_closed_form() -> None:
    # k = 0: the upper bound solves (1 - p)^n = alpha / 2
    n = 30
    assert clopper_pearson(0, n)[1] == pytest.approx(1 - 0.025 ** (1 / n))
    # k = n: the lower bound solves p^n = alpha / 2
    assert clopper_pearson(n, n)[0] == pytest.approx(0.025 ** (1 / n))


def test_captures_of_three_sessions_are_left_out_by_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Captures of three acquisitions (each simulation starts at the epoch again): three
    sessions, the cross-validation leaves one out at a time and the file keeps them."""
    folder = tmp_path / "ref"
    folder.mkdir()
    for session in range(3):
        caps = simulate_captures(RIG, files=4, pre_trigger_s=0.2, capture_s=2.6, seed=10 + session)
        pause = (caps[1].start_time - caps[0].start_time).total_seconds() - caps[0].duration
        assert 0.0 <= pause <= SESSION_GAP_S  # one acquisition
        for k, cap in enumerate(caps):
            as_exported(cap).write(folder / f"s{session}c{k}.parquet")
    ref = tmp_path / "rig.pnref"
    args = ["reference", "build", str(folder), "--machine", str(RIG), "--no-signatures"]
    assert main([*args, "--out", str(ref)]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "of 12 independent cycles in 12 recording(s) of 3 session(s)" in err
    assert "come from" not in err  # three sessions: no warning
    model = load_reference(ref)
    assert model.recording_session == (0,) * 4 + (1,) * 4 + (2,) * 4
    assert model.cycle_session is not None
    assert model.cycle_session.tolist() == [0] * 4 + [1] * 4 + [2] * 4
    det = model.detector
    assert det.grouped_cv_
    assert 0.0 <= det.recording_correlation_ <= 1.0
    assert reference_honesty(model).sessions == 3
