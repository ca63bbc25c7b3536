"""Command-line conventions (issue 32, item 6): flags read naturally, ``history`` draws
only when asked, and never onto its own database."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import typer

from pneufdd.cli.app import app, main
from pneufdd.monitor.database import HistoryDatabase


def _options():
    def walk(command, name):
        for sub_name, sub in getattr(command, "commands", {}).items():
            yield from walk(sub, f"{name} {sub_name}")
        for param in command.params:  # typer's own click: options have secondary_opts
            if hasattr(param, "secondary_opts"):
                yield name, param

    yield from walk(typer.main.get_command(app), "pneufdd")


def test_boolean_flags_read_naturally():
    flags = [(name, p) for name, p in _options() if getattr(p, "is_flag", False)]
    assert len(flags) > 15
    for name, param in flags:
        for opt in [*param.opts, *param.secondary_opts]:
            assert not opt.startswith("--no-no-"), (name, opt)
        if param.default is False:  # a switch that is off unless given: no --no-X twin
            assert param.secondary_opts == [], (name, param.opts, param.secondary_opts)
    names = {(n, o) for n, p in flags for o in p.opts}
    assert ("pneufdd monitor", "--once") in names
    assert ("pneufdd history", "--overwrite") in names


@pytest.fixture
def history(tmp_path):
    db = tmp_path / "h.db"
    h = HistoryDatabase(f"sqlite:///{db}")
    m = h.machine_id("festo-dsd")
    with h.begin() as conn:
        h.add_cycle(conn, m, 1.77e9, 14.8, 0.5, 0.0, 0.01, 6e5)
    h.close()
    return db


def _intact(db: Path) -> bool:
    h = HistoryDatabase(f"sqlite:///{db}")
    try:
        return h.integrity_ok() and h.cycle_count(h.machine_id("festo-dsd")) == 1
    finally:
        h.close()


def test_history_draws_only_when_asked(history, tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    url = f"sqlite:///{history}"
    assert main(["history", "--history", url, "--json"]) == 0
    assert main(["history", "--history", url, "--json"]) == 0
    assert main(["history", "--history", url]) == 0
    assert list(work.iterdir()) == []
    figure = tmp_path / "trend.png"
    assert main(["history", "--history", url, "--figure", str(figure)]) == 0
    assert figure.stat().st_size > 1000
    assert main(["history", "--history", url, "--figure", str(figure)]) == 2  # exists
    assert main(["history", "--history", url, "--figure", str(figure), "--overwrite"]) == 0


def test_history_never_draws_onto_its_database(history, tmp_path, capsys):
    url = f"sqlite:///{history}"
    link = tmp_path / "link.png"
    link.symlink_to(history)
    hard = tmp_path / "hard.png"
    os.link(history, hard)
    for target in (history, link, hard):
        code = main(["history", "--history", url, "--figure", str(target), "--overwrite"])
        assert code == 2, target
        assert "--figure" in capsys.readouterr().err
    # the database named like a figure, and the figure the same file
    png = tmp_path / "h.png"
    history.rename(png)
    code = main(["history", "--history", f"sqlite:///{png}", "--figure", str(png), "--overwrite"])
    assert code == 2
    assert "--history" in capsys.readouterr().err
    assert _intact(png)
