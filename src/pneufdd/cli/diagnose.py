"""``pneufdd diagnose``: detect, locate, size and cost leaks in a run.

Exit codes (see :mod:`pneufdd.cli.exit_codes`): 0 no leak, 1 leak or other fault found
(any finding: a detected run), 2 bad input
(another machine, missing channels, an invalid reference...). Output files are
rendered completely before anything is written, then written atomically, so an
error never leaves a partial file behind.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd.cli.cost_options import HoursOption, JsonOption, KwOption, PriceOption, ReportOption
from pneufdd.cli.exit_codes import ExitCode
from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption, read_recording
from pneufdd.errors import InputError, describe
from pneufdd.files import write_text_atomic

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from pneufdd.diagnosis.cost import CostSettings
    from pneufdd.diagnosis.findings import Diagnosis
    from pneufdd.diagnosis.localisation.search import LocalisationSettings
    from pneufdd.diagnosis.reference.model import ReferenceModel
    from pneufdd.features.step_table import StepTable

__all__ = ["leak_table", "register"]


def leak_table(result: Diagnosis, title: str = "Leaks, largest annual cost first") -> Table:
    """A rich table of the diagnosis' leaks."""
    from rich.markup import escape
    from rich.table import Table

    from pneufdd.diagnosis.cost import COST_BASIS_AVERAGE

    table = Table(title=title)
    for name in (
        "#",
        "location",
        "ambiguity group",
        "flow [SLPM]",
        "avg flow [SLPM]",
        "orifice \\[mm]",  # escaped: rich reads [mm] as markup
        "cost [$/yr]",
        "confidence",
    ):
        table.add_column(
            name,
            justify="left" if name in ("location", "ambiguity group") else "right",
            overflow="fold",  # a narrow terminal wraps text instead of cutting it
        )
    for i, leak in enumerate(result.leaks, start=1):
        table.add_row(
            str(i),
            escape(str(leak.location)),  # names from the machine file are plain text
            escape(", ".join(str(x) for x in leak.ambiguity_group)),
            f"{leak.flow_slpm:.1f}",
            f"{leak.average_flow_slpm:.1f}",
            f"{leak.orifice_mm:.2f}",
            f"{leak.annual_cost:,.0f}",
            f"{100 * leak.confidence:.0f} %",
        )
    table.add_section()
    table.add_row("", "total", "", "", "", "", f"{result.total_annual_cost:,.0f}", "")
    table.caption = (
        "flow: while the leak's line is pressurised, at supply pressure (what a leak "
        "detector finds); avg flow: mean over the operating cycle; cost: eq. 1.1 of the "
        "avg flow x operating hours"
    )
    if any(leak.cost_basis != COST_BASIS_AVERAGE for leak in result.leaks):
        table.caption += " (continuous leakage assumed where no average flow is known)"
    return table


