"""Outputs of a command (pneufdd/cli/outputs.py): never an input, never shared, atomic."""

from __future__ import annotations

import os

import pytest

from pneufdd.cli.app import main
from pneufdd.cli.outputs import check_outputs
from pneufdd.errors import FileExistsInputError, InputError
from pneufdd.files import write_text_atomic


def test_links_to_an_input_are_the_input(tmp_path) -> None:
    run = tmp_path / "run.parquet"
    run.write_bytes(b"PAR1 data")
    (tmp_path / "soft.json").symlink_to(run)
    os.link(run, tmp_path / "hard.json")
    for name in ("soft.json", "hard.json", "./sub/../run.parquet"):
        (tmp_path / "sub").mkdir(exist_ok=True)
        with pytest.raises(InputError, match="it is RUN"):
            check_outputs({"--json": tmp_path / name}, {"RUN": run}, overwrite=True)
    assert run.read_bytes() == b"PAR1 data"


def test_outputs_may_not_share_a_path_or_be_a_folder(tmp_path) -> None:
    with pytest.raises(InputError, match=r"--report.*--json writes there"):
        check_outputs({"--json": tmp_path / "a", "--report": tmp_path / "b/../a"}, {})
    with pytest.raises(InputError, match="folder"):
        check_outputs({"--out": tmp_path}, {}, overwrite=True)
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="is a file"):
        check_outputs({"--out": tmp_path / "file" / "x.json"}, {})
    with pytest.raises(FileExistsInputError, match="--overwrite"):
        check_outputs({"--out": tmp_path / "file"}, {})
    check_outputs({"--out": tmp_path / "file"}, {}, overwrite=True)  # allowed


def test_atomic_write_keeps_the_old_file_on_error(tmp_path, monkeypatch) -> None:
    target = tmp_path / "report.html"
    target.write_text("old")

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="No space"):
        write_text_atomic(target, "new")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_diagnose_refuses_to_write_over_its_inputs(tmp_path, capsys) -> None:
    run, ref = tmp_path / "run.parquet", tmp_path / "ref.pnref"
    run.write_bytes(b"recording")
    ref.write_bytes(b"reference")
    for extra in (
        ["--json", str(run)],
        ["--json", str(run), "--overwrite"],
        ["--report", str(ref), "--overwrite"],
        ["--json", str(tmp_path / "x"), "--report", str(tmp_path / "x")],
    ):
        assert main(["diagnose", str(run), "--reference", str(ref), *extra]) == 2
        err = " ".join(capsys.readouterr().err.split())
        assert "error:" in err
        assert extra[0] in err or "--report" in err
    assert run.read_bytes() == b"recording"
    assert ref.read_bytes() == b"reference"
    assert not (tmp_path / "x").exists()
