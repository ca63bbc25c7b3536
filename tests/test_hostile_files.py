"""Issue 39, third round: what an attacker or a careless user feeds pneufdd.

The corpus is ``tests/fuzzing_files.py`` (``make fuzz`` runs it through the commands);
here each defect the round found is asserted at its cause: monitor source URLs that
printed their password or exited 3, replay options that were silently ignored.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import fuzzing_files as ff
from pneufdd.errors import InputError
from pneufdd.monitor.sources import open_source

ANALOG, DIGITAL = ["P_In"], ["U_FEED_A"]


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        (f"mqtt://user:{ff.SECRET}@127.0.0.1:99999/t", "(Port out of range 0-65535)"),
        (f"mqtt://user:{ff.SECRET}@[::1/t", "(Invalid IPv6 URL)"),
        ("mqtt://127.0.0.1:abc/t", "(Port could not be cast to integer value as 'abc')"),
        (f"mqtt://:{ff.SECRET}@/t", "received 'mqtt://:***@/t'; allowed: mqtt://host:port/topic"),
        (f"opc.tcp://user:{ff.SECRET}@127.0.0.1:1/", "received 'opc.tcp://user:***@127.0.0.1:1/'"),
        (f"http://user:{ff.SECRET}@h/", "received 'http://user:***@h/'; allowed: replay:FILE"),
    ],
)
def test_source_urls_are_refused_without_their_password(url: str, shown: str) -> None:
    with pytest.raises(InputError) as caught:
        open_source(url, ANALOG, DIGITAL)
    text = str(caught.value)
    assert text.startswith("--source: received")
    assert shown in text
    assert ff.SECRET not in text


def test_opcua_messages_never_show_the_password() -> None:
    source = open_source(f"opcua://user:{ff.SECRET}@127.0.0.1:4840/", ANALOG, DIGITAL)
    assert source.shown == "opc.tcp://user:***@127.0.0.1:4840/"
    assert source.url == f"opc.tcp://user:{ff.SECRET}@127.0.0.1:4840/"  # asyncua logs in


@pytest.mark.parametrize(
    "query", ["speed=max&unknown=1", "sped=max", "speed=max&speed=1", "speed=", "?speed=max"]
)
def test_replay_options_are_never_silently_ignored(tmp_path: Path, query: str) -> None:
    run = tmp_path / "run.parquet"
    run.write_bytes(b"PAR1")
    with pytest.raises(InputError, match=r"--source replay options: received .*; allowed: "
                       r"speed=<number>\|max, chunk=<s>"):  # fmt: skip
        open_source(f"replay:{run}?{query}", ANALOG, DIGITAL)


@pytest.mark.parametrize("path", ["", ".", "/dev/zero"])
def test_a_replay_needs_a_recording_file(path: str) -> None:
    with pytest.raises(InputError, match=rf"--source replay file: received '{path}'; allowed: an "
                       "existing recording file"):  # fmt: skip
        open_source(f"replay:{path}?speed=max", ANALOG, DIGITAL)


@pytest.fixture(scope="module")
def pnref(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small reference built from a simulated run (no signatures)."""
    import fuzzing

    return fuzzing.make_base(tmp_path_factory.mktemp("hostile-base"), full=False)["pnref"]


@pytest.mark.parametrize(
    ("name", "shown"),
    [
        ("member_traversal", "entry name: received '../../evil.npy'; allowed: one <array>.npy"),
        ("member_absolute", "entry name: received '/etc/evil.npy'"),
        ("member_not_npy", "entry name: received 'readme.txt'"),
        ("member_duplicate_features", "entry name: received 'features.npy'"),
        ("member_encrypted", "entry 'features.npy': received 'encrypted'; allowed: not encrypted"),
    ],
)
def test_pnref_entries_are_only_what_numpy_writes(
    tmp_path: Path, pnref: Path, name: str, shown: str
) -> None:
    """A .pnref holds one <array>.npy per array: no path, no duplicate (zipfile reads the
    last of two alike), no encryption (zipfile's RuntimeError was exit 3)."""
    from pneufdd.diagnosis.reference.file import load_reference

    path = tmp_path / "hostile.pnref"
    path.write_bytes({n: c for n, c, _ in ff.hostile_pnrefs(pnref, full=False)}[name])
    with pytest.raises(InputError) as caught:
        load_reference(path)
    assert str(caught.value).startswith(f"reference file '{path}': ")
    assert shown in str(caught.value)
    assert load_reference(pnref).feature_names  # the whole file still loads


@pytest.mark.parametrize("name", ["bell\x07\x1b[31mred", "x\n[supply]\nhouse_psig = 1", "\x7f"])
def test_a_varied_machine_is_valid_toml_whatever_its_name(tmp_path: Path, name: str) -> None:
    """machine vary writes the source's name in its header comment: a control character
    there made the written file unreadable TOML; a line end cannot inject a table."""
    import contextlib
    import io
    import json
    import os
    import tomllib

    from pneufdd.cli.app import main
    from pneufdd.sim import load_machine
    from pneufdd.sim.variation import machine_to_toml

    source = tmp_path / "m.toml"
    original = machine_to_toml(load_machine("press-fit-cell"))
    source.write_text(original.replace('name = "press-fit-cell"', f"name = {json.dumps(name)}", 1))
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            code = main(["machine", "vary", "m.toml", "--seed", "3", "--out", "v.toml"])
    finally:
        os.chdir(here)
    assert code == 0
    text = (tmp_path / "v.toml").read_text("utf-8")
    written = tomllib.loads(text)
    assert written["machine"]["name"] == name
    header = text.split("\n\n", 1)[0].splitlines()
    assert header[0].startswith("# plant varied from ")
    assert all(line.startswith("#") for line in header)  # nothing of the name outside it
