"""Issue 39: names from files are plain text wherever printed (rich) or drawn (matplotlib).

A machine named ``cell[/]`` crashed rich (MarkupError, exit 3) in simulate, monitor and
campaign; a machine named ``$\\undefinedcmd$`` crashed matplotlib's mathtext in figures.
"""

from __future__ import annotations

import io
from importlib import resources
from pathlib import Path

import matplotlib
import pytest
from rich.console import Console

from pneufdd.cli.app import main
from pneufdd.cli.progress_bar import progress_bars
from pneufdd.report.figures import save_figure
from pneufdd.report.history_figure import history_figure
from pneufdd.report.plain_text import plain_text, printable

matplotlib.use("Agg")

PRESS_FIT = Path(str(resources.files("pneufdd.sim") / "machines" / "press-fit-cell.toml"))
PNG = b"\x89PNG\r\n"
NAMES = ["cell[/]", "[bold]x[/bold", r"$\undefinedcmd$", "a$b$c [red]"]


def _named(folder: Path, name: str) -> Path:
    text = PRESS_FIT.read_text("utf-8")
    toml_name = name.replace("\\", "\\\\")
    text = text.replace('name = "press-fit-cell"', f'name = "{toml_name}"', 1)
    path = folder / "m.toml"
    path.write_text(text, "utf-8")
    return path


def test_simulate_prints_a_markup_name_as_text(tmp_path, capsys) -> None:
    machine = _named(tmp_path, "cell[/]")
    out = tmp_path / "run.parquet"
    assert main(["simulate", "--machine", str(machine), "--cycles", "2", "--out", str(out)]) == 0
    # rich wraps long paths at the console width, also inside a word
    assert f"wrote{out}" in "".join(capsys.readouterr().err.split())
    assert out.is_file()


@pytest.mark.parametrize("name", NAMES)
def test_progress_bars_show_names_as_text(name) -> None:
    buffer = io.StringIO()
    console = Console(file=buffer, force_terminal=True, color_system=None, width=120)
    with progress_bars(console) as update:
        update(f"signatures of {name}", 1, 2)
    assert name in buffer.getvalue()  # drawn as given, without MarkupError


def _history(name: str) -> list[dict]:
    sizes = [
        {"time": "2026-03-01T06:00:00+00:00", "flow_slpm": 30.0, "annual_cost": 50.0},
        {"time": "2026-03-02T06:00:00+00:00", "flow_slpm": 35.0, "annual_cost": 60.0},
    ]
    leak = {"location": name, "state": "active", "sizes": sizes, "repaired_at": None}
    return [{"machine": name, "leaks": [leak]}]


@pytest.mark.parametrize("name", NAMES)
def test_the_history_figure_draws_any_name(tmp_path, name) -> None:
    path = history_figure(_history(name), tmp_path / "h.png")
    assert path.read_bytes().startswith(PNG)
    assert matplotlib.rcParams["text.parse_math"] is True  # restored afterwards


def test_a_figure_is_saved_over_a_link_not_through_it(tmp_path) -> None:
    database = tmp_path / "h.db"
    database.write_bytes(b"SQLite format 3\x00")
    link = tmp_path / "h.png"
    link.symlink_to(database)
    history_figure(_history("cell"), link)
    assert database.read_bytes() == b"SQLite format 3\x00"
    assert not link.is_symlink()
    assert link.read_bytes().startswith(PNG)


def test_plain_text_keeps_dollars_literal(tmp_path) -> None:
    import matplotlib.pyplot as plt

    @plain_text
    def figure(title: str):
        fig, ax = plt.subplots()
        ax.set_title(title)
        return fig

    fig = figure(r"$\undefinedcmd$")
    assert fig.axes[0].title.get_text() == r"$\undefinedcmd$"
    save_figure(fig, tmp_path / "f.png")  # drawn after the function returned: still plain
    assert (tmp_path / "f.png").read_bytes().startswith(PNG)


def test_random_markup_and_mathtext_names_are_text_everywhere(tmp_path, capsys) -> None:
    """Names drawn by the fuzz generator (rich tags, mathtext, control characters) come out
    as the same text in a progress bar, and draw in a figure; a bad --actuator is named."""
    import numpy as np

    from fuzzing_files import markup_name

    rng = np.random.default_rng(97_000_201)
    names = [markup_name(rng) for _ in range(8)]
    for name in names:
        buffer = io.StringIO()
        console = Console(file=buffer, force_terminal=True, color_system=None, width=1000)
        with progress_bars(console) as update:
            update(name, 1, 2)
        assert printable(name).strip() in buffer.getvalue()  # the same text, escapes shown
        assert "\x1b[3" not in buffer.getvalue()  # no colour a name could switch on
    path = history_figure([h for n in names for h in _history(n)], tmp_path / "h.png")
    assert path.read_bytes().startswith(PNG)
    run = tmp_path / "run.parquet"
    assert (
        main(["simulate", "--machine", "press-fit-cell", "--cycles", "1", "--out", str(run)]) == 0
    )
    capsys.readouterr()
    code = main(["features", str(run), "--actuator", "\x1b[31m", "--out", str(tmp_path / "f.csv")])
    assert code == 2
    assert "error: --actuator: received '\\x1b[31m'" in capsys.readouterr().err
