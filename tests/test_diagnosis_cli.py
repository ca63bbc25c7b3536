"""``pneufdd reference build`` and ``pneufdd diagnose`` on simulated festo-dsd files."""

from __future__ import annotations

import json
import re

import pytest

from pneufdd.cli.app import main
from pneufdd.diagnosis.reference.file import load_reference
from pneufdd.sim import simulate

SEED = 31_000  # this file's seeds: SEED + k


def _flat(text: str) -> str:
    """The console wraps long messages anywhere, even inside paths: drop whitespace."""
    return "".join(text.split())


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli")
    paths = {}
    for name, cycles, leaks, seed in [
        ("ref1", 8, {}, 1),
        ("ref2", 8, {}, 2),
        ("short", 9, {}, 3),
        ("free", 6, {}, 4),
        ("leaky", 6, {"supply": 4}, 5),
    ]:
        rec = simulate("festo-dsd", cycles=cycles, leaks=leaks, seed=SEED + seed)
        paths[name] = rec.write(folder / f"{name}.parquet")
        if name == "free":
            other = dict(rec.metadata)
            other["machine"] = {"name": "another-machine"}
            paths["other"] = rec.with_metadata(other).write(folder / "other.parquet")
            keep = [c for c in rec.channels if c != "Q_In"]
            paths["noq"] = rec.select(keep).write(folder / "noq.parquet")
    ref = folder / "ref.pnref"
    code = main(
        [
            "reference",
            "build",
            str(paths["ref1"]),
            str(paths["ref2"]),
            "--out",
            str(ref),
            "--no-signatures",
        ]
    )
    assert code == 0
    paths["ref"] = ref
    paths["folder"] = folder
    return paths


def test_reference_build_writes_a_valid_reference(files):
    model = load_reference(files["ref"])
    assert model.machine == "festo-dsd"
    assert model.n_cycles >= 12  # 2 x 8 simulated; the first and last may be partial
    assert "Q_In" in model.channels
    assert model.sequence


@pytest.mark.parametrize(("channels", "expected"), [("P_In,Q_In", ("P_In", "Q_In")), ("none", ())])
def test_reference_channels_option(files, tmp_path, channels, expected):
    out = tmp_path / "r.pnref"
    code = main(
        [
            "reference",
            "build",
            str(files["ref1"]),
            str(files["ref2"]),
            "--out",
            str(out),
            "--channels",
            channels,
            "--no-signatures",
        ]
    )
    assert code == 0
    assert load_reference(out).channels == expected


def test_reference_of_fewer_than_ten_cycles_is_refused(files, tmp_path, capsys):
    out = tmp_path / "r.pnref"
    code = main(["reference", "build", str(files["short"]), "--out", str(out), "--no-signatures"])
    assert code == 2
    assert not out.exists()
    assert not list(tmp_path.iterdir())
    assert "referencecycles" in _flat(capsys.readouterr().err)


def test_leak_free_run_exits_zero(files, tmp_path):
    out, rep = tmp_path / "d.json", tmp_path / "d.html"
    code = main(
        [
            "diagnose",
            str(files["free"]),
            "--reference",
            str(files["ref"]),
            "--json",
            str(out),
            "--report",
            str(rep),
        ]
    )
    data = json.loads(out.read_text())
    assert code == 0
    assert data["detected"] is False
    # every simulated cycle is complete; the first follows the machine at rest
    assert data["cycles_analyzed"] == 5
    assert data["startup_cycles_excluded"] == 1
    assert data["leaks"] == []
    assert rep.read_text().startswith("<!DOCTYPE html>")


def test_leaky_run_exits_one(files, tmp_path):
    out = tmp_path / "d.json"
    code = main(
        [
            "diagnose",
            str(files["leaky"]),
            "--reference",
            str(files["ref"]),
            "--json",
            str(out),
            "--hours",
            "8000",
            "--repair-fitting",
            "55",
            "--repair-seal",
            "300",
            "--seal-share",
            "0.25",
            "--no-simulate",
        ]
    )
    data = json.loads(out.read_text())
    assert code == 1
    assert data["fit"] is None or data["fit"]["checked_by_simulation"] is False
    assert data["detected"] is True
    settings = data["cost_settings"]
    assert settings["hours"] == 8000.0
    assert (settings["repair_fitting"], settings["repair_seal"], settings["seal_share"]) == (
        55.0,
        300.0,
        0.25,
    )
    assert any("signatures" in note for note in data["notes"])  # built without them


def test_threads_option(files, tmp_path, capsys):
    out = tmp_path / "d.json"
    args = ["diagnose", str(files["leaky"]), "--reference", str(files["ref"])]
    assert main([*args, "--threads", "1", "--json", str(out)]) == 1
    assert json.loads(out.read_text())["detected"] is True
    assert main([*args, "--threads", "0"]) == 2
    assert "--threads" in _flat(capsys.readouterr().err)


@pytest.mark.parametrize(("run", "message"), [("other", "another machine"), ("noq", "Q_In")])
def test_bad_runs_fail_cleanly(files, tmp_path, capsys, run, message):
    out, rep = tmp_path / "d.json", tmp_path / "d.html"
    code = main(
        [
            "diagnose",
            str(files[run]),
            "--reference",
            str(files["ref"]),
            "--json",
            str(out),
            "--report",
            str(rep),
        ]
    )
    assert code == 2
    assert message.replace(" ", "") in _flat(capsys.readouterr().err)
    assert not list(tmp_path.iterdir())  # no partial output


def test_corrupted_reference_fails_cleanly(files, tmp_path, capsys):
    bad = tmp_path / "bad.pnref"
    bad.write_bytes(files["ref"].read_bytes()[:300])
    out = tmp_path / "d.json"
    code = main(["diagnose", str(files["free"]), "--reference", str(bad), "--json", str(out)])
    assert code == 2
    assert "bad.pnref" in _flat(capsys.readouterr().err)
    assert not out.exists()


def test_a_six_leak_table_keeps_one_line_per_leak_on_a_terminal():
    import io

    from rich.console import Console

    from _diag_synth import synth_signatures, synth_table
    from pneufdd.cli.diagnose import leak_table, repair_lines
    from pneufdd.diagnosis.engine import diagnose
    from pneufdd.diagnosis.reference.model import ReferenceModel
    from test_report_html import _six_leaks

    ref = ReferenceModel.build(synth_table(40, seed=100), signatures=synth_signatures())
    result = _six_leaks(diagnose(ref, synth_table(10, {"X_B": 1.1e-3}, seed=9)))
    out = io.StringIO()
    Console(file=out, width=120).print(leak_table(result))
    body = [line for line in out.getvalue().splitlines() if re.match(r"^\s*[1-6]\s{2,}\S", line)]
    assert len(body) == 6  # no row folds onto a second line
    assert all("+2 more" in line for line in body)  # the groups of four name two
    assert "#1" in out.getvalue()
    lines = repair_lines(result)
    assert lines[1].startswith("  1. DNC_B (fitting, tube, hose or coupling): $40")
    assert "95 % interval 1,900-2,300" in lines[-1]
    assert "more leaks may be present: up to 12 SLPM more at HMPL_H" in result.summary()