def diagnose(
    runs: Annotated[
        list[Path],
        typer.Argument(
            metavar="RUN...",
            help="Recording to diagnose (.parquet); several, a folder or a glob pattern "
            "diagnose a batch: one JSON line per run.",
        ),
    ],
    reference: Annotated[Path, typer.Option("--reference", help="Reference file (.pnref).")],
    json_out: JsonOption = None,
    report: ReportOption = None,
    hours: HoursOption = 7000.0,
    price: PriceOption = 0.05,
    kw_per_100cfm: KwOption = 18.0,
    max_leaks: Annotated[
        int | None,
        typer.Option(help="Most simultaneous leaks considered, 1 or 2 (default: the reference's)."),
    ] = None,
    simulate: Annotated[
        bool | None,
        typer.Option(
            "--simulate/--no-simulate",
            help="When the leak signatures do not explain the run (typically two large "
            "leaks), check the best explanations with the digital twin (a few seconds "
            "more). Default: the reference's setting.",
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(min=1, help="Batch: processes of the local Dask cluster (default: CPUs)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Batch: run on an existing Dask cluster (tcp://host:8786)."),
    ] = None,
    threads: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="Threads of the check by simulation (default: every core; in a batch on "
            "a Dask cluster, one per worker).",
        ),
    ] = None,
    tag_map: MapOption = None,
    overwrite: Annotated[
        bool,
        typer.Option(
            "--overwrite", help="Replace existing --json/--report files (never an input)."
        ),
    ] = False,
    pool: Annotated[
        bool,
        typer.Option(
            "--pool",
            help="The RUNs (files, a folder or a glob) are short captures of one run: pool "
            "their cycles and judge them together (one result), instead of a batch.",
        ),
    ] = False,
    startup_cycles: Annotated[
        int | None,
        typer.Option(
            min=0,
            max=10,
            help="Complete cycles left out at the start of each recording (default: the "
            "reference's; 0 for a capture detected as starting at a cycle start).",
        ),
    ] = None,
) -> None:
    """Diagnose RUN against a leak-free reference: exit 0 no finding, 1 leak or other fault
    found, 2 error."""
    from dataclasses import replace

    from rich.console import Console

    from pneufdd.diagnosis.cost import CostSettings
    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.limits import MAX_WORKERS, check_count

    inputs: dict[str, Path | None] = {"--reference": reference, "--map": tag_map}
    inputs.update({"RUN" if len(runs) == 1 else f"RUN {i + 1}": p for i, p in enumerate(runs)})
    check_outputs({"--json": json_out, "--report": report}, inputs, overwrite=overwrite)
    if max_leaks is not None and max_leaks not in (1, 2):
        raise InputError(describe("--max-leaks", max_leaks, [1, 2]))
    for option, count in (("--workers", workers), ("--threads", threads)):
        if count is not None:
            check_count(option, count, MAX_WORKERS, low=1)
    console = Console()
    settings = CostSettings(hours=hours, price_per_kwh=price, kw_per_100_cfm=kw_per_100cfm)
    from pneufdd.cli.diagnose_batch import is_batch, run_batch

    runs = _pooled_runs(runs, pool, tag_map, startup_cycles)
    if not pool and is_batch(runs):
        args = (json_out, report, settings, max_leaks, simulate, workers, scheduler, threads)
        raise typer.Exit(run_batch(runs, reference, *args))
    run = runs[0] if len(runs) == 1 else Path(f"{len(runs)} pooled captures from {runs[0].parent}")
    model = load_reference(reference)
    localisation = model.localisation
    if max_leaks is not None:
        localisation = replace(localisation, max_leaks=max_leaks)
    if simulate is not None:
        localisation = replace(localisation, simulate_explanations=simulate)
    table, result = _diagnosed(
        model, runs, pool, tag_map, settings, localisation, threads, startup_cycles
    )
    # render everything first, write afterwards: no partial output on error
    outputs: list[tuple[Path, str]] = []
    if json_out is not None:
        data = result.to_dict()
        data.update({"run": str(run), "reference": str(reference), "machine": model.machine})
        outputs.append((json_out, json.dumps(data, indent=2, allow_nan=False) + "\n"))
    if report is not None:
        from pneufdd.recording.parquet import recording_start_time
        from pneufdd.report.html import render_report  # matplotlib: only for --report

        when = recording_start_time(runs[0]) if len(runs) == 1 and tag_map is None else None
        html = render_report(model, table, result, run_name=str(run), run_time=when)
        outputs.append((report, html))
    for path, text in outputs:
        write_text_atomic(path, text)
    _print_result(console, run, result)
    if result.detected:
        raise typer.Exit(ExitCode.LEAK_FOUND)


