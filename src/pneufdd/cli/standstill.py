"""``pneufdd standstill ...``: plan a standstill leak test and analyse its recordings."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd.cli.exit_codes import ExitCode
from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption
from pneufdd.errors import InputError, describe, naming

if TYPE_CHECKING:
    from pneufdd.standstill.plan import StandstillPlan

__all__ = ["register"]

standstill_app = typer.Typer(
    help="A standstill leak test planned by the twin: its PLC sequence, and its analysis.",
    no_args_is_help=True,
)

PLAN_FILES = ("plan.json", "standstill.st", "standstill.csv", "standstill.md")
"""What ``standstill plan`` writes into its folder."""


def _say(text: str) -> None:
    from rich.console import Console

    Console(stderr=True).print(text, highlight=False, markup=False, soft_wrap=True)


@standstill_app.command("plan")
def plan(
    machine: Annotated[
        str, typer.Option("--machine", help="Built-in machine name or a description (TOML).")
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Folder for plan.json, standstill.st, .csv and .md (without: the table "
            "is printed, nothing is written).",
        ),
    ] = None,
    mode: Annotated[
        str,
        typer.Option(
            help="flow (a supply flow meter), decay (supply pressure, shut-off valve "
            "closed) or auto (flow when the description has a supply flow meter)."
        ),
    ] = "auto",
    settle: Annotated[
        float, typer.Option("--settle", help="Hold before measuring [s] (1-600).")
    ] = 5.0,
    window: Annotated[
        float, typer.Option("--window", help="Measurement window [s] (1-600).")
    ] = 5.0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace existing files in OUT.")
    ] = False,
) -> None:
    """Plan the standstill leak test of MACHINE and write its PLC sequence into --out.

    The states hold every actuator at each end (a 5/3 closed-centre valve also in its
    centre); the plan says which lines they separate. Method: docs/standstill.md.
    """
    from pneufdd.files import write_text_atomic
    from pneufdd.sim import load_machine
    from pneufdd.standstill import plan_standstill
    from pneufdd.standstill.program import state_table, structured_text

    if mode not in ("auto", "flow", "decay"):
        raise InputError(describe("--mode", mode, ["auto", "flow", "decay"]))
    for option, value in (("--settle", settle), ("--window", window)):
        if not 1.0 <= value <= 600.0:  # NaN too
            raise InputError(describe(option, value, "1 to 600 [s]"))
    if out is not None:
        if out.exists() and not out.is_dir():
            raise InputError(describe("--out", str(out), "a folder (or a path to create one)"))
        targets = {f"--out {name}": out / name for name in PLAN_FILES}
        check_outputs(targets, {"--machine": Path(machine)}, overwrite)
    description = load_machine(machine)
    planned = plan_standstill(description, mode=mode, settle_s=settle, window_s=window)
    csv_text, md_text = state_table(planned)
    if out is None:
        typer.echo(md_text, nl=False)
    else:
        out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out / "plan.json", planned.to_json() + "\n")
        write_text_atomic(out / "standstill.st", structured_text(planned))
        write_text_atomic(out / "standstill.csv", csv_text)
        write_text_atomic(out / "standstill.md", md_text)
        _say(
            f"wrote {out}: {len(planned.states)} states ({planned.mode} mode), "
            f"{', '.join(PLAN_FILES)}"
        )
    for note in planned.notes:
        _say(note)
    if planned.pairs_not_separable:
        pairs = ", ".join(f"{a}+{b}" for a, b in planned.pairs_not_separable)
        _say(f"pairs of leaks it cannot tell apart: {pairs}")


def _read_plan(folder: Path) -> StandstillPlan:
    """The plan of ``standstill plan``: a folder holding plan.json, or the file itself
    (at most 4 MiB, JSON nested at most 64 levels: docs/limits.md)."""
    from pneufdd.cli.plan_files import read_plan_json
    from pneufdd.standstill.plan import StandstillPlan

    path, data = read_plan_json(folder, "standstill plan")
    return StandstillPlan.from_dict(data, str(path))


@standstill_app.command("analyse")
def analyse(
    recordings: Annotated[
        list[Path], typer.Argument(help="Recordings of the standstill test (any order).")
    ],
    plan_folder: Annotated[
        Path, typer.Option("--plan", help="The folder (or plan.json) of standstill plan.")
    ],
    tag_map: MapOption = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the result as JSON.")
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing --json file.")
    ] = False,
) -> None:
    """Each line's leak from RECORDINGS of a standstill test, with its uncertainty.

    Exit 1 when a leak is found, 0 when none. Method: docs/standstill.md.
    """
    from pneufdd.cli.recordings import read_recordings
    from pneufdd.files import write_text_atomic
    from pneufdd.standstill.analyse import measure_states
    from pneufdd.standstill.estimate import estimate_leaks

    inputs: dict[str, Path | None] = {f"RECORDINGS[{k}]": p for k, p in enumerate(recordings)}
    plan_file = plan_folder / "plan.json" if plan_folder.is_dir() else plan_folder
    check_outputs(
        {"--json": json_out}, {**inputs, "--map": tag_map, "--plan": plan_file}, overwrite
    )
    planned = _read_plan(plan_folder)
    recs = read_recordings(recordings, tag_map)
    try:
        rows = measure_states(recs, planned)
    except InputError as exc:
        raise naming(exc, ", ".join(str(p) for p in recordings)) from exc
    result = estimate_leaks(planned, rows)
    for line in result.lines_text():
        _say(line)
    if json_out is not None:
        write_text_atomic(json_out, json.dumps(result.to_dict(), indent=1) + "\n")
    if result.leak_found:
        raise typer.Exit(ExitCode.LEAK_FOUND)


def register(app: typer.Typer) -> None:
    """Attach the ``standstill`` command group to ``app``."""
    app.add_typer(standstill_app, name="standstill")
