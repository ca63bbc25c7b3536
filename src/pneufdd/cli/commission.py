"""``pneufdd commission ...``: commissioning with a test leak (plan, then apply)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd.cli.exit_codes import ExitCode
from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption
from pneufdd.errors import InputError, describe, naming

if TYPE_CHECKING:
    from pneufdd.diagnosis.commission_plan import CommissioningPlan
    from pneufdd.diagnosis.commissioning import CommissioningResult

__all__ = ["register"]

commission_app = typer.Typer(
    help="Commissioning with a test leak: the procedure, then the corrected reference.",
    no_args_is_help=True,
)

PLAN_FILES = ("plan.json", "commissioning.md")
"""What ``commission plan`` writes into its folder."""


def _say(text: str) -> None:
    from rich.console import Console

    Console(stderr=True).print(text, highlight=False, markup=False, soft_wrap=True)


@commission_app.command("plan")
def plan(
    reference: Annotated[Path, typer.Option("--reference", help="The reference (.pnref).")],
    ports: Annotated[
        str | None,
        typer.Option(
            "--ports", help="Comma-separated locations to visit, in order (default: all)."
        ),
    ] = None,
    orifice_mm: Annotated[
        float | None,
        typer.Option("--orifice-mm", help="Test nozzle diameter [mm] (default 1.0)."),
    ] = None,
    turns: Annotated[
        float | None,
        typer.Option("--turns", help="Test leak valve (GR-3/8B) opened this many turns (0-6)."),
    ] = None,
    second_orifice_mm: Annotated[
        float | None,
        typer.Option(
            "--second-orifice-mm",
            help="A second, larger test nozzle [mm] at every port: the correction is "
            "measured at two sizes (docs/commissioning.md).",
        ),
    ] = None,
    second_turns: Annotated[
        float | None,
        typer.Option("--second-turns", help="A second, larger opening of the GR-3/8B (0-6)."),
    ] = None,
    cycles: Annotated[
        int, typer.Option("--cycles", min=1, max=10_000, help="Cycles to record at each port.")
    ] = 20,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Folder for plan.json and commissioning.md (without: the procedure is "
            "printed, nothing is written).",
        ),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace existing files in OUT.")
    ] = False,
) -> None:
    """Plan the commissioning of REFERENCE: a known test orifice at each port in turn.

    Method: docs/commissioning.md.
    """
    from pneufdd.diagnosis.commission_plan import plan_commissioning
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.files import write_text_atomic

    orifice = _orifice(orifice_mm, turns, "") or "1.0mm"
    second = _orifice(second_orifice_mm, second_turns, "second-")
    if out is not None:
        if out.exists() and not out.is_dir():
            raise InputError(describe("--out", str(out), "a folder (or a path to create one)"))
        targets = {f"--out {name}": out / name for name in PLAN_FILES}
        check_outputs(targets, {"--reference": reference}, overwrite)
    model = load_reference(reference)
    chosen = None if ports is None else [p.strip() for p in ports.split(",") if p.strip()]
    planned = plan_commissioning(model, chosen, orifice, cycles, second)
    if out is None:
        typer.echo(planned.markdown(), nl=False)
        return
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "plan.json", json.dumps(planned.to_dict(), indent=1) + "\n")
    write_text_atomic(out / "commissioning.md", planned.markdown())
    _say(f"wrote {out}: {len(planned.ports)} ports, {', '.join(PLAN_FILES)}")


def _orifice(mm: float | None, turns: float | None, prefix: str) -> str | None:
    """``--[second-]orifice-mm`` or ``--[second-]turns`` checked, as ``"1.0mm"``/``"2turns"``."""
    if mm is not None and turns is not None:
        raise InputError(describe(f"--{prefix}orifice-mm and --{prefix}turns", "both", "one"))
    if mm is not None and not (math.isfinite(mm) and 0.1 <= mm <= 20):
        raise InputError(describe(f"--{prefix}orifice-mm", mm, "a nozzle of 0.1 to 20 mm"))
    if turns is not None and not (math.isfinite(turns) and 0 < turns <= 6):
        raise InputError(
            describe(f"--{prefix}turns", turns, "more than 0, at most 6 turns (GR-3/8B)")
        )
    if turns is not None:
        return f"{turns}turns"
    return None if mm is None else f"{mm}mm"


def _read_plan(folder: Path) -> CommissioningPlan:
    """The plan of ``commission plan``: its folder or its plan.json (at most 4 MiB)."""
    from pneufdd.cli.plan_files import read_plan_json
    from pneufdd.diagnosis.commission_plan import CommissioningPlan

    path, data = read_plan_json(folder, "commission plan")
    return CommissioningPlan.from_dict(data, f"--plan {path}")


def _runs(recordings: list[Path], run: list[str], ports: list[str]) -> dict[str, Path]:
    """Test -> file: ``--run PORT=FILE``, or a RECORDING named for its test.

    A test is named by its port (``DNC_B.parquet``), with a second orifice by its port
    and ``@2`` (``DNC_B@2.parquet``).
    """
    out: dict[str, Path] = {}

    def add(port: str, path: Path, where: str) -> None:
        if port not in ports:
            raise InputError(describe(f"port of {where}", port, list(ports)))
        if port in out:
            raise InputError(describe(f"port {port} of {where}", "given twice", "once"))
        out[port] = path

    for item in run:
        port, sep, file = item.partition("=")
        if not sep or not port.strip() or not file.strip():
            raise InputError(
                describe("--run", item, "PORT=FILE (e.g. DNC_B=DNC_B.parquet, DNC_B@2=...)")
            )
        add(port.strip(), Path(file.strip()), f"--run {item}")
    for path in recordings:
        port = path.name.split(".")[0]
        add(port, path, f"RECORDING {path} (its file name names the port)")
    if not out:
        raise InputError(describe("recordings", 0, "at least one (--run PORT=FILE or RECORDING)"))
    return out


def _table(result: CommissioningResult) -> None:
    from rich.console import Console
    from rich.table import Table

    from pneufdd.physics.units import kg_s_to_slpm

    def slpm(x: float) -> str:
        return "-" if x != x else f"{float(kg_s_to_slpm(x)):.1f}"

    table = Table(title=f"commissioning of {result.reference.machine}")
    for name in (
        "port",
        "orifice",
        "status",
        "test SLPM",
        "before SLPM",
        "after SLPM",
        "measured/twin",
        "explained twin / corr.",
    ):
        table.add_column(name)
    for p in result.ports:
        fit = p.fit
        table.add_row(
            p.port,
            p.orifice,
            p.status,
            slpm(p.test_size),
            slpm(p.size_before),
            slpm(p.size_after),
            "-" if fit is None else f"{fit.overall_gain:.2f}",
            "-" if fit is None else f"{fit.explained_twin:.0%} / {fit.explained_corrected:.0%}",
        )
    Console(stderr=True).print(table)


@commission_app.command("apply")
def apply(
    reference: Annotated[
        Path, typer.Option("--reference", help="The reference the plan was made for.")
    ],
    plan_folder: Annotated[
        Path, typer.Option("--plan", help="The folder (or plan.json) of commission plan.")
    ],
    recordings: Annotated[
        list[Path] | None,
        typer.Argument(
            help="Test-leak recordings, each named for its port (DNC_B.parquet; "
            "the second orifice DNC_B@2.parquet)."
        ),
    ] = None,
    run: Annotated[
        list[str] | None,
        typer.Option(
            "--run", help="PORT=FILE: the recording with the orifice at PORT (PORT@2: the second)."
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", help="The corrected reference (.pnref) to write.")
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the report as JSON.")
    ] = None,
    figure: Annotated[
        Path | None,
        typer.Option("--figure", help="PNG of the twin's against the measured effect per port."),
    ] = None,
    tag_map: MapOption = None,
    threads: Annotated[
        int, typer.Option("--threads", min=1, max=64, help="Threads for the check by simulation.")
    ] = 1,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace existing output files.")
    ] = False,
) -> None:
    """Correct REFERENCE's leak model per port from the test-leak recordings.

    Writes a NEW reference (--out; never the input). A recording whose leak is seen
    elsewhere is refused (named) and its port stays uncorrected; exit 1 then, 0 when
    every recording was used. Method: docs/commissioning.md.
    """
    from pneufdd.cli.recordings import read_recording
    from pneufdd.diagnosis.commissioning import commission
    from pneufdd.diagnosis.reference.file import load_reference, save_reference
    from pneufdd.files import write_text_atomic
    from pneufdd.parallel import positive_count

    if out is None:
        raise InputError(describe("--out", None, "a new .pnref file for the corrected reference"))
    if out.suffix != ".pnref":
        raise InputError(describe("--out", str(out), "a file ending in .pnref"))
    if figure is not None and figure.suffix.lower() != ".png":
        raise InputError(describe("--figure", str(figure), "a file ending in .png"))
    positive_count(threads, "--threads")
    plan_file = plan_folder / "plan.json" if plan_folder.is_dir() else plan_folder
    planned = _read_plan(plan_folder)
    files = _runs(list(recordings or []), list(run or []), [t.key for t in planned.tests()])
    inputs: dict[str, Path | None] = {f"--run {p}": f for p, f in files.items()}
    inputs |= {"--reference": reference, "--plan": plan_file, "--map": tag_map}
    check_outputs({"--out": out, "--json": json_out, "--figure": figure}, inputs, overwrite)
    model = load_reference(reference)
    runs = {}
    for port, path in files.items():
        try:
            runs[port] = (str(path), read_recording(path, tag_map))
        except InputError as exc:
            raise naming(exc, str(path)) from exc
    result = commission(model, planned, runs, threads=threads)
    save_reference(result.reference, out, overwrite=overwrite)
    _table(result)
    if json_out is not None:
        write_text_atomic(json_out, json.dumps(result.to_dict(), indent=1) + "\n")
    if figure is not None:
        from pneufdd.report.commissioning import commissioning_figure

        commissioning_figure(result, figure)
    refused = [p for p in result.ports if p.status == "refused"]
    for p in refused:
        _say(f"refused: {p.reason}; {p.port} stays uncorrected")
    _say(f"wrote {out}; uncorrected locations: {', '.join(result.uncorrected) or 'none'}")
    if refused:
        raise typer.Exit(ExitCode.LEAK_FOUND)


def register(app: typer.Typer) -> None:
    """Attach the ``commission`` command group to ``app``."""
    app.add_typer(commission_app, name="commission")
