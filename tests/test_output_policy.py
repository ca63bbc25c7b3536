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


def test_one_place_check_names_the_option_for_every_bad_place(tmp_path) -> None:
    """Issue 39 (fuzz round 3): an output whose place cannot hold it is refused at start by
    one check that names the option (the messages named only the path, or a folder of it)."""
    from pneufdd.cli.outputs import check_outputs, check_place
    from pneufdd.errors import InputError

    (tmp_path / "loop").symlink_to("loop")
    (tmp_path / "gone").symlink_to("nowhere")
    (tmp_path / "a-file").write_text("x")
    refused = {
        "x" * 300 + ".json": "File name too long",
        "loop/sub/out.json": "loop. is no folder",
        "a-file/out.json": "is a file",
    }
    for name, why in refused.items():
        with pytest.raises(InputError, match=r"^--json: received .*" + why):
            check_outputs({"--json": tmp_path / name}, {})
    for name in ("loop", "gone"):  # a folder output behind a link: never written through
        with pytest.raises(InputError, match=r"^--out: .*a link that leads nowhere or to itself"):
            check_place("--out", tmp_path / name, folder=True)
    with pytest.raises(InputError, match=r"^--out: .*this is a file"):
        check_place("--out", tmp_path / "a-file", folder=True)
    check_outputs({"--json": tmp_path / "new" / "sub" / "out.json"}, {})  # created when written
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "gone", "loop"]


def test_a_long_machine_name_and_a_missing_folder(tmp_path, capsys) -> None:
    """A 10,000-character --machine names --machine, not just 'File name too long'; an
    --out in a missing folder is created (simulate wrote nothing after its simulation)."""
    bad = ["simulate", "--machine", "x" * 10_000, "--cycles", "1", "--out", str(tmp_path / "o.pq")]
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: machine: received 'xxx")
    assert len(err) < 400
    assert "File name too long" in err
    out = tmp_path / "new" / "sub" / "o.parquet"
    assert (
        main(["simulate", "--machine", "press-fit-cell", "--cycles", "1", "--out", str(out)]) == 0
    )
    assert out.is_file()


def test_demo_refuses_an_out_on_a_link_loop_before_any_work(tmp_path, capsys) -> None:
    (tmp_path / "loop").symlink_to("loop")
    assert main(["demo", "--out", str(tmp_path / "loop")]) == 2
    assert "--out: received" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop"]
