"""``pneufdd diagnose``: detect, locate, size and cost leaks in a run.

Exit codes (see :mod:`pneufdd.cli.exit_codes`): 0 no leak, 1 leak or other fault found
(any finding: a detected run), 2 bad input
(another machine, missing channels, an invalid reference...). Output files are
rendered completely before anything is written, then written atomically, so an
error never leaves a partial file behind.
"""

from __future__ import annotations

import json
import math
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
    from pneufdd.diagnosis.findings import Diagnosis, LeakFinding
    from pneufdd.diagnosis.localisation.search import LocalisationSettings
    from pneufdd.diagnosis.reference.model import ReferenceModel
    from pneufdd.features.step_table import StepTable

__all__ = ["leak_table", "register", "repair_lines"]


GROUP_SHOWN = 2
"""Ambiguity-group members a console row names before "+N more" (the JSON has all)."""


def _group_text(leak: LeakFinding) -> str:
    names = [str(x) for x in leak.ambiguity_group]
    if len(names) > GROUP_SHOWN:
        return ", ".join(names[:GROUP_SHOWN]) + f" +{len(names) - GROUP_SHOWN} more"
    return ", ".join(names)


def _interval_text(low: float, high: float) -> str:
    from pneufdd.physics.units import kg_s_to_slpm

    if not (math.isfinite(low) and math.isfinite(high)):
        return "n/a"
    return f"{float(kg_s_to_slpm(low)):.1f}-{float(kg_s_to_slpm(high)):.1f}"


def leak_table(result: Diagnosis, title: str = "Leaks, largest annual cost first") -> Table:
    """A rich table of the diagnosis' leaks, their totals and the repair order.

    Each row names at most :data:`GROUP_SHOWN` members of its ambiguity group, so a
    table of many leaks keeps one line per leak on a normal terminal.
    """
    from rich import box
    from rich.markup import escape
    from rich.table import Table

    from pneufdd.diagnosis.cost import COST_BASIS_AVERAGE
    from pneufdd.physics.units import kg_s_to_slpm

    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    columns = (
        ("#", "right"),
        ("location", "left"),
        ("ambiguity group", "left"),
        ("flow (95 %)", "right"),
        ("avg", "right"),
        ("orifice", "right"),
        ("$/yr", "right"),
        ("conf.", "right"),
        ("repair", "right"),
    )
    for name, justify in columns:
        # text columns wrap on a narrow terminal instead of cutting; numbers stay whole
        wrap = name in ("location", "ambiguity group")
        table.add_column(
            name,
            justify=justify,  # type: ignore[arg-type]
            overflow="fold" if wrap else "ellipsis",
            no_wrap=not wrap,
            min_width=18 if name == "ambiguity group" else None,
        )
    rank = {index: place for place, index in enumerate(result.repair_order, start=1)}
    for i, leak in enumerate(result.leaks, start=1):
        table.add_row(
            str(i),
            escape(str(leak.location)),  # names from the machine file are plain text
            escape(_group_text(leak)),
            f"{leak.flow_slpm:.1f} ({_interval_text(*leak.mass_flow_interval)})",
            f"{leak.average_flow_slpm:.1f}",
            f"{leak.orifice_mm:.2f}",
            f"{leak.annual_cost:,.0f}",
            f"{100 * leak.confidence:.0f} %",
            f"#{rank[i - 1]}" if i - 1 in rank else "",
        )
    table.add_section()
    totals = result.totals
    table.add_row(
        "",
        "total",
        "",
        ""
        if totals is None
        else f"{float(kg_s_to_slpm(totals.mass_flow)):.1f} "
        f"({_interval_text(*totals.mass_flow_interval)})",
        "" if totals is None else f"{float(kg_s_to_slpm(totals.average_mass_flow)):.1f}",
        "",
        f"{result.total_annual_cost:,.0f}",
        "",
        "",
    )
    table.caption = (
        "flow [SLPM]: while the leak's line is pressurised, at supply pressure (what a leak "
        "detector finds), its 95 % interval from the fit (the total's from the leaks' "
        "joint covariance); avg [SLPM]: mean over the operating cycle; orifice \\[mm]: "
        "equivalent sharp-edged orifice; $/yr: eq. 1.1 of the avg flow x operating hours; "
        "conf.: confidence that a leak lies in the group; repair: order by annual cost per "
        "repair cost"
    )
    if any(leak.cost_basis != COST_BASIS_AVERAGE for leak in result.leaks):
        table.caption += " (continuous leakage assumed where no average flow is known)"
    return table


def repair_lines(result: Diagnosis) -> list[str]:
    """The repair order as plain lines: what to repair first, its cost and payback."""
    if not result.repair_order:
        return []
    out = ["repair order (most saved per repair dollar first):"]
    for place, i in enumerate(result.repair_order, start=1):
        leak = result.leaks[i]
        payback = leak.payback_days
        pays = "never pays back" if not math.isfinite(payback) else f"pays back in {payback:.0f} d"
        out.append(
            f"  {place}. {leak.location} ({leak.repair_kind}): ${leak.repair_cost:,.0f}, saves "
            f"${leak.annual_cost:,.0f}/yr, {pays}"
        )
    if result.totals is not None:
        low, high = result.totals.annual_cost_interval
        out.append(
            f"total ${result.totals.annual_cost:,.0f}/yr (95 % interval {low:,.0f}-{high:,.0f})"
        )
    return out


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
    repair_fitting: Annotated[
        float,
        typer.Option(help="Repair cost of a leaking fitting, tube, hose or coupling [$]."),
    ] = 40.0,
    repair_seal: Annotated[
        float, typer.Option(help="Repair cost of resealing an actuator [$].")
    ] = 250.0,
    seal_share: Annotated[
        float,
        typer.Option(
            help="Share of the leaks on a line whose actuator's seal vents to the "
            "atmosphere (rod side, rodless band) that are that seal (docs/assumptions.md)."
        ),
    ] = 0.5,
    max_leaks: Annotated[
        int | None,
        typer.Option(
            help="Most simultaneous leaks considered, 1 to 32 (default: the reference's; "
            "references built since issue 38: as many as the evidence supports).",
        ),
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
    from pneufdd.limits import MAX_LEAKS, MAX_WORKERS, check_count

    inputs: dict[str, Path | None] = {"--reference": reference, "--map": tag_map}
    inputs.update({"RUN" if len(runs) == 1 else f"RUN {i + 1}": p for i, p in enumerate(runs)})
    check_outputs({"--json": json_out, "--report": report}, inputs, overwrite=overwrite)
    if max_leaks is not None:
        check_count("--max-leaks", max_leaks, MAX_LEAKS, low=1)
    for option, count in (("--workers", workers), ("--threads", threads)):
        if count is not None:
            check_count(option, count, MAX_WORKERS, low=1)
    console = Console()
    settings = CostSettings(
        hours=hours,
        price_per_kwh=price,
        kw_per_100_cfm=kw_per_100cfm,
        repair_fitting=repair_fitting,
        repair_seal=repair_seal,
        seal_share=seal_share,
    )
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
            f"finding: {' or '.join(finding.types)}: {finding.describe()}; confidence "
            f"{100 * finding.confidence:.0f} %"
            + (f"; {finding.consequence()}" if finding.consequence() else ""),
            highlight=False,
            markup=False,
        )
        for line in repair_lines(result):
            console.print(line, highlight=False, markup=False)
    if result.detected or result.remainder is not None:
        console.print(result.summary(), highlight=False, markup=False)
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
