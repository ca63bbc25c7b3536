"""Issue 39, item 1: no command writes over its inputs, through a link, or outside --out."""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

import pytest

from pneufdd.cli.app import main
from pneufdd.files import safe_name, write_text_atomic

PRESS_FIT = Path(str(resources.files("pneufdd.sim") / "machines" / "press-fit-cell.toml"))

# the smallest campaign that writes every kind of file (about 5 s)
TINY = [
    "--plants", "1", "--sizes", "1", "--leak-free-runs", "0", "--pairs", "0",
    "--run-cycles", "1", "--reference-cycles", "10", "--reference-recordings", "1",
    "--uncertainty-plants", "0", "--workers", "1", "--sensor-sets", "supply-only",
]  # fmt: skip


def _named(folder: Path, name: str) -> Path:
    """press-fit-cell's description under another machine name."""
    text = PRESS_FIT.read_text("utf-8").replace('name = "press-fit-cell"', f"name = {name!r}", 1)
    assert f"name = {name!r}" in text
    path = folder / "m.toml"
    path.write_text(text, "utf-8")
    return path


def _files(folder: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("name", ["../../victim", "/abs/victim", "..", "a\\b/../../c"])
def test_safe_name_never_leaves_the_folder(tmp_path, name) -> None:
    part = safe_name(name)
    assert "/" not in part
    assert "\\" not in part
    assert not part.startswith(".")
    assert (tmp_path / part).resolve().parent == tmp_path.resolve()
    assert safe_name("press-fit-cell") == "press-fit-cell"


@pytest.mark.parametrize("name", ["../../victim", "/tmp/pneufdd-victim-{}"])
def test_campaign_writes_only_inside_out_whatever_the_machine_name(tmp_path, name) -> None:
    name = name.format(os.getpid())
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    machine = _named(work, name)
    before = _files(tmp_path)
    out = work / "c2"
    assert main(["campaign", "--machine", str(machine), "--out", str(out), *TINY]) == 0
    after = _files(tmp_path)
    assert {p: after[p] for p in before} == before  # the input untouched, byte for byte
    assert all(out in p.parents for p in set(after) - set(before))
    assert sorted(p.name for p in (out / "plants").iterdir()) == [f"{safe_name(name)}-s1-p1.toml"]
    assert not Path(name).exists()


def test_campaign_refuses_a_machine_file_it_would_overwrite(tmp_path, capsys) -> None:
    out = tmp_path / "c3"
    (out / "plants").mkdir(parents=True)
    machine = out / "plants" / "press-fit-cell-s1-p1.toml"  # the first plant's own name
    machine.write_bytes(PRESS_FIT.read_bytes())
    assert main(["campaign", "--machine", str(machine), "--out", str(out), *TINY]) == 2
    err = capsys.readouterr().err
    assert "plants/press-fit-cell-s1-p1.toml" in err
    assert "it is --machine" in err
    assert machine.read_bytes() == PRESS_FIT.read_bytes()
    assert sorted(p.name for p in out.rglob("*")) == ["plants", "press-fit-cell-s1-p1.toml"]


@pytest.mark.parametrize("overwrite", [True, False])
def test_the_atomic_writer_replaces_a_link_never_writes_through_it(tmp_path, overwrite) -> None:
    victim = tmp_path / "h.db"
    victim.write_bytes(b"SQLite format 3\x00 database")
    link = tmp_path / "h.png"
    link.symlink_to(victim)
    if overwrite:
        write_text_atomic(link, "figure", overwrite=True)
        assert not link.is_symlink()
        assert link.read_text() == "figure"
    else:
        with pytest.raises(FileExistsError):
            write_text_atomic(link, "figure", overwrite=False)
        assert link.is_symlink()
    assert victim.read_bytes() == b"SQLite format 3\x00 database"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.db", "h.png"]


def test_vector_map_refuses_a_machine_file_it_would_overwrite(tmp_path, capsys) -> None:
    out = tmp_path / "vm"
    out.mkdir()
    machine = out / "sign_table.png"  # a TOML under the name of one of its outputs
    machine.write_bytes(PRESS_FIT.read_bytes())
    assert main(["vector-map", "--out", str(out), "--machine", str(machine)]) == 2
    assert "it is --machine" in capsys.readouterr().err
    assert machine.read_bytes() == PRESS_FIT.read_bytes()
    assert sorted(p.name for p in out.iterdir()) == ["sign_table.png"]


@pytest.mark.parametrize("target", ["elsewhere/missing.toml", "loop.toml"])
def test_an_output_on_a_link_that_leads_nowhere_needs_overwrite(tmp_path, target) -> None:
    """A dangling link, or one to itself, is there (path.exists() says not): replacing it
    needs --overwrite, as for a file (machine draft replaced it unasked, exit 0)."""
    from pneufdd.cli.outputs import check_outputs
    from pneufdd.errors import FileExistsInputError

    link = tmp_path / "loop.toml"
    os.symlink(target, link)
    with pytest.raises(FileExistsInputError, match=r"--out: received '.*loop\.toml'; allowed: a "
                       r"new file \(or pass --overwrite to replace it\)"):  # fmt: skip
        check_outputs({"--out": link}, {}, overwrite=False)
    check_outputs({"--out": link}, {}, overwrite=True)
    write_text_atomic(link, "x = 1\n", overwrite=True)  # the link replaced, nothing behind it
    assert not link.is_symlink()
    assert link.read_text() == "x = 1\n"
    assert not (tmp_path / "elsewhere").exists()
