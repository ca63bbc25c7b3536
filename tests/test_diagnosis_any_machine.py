"""Any machine a user can describe: the description travels with the reference.

A copy of festo-dsd under another name, the two other built-in machines, recordings
without a description (a DAQ export) and recordings of another machine than the
description given.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pneufdd.cli.app import main
from pneufdd.diagnosis.reference.file import load_reference
from pneufdd.recording import Recording
from pneufdd.sim import as_exported, simulate

SEED = 33_000  # this file's seeds: SEED + k
FESTO = Path(__file__).resolve().parents[1] / "src/pneufdd/sim/machines/festo-dsd.toml"
FAST = [
    "--channels",
    "P_In,Q_In",
    "--signature-sizes",
    "30,120",
    "--signature-cycles",
    "1",
    "--uncertainty-plants",
    "1",
]


def _flat(text: str) -> str:
    return "".join(text.split())


def _without_description(recording: Recording) -> Recording:
    """As a DAQ export: no machine metadata at all."""
    meta = {k: v for k, v in recording.metadata.items() if k != "machine"}
    return recording.with_metadata(meta)


@pytest.fixture(scope="module")
def my_rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("my-rig")
    toml = folder / "my-rig.toml"
    toml.write_text(FESTO.read_text("utf-8").replace('name = "festo-dsd"', 'name = "my-rig"'))
    paths = {"toml": toml, "folder": folder}
    for name, cycles, leaks, seed in [
        ("ref1", 7, {}, 1),
        ("ref2", 7, {}, 2),
        ("run", 8, {"DNC_B": "120slpm"}, 3),
    ]:
        rec = simulate(toml, cycles=cycles, leaks=leaks, seed=SEED + seed)
        paths[name] = rec.write(folder / f"{name}.parquet")
        paths[f"{name}-bare"] = _without_description(rec).write(folder / f"{name}-bare.parquet")
    return paths


def test_renamed_machine_gets_signatures_and_is_diagnosed(my_rig, capsys):
    ref = my_rig["folder"] / "ref.pnref"
    code = main(
        ["reference", "build", str(my_rig["ref1"]), str(my_rig["ref2"]), "--out", str(ref), *FAST]
    )
    assert code == 0
    assert "signatures:19locations" in _flat(capsys.readouterr().err)
    model = load_reference(ref)
    assert model.machine == "my-rig"
    assert model.description is not None
    assert model.description.name == "my-rig"
    assert model.signatures is not None
    assert model.signatures.n_plants == 1
    out = my_rig["folder"] / "d.json"
    code = main(["diagnose", str(my_rig["run"]), "--reference", str(ref), "--json", str(out)])
    data = json.loads(out.read_text())
    assert code == 1
    assert [leak["location"] for leak in data["leaks"]] == ["DNC_B"]
    assert data["leaks"][0]["flow_slpm"] == pytest.approx(120.0, rel=0.25)


def test_recordings_without_description_need_the_machine(my_rig, capsys):
    bare = [str(my_rig["ref1-bare"]), str(my_rig["ref2-bare"])]
    out = my_rig["folder"] / "bare.pnref"
    # no name, no description: the user must say which machine this is
    assert main(["reference", "build", *bare, "--out", str(out), *FAST]) == 2
    assert "--machine" in _flat(capsys.readouterr().err)
    assert not out.exists()
    code = main(["reference", "build", *bare, "--out", str(out), "--machine", str(my_rig["toml"])])
    assert code == 0
    model = load_reference(out)
    assert model.machine == "my-rig"
    assert model.signatures is not None
    assert len(model.signatures.locations) == 19
    run = my_rig["folder"] / "d2.json"
    code = main(["diagnose", str(my_rig["run-bare"]), "--reference", str(out), "--json", str(run)])
    assert code == 1
    assert [leak["location"] for leak in json.loads(run.read_text())["leaks"]] == ["DNC_B"]


def test_description_of_another_machine_is_refused(my_rig, tmp_path, capsys):
    out = tmp_path / "x.pnref"
    bare = [str(my_rig["ref1-bare"]), str(my_rig["ref2-bare"])]
    code = main(["reference", "build", *bare, "--out", str(out), "--machine", "press-fit-cell"])
    assert code == 2
    err = _flat(capsys.readouterr().err)
    assert "ref1-bare.parquet" in err  # the file
    assert "U_PRESS_A" in err  # a channel the description has and the recording lacks
    assert not out.exists()
    # a recording named after another machine than the description given
    named = [str(my_rig["ref1"]), str(my_rig["ref2"])]
    assert main(["reference", "build", *named, "--out", str(out), "--machine", "festo-dsd"]) == 2
    assert "my-rig" in _flat(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("machine", "location", "channels"),
    [
        ("press-fit-cell", "EJECT_B", None),
        ("press-fit-cell", "supply", "P_In,Q_In"),
        ("carton-sorter", "PUSH_L_A", None),
        ("carton-sorter", "GATE_B", None),
    ],
)
def test_built_in_industrial_machines_from_the_command_line(
    machine, location, channels, tmp_path, capsys
):
    paths = []
    for k in (1, 2):  # 6 running cycles each (the first follows the machine at rest)
        rec = as_exported(simulate(machine, cycles=8, seed=SEED + 10 + k))
        paths.append(str(rec.write(tmp_path / f"free{k}.parquet")))
    leaky = simulate(machine, cycles=12, leaks={location: "60slpm"}, seed=SEED + 13)
    run = as_exported(leaky).write(tmp_path / "run.parquet")
    free = as_exported(simulate(machine, cycles=12, seed=SEED + 14)).write(
        tmp_path / "free.parquet"
    )
    ref = tmp_path / "ref.pnref"
    options = ["--machine", machine, "--uncertainty-plants", "1"]
    options += [] if channels is None else ["--channels", channels]
    assert main(["reference", "build", *paths, "--out", str(ref), *options]) == 0
    assert "signatures:" in capsys.readouterr().err
    out = tmp_path / "d.json"
    assert main(["diagnose", str(run), "--reference", str(ref), "--json", str(out)]) == 1
    data = json.loads(out.read_text())
    assert [leak["location"] for leak in data["leaks"]] == [location]
    assert data["leaks"][0]["flow_slpm"] == pytest.approx(60.0, rel=0.25)
    assert main(["diagnose", str(free), "--reference", str(ref)]) == 0