def _print_result(console: Console, run: Path, result: Diagnosis) -> None:
    """The verdict, data gaps, leak table, supply check and notes of one diagnosis."""
    from rich.markup import escape

    from pneufdd.physics.units import kg_s_to_slpm

    verdict = "[bold red]leak detected[/]" if result.detected else "[bold green]no leak[/]"
    others = [f for f in result.findings if f.fault_type != "leak"]
    if others:
        verdict = "[bold red]fault detected[/]" + (" and leak" if result.leaks else "")
    console.print(
        f"{escape(str(run))}: {verdict} ({result.cycles_analyzed} cycles"
        + (f" after {result.startup_cycles} start-up" if result.startup_cycles else "")
        + "; run statistic "
        f"{result.run_score:.3g} vs threshold {result.run_threshold:.3g})",
        highlight=False,
    )
    if result.cycles_skipped or result.gaps_repaired:
        channels = sorted({channel for _, channel in result.cycles_skipped})
        console.print(
            f"data gaps: {len(result.cycles_skipped)} cycle(s) skipped"
            + (f" (gaps longer than 0.05 s in {', '.join(channels)})" if channels else "")
            + f", {result.gaps_repaired} short gap(s) interpolated (docs/data-quality.md)",
            highlight=False,
            markup=False,
        )
    if result.leaks:
        console.print(leak_table(result))
    for finding in result.findings:
        console.print(
            f"finding: {finding.fault_type}: {finding.describe()}; confidence "
            f"{100 * finding.confidence:.0f} %"
            + (f"; {finding.consequence()}" if finding.consequence() else ""),
            highlight=False,
            markup=False,
        )
    if result.supply is not None and (result.detected or result.supply.verdict != "no leak"):
        supply = result.supply
        console.print(
            f"supply check (eq. 4.21): {supply.verdict} in "
            f"{supply.cycles.get(supply.verdict, 0)} of {result.cycles_analyzed} cycles; "
            f"supply flow {kg_s_to_slpm(supply.flow_change):+.1f} SLPM, pressure "
            f"{supply.pressure_change / 1e5:+.3f} bar against the reference",
            highlight=False,
            markup=False,
        )
    if result.sensor_set is not None and (result.detected or result.sensor_set.kind != "full"):
        console.print(
            f"sensor set {result.sensor_set.kind}: it cannot {result.sensor_set.cannot} "
            "(docs/sensor-sets.md)",
            highlight=False,
            markup=False,
        )
    for note in result.notes:
        console.print(f"note: {note}", highlight=False, markup=False)


def _diagnosed(
    model: ReferenceModel,
    runs: list[Path],
    pool: bool,
    tag_map: Path | None,
    settings: CostSettings,
    localisation: LocalisationSettings,
    threads: int | None,
    startup_cycles: int | None,
) -> tuple[StepTable, Diagnosis]:
    """One run, or ``--pool``'s captures pooled, diagnosed with progress bars."""
    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.diagnosis.recordings import diagnose_pooled, diagnose_recording

    with progress_bars() as progress:
        if pool:
            return diagnose_pooled(
                model,
                list(runs),
                settings,
                progress,
                localisation,
                threads,
                startup_cycles,
                tag_map,
            )
        source = runs[0] if tag_map is None else read_recording(runs[0], tag_map)
        return diagnose_recording(
            model, source, settings, progress, localisation, threads, startup_cycles
        )


def _pooled_runs(
    runs: list[Path], pool: bool, tag_map: Path | None, startup_cycles: int | None
) -> list[Path]:
    """The runs of ``--pool`` expanded (files, folders, globs); a batch's checks."""
    from pneufdd.cli.diagnose_batch import is_batch

    if pool:
        from pneufdd.diagnosis.batch import expand_runs

        return expand_runs(runs)
    if is_batch(runs):
        if startup_cycles is not None:
            raise InputError(
                describe("--startup-cycles with a batch", startup_cycles, "one run or --pool")
            )
        if tag_map is not None:
            raise InputError(
                describe("--map with several runs", str(tag_map), "one run (import them first)")
            )
    return runs


def register(app: typer.Typer) -> None:
    """Attach the ``diagnose`` command to ``app``."""
    app.command("diagnose")(diagnose)
