"""``pneufdd energy``: where the air goes, the lowest pressure, what-ifs priced by the twin.

Exit codes: 0 success, 2 bad input. Outputs are rendered completely, then written
atomically.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd.cli.cost_options import HoursOption, JsonOption, KwOption, PriceOption, ReportOption
from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption, read_recordings
from pneufdd.errors import InputError, describe
from pneufdd.files import write_text_atomic

if TYPE_CHECKING:
    from rich.console import Console

    from pneufdd.energy.analysis import EnergyAnalysis

__all__ = ["register"]


def _parse_leaks(items: list[str] | None) -> dict[str, float] | None:
    """``--leak LOC=MM`` options as {location: equivalent orifice [mm]}."""
    if not items:
        return None
    out: dict[str, float] = {}
    for item in items:
        loc, sep, size = item.partition("=")
        try:
            mm = float(size.removesuffix("mm"))
        except ValueError:
            mm = float("nan")
        if not sep or not loc or not 0.0 < mm <= 50.0:
            raise InputError(describe("--leak", item, "LOCATION=MM, an orifice of 0 to 50 mm"))
        out[loc.strip()] = mm
    return out


def energy(
    runs: Annotated[
        list[Path], typer.Argument(metavar="REC...", help="Recordings of the machine running.")
    ],
    reference: Annotated[
        Path | None,
        typer.Option(
            "--reference",
            help="Reference (.pnref): its description is the twin, its diagnosis gives the leaks.",
        ),
    ] = None,
    machine: Annotated[
        str | None,
        typer.Option(
            "--machine",
            help="A description overriding the reference's (calibrated.toml, or a built-in name).",
        ),
    ] = None,
    json_out: JsonOption = None,
    report: ReportOption = None,
    hours: HoursOption = 7000.0,
    price: PriceOption = 0.05,
    kw_per_100cfm: KwOption = 18.0,
    tolerance: Annotated[
        float,
        typer.Option(help="How much longer each step may take, as a fraction of the cycle time."),
    ] = 0.02,
    cycle_time: Annotated[
        float | None,
        typer.Option(
            "--cycle-time",
            help="The cycle time production needs [s]: steps may "
            "slow down in proportion, the cycle no further (default: the present one, "
            "steps within --tolerance).",
        ),
    ] = None,
    standby_hours: Annotated[
        float | None,
        typer.Option(
            "--standby-hours",
            help="Hours a year stopped with the air on (default: 8760 minus --hours).",
        ),
    ] = None,
    restarts: Annotated[
        float, typer.Option(help="Restarts a year if the air were switched off at standstill.")
    ] = 250.0,
    header_follows: Annotated[
        bool,
        typer.Option(
            "--header-follows",
            help="The compressor's pressure follows this "
            "machine's: count the DOE compressor-side saving (2 psi ~ 1 %).",
        ),
    ] = False,
    twin_cycles: Annotated[
        int, typer.Option("--twin-cycles", help="Twin cycles per candidate (the first left out).")
    ] = 3,
    leak: Annotated[
        list[str] | None,
        typer.Option(
            "--leak",
            help="LOCATION=MM: a leak (equivalent orifice) to put in the "
            "twin instead of the diagnosis's; repeatable.",
        ),
    ] = None,
    tag_map: MapOption = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace existing --json/--report files.")
    ] = False,
) -> None:
    """Where the air goes, the lowest pressure that does the job, what-ifs priced."""
    from rich.console import Console

    from pneufdd.diagnosis.cost import CostSettings
    from pneufdd.energy.analysis import analyse_energy
    from pneufdd.energy.settings import EnergySettings

    inputs: dict[str, Path | None] = {
        "--reference": reference,
        "--map": tag_map,
        "--machine": None if machine is None else Path(machine),  # a built-in name is ignored
    }
    inputs.update({"REC" if len(runs) == 1 else f"REC {i + 1}": p for i, p in enumerate(runs)})
    check_outputs({"--json": json_out, "--report": report}, inputs, overwrite=overwrite)
    if reference is None and machine is None:
        raise InputError(describe("--reference / --machine", None, "one of them (the twin)"))
    settings = EnergySettings(
        cost=CostSettings(hours=hours, price_per_kwh=price, kw_per_100_cfm=kw_per_100cfm),
        tolerance=tolerance,
        standby_hours=standby_hours,
        restarts_per_year=restarts,
        cycle_time_needed_s=cycle_time,
        header_follows=header_follows,
        cycles=twin_cycles,
    )
    leaks = _parse_leaks(leak)
    recordings = read_recordings(runs, tag_map)
    console = Console(stderr=True)
    analysis = analyse_energy(
        recordings,
        reference=reference,
        machine=machine,
        settings=settings,
        leaks=leaks,
        progress=lambda task: console.print(f"[dim]{task}...[/]", highlight=False),
    )
    names = ", ".join(str(p) for p in runs)
    outputs: list[tuple[Path, str]] = []
    if json_out is not None:
        data = analysis.to_dict()
        data["recordings"] = [str(p) for p in runs]
        outputs.append((json_out, json.dumps(data, indent=2, allow_nan=False) + "\n"))
    if report is not None:
        from pneufdd.report.energy import render_energy_report  # matplotlib: only for --report

        outputs.append((report, render_energy_report(analysis, names)))
    for path, text in outputs:
        write_text_atomic(path, text)
    _print(Console(), analysis)


def _print(console: Console, analysis: EnergyAnalysis) -> None:
    """The breakdown by actuator, the set point and the ranked measures."""
    from rich.markup import escape
    from rich.table import Table

    from pneufdd.energy.changes import bar_g

    b = analysis.breakdown
    table = Table(
        title=f"Where the air goes ({b.source}; {b.cycles} cycles of {b.cycle_time_s:.2f} s)"
    )
    for name in ("component", "air \\[g/cycle]", "share", "cost \\[$/yr]"):
        table.add_column(name, justify="left" if name == "component" else "right")
    total = b.explained_kg
    for group, value in sorted(b.by_group().items(), key=lambda kv: -kv[1]):
        table.add_row(escape(group), f"{1e3 * value:.3f}", f"{100 * value / total:.1f} %",
                      f"{b.money(value).cost:,.0f}")  # fmt: skip
    table.add_section()
    table.add_row("total", f"{1e3 * total:.3f}", "", f"{b.money(total).cost:,.0f}")
    standby = b.standby_money
    table.add_row("standby (air on, stopped)", f"{1e3 * standby.mass_flow_kg_s:.4f} g/s", "",
                  f"{standby.cost:,.0f}")  # fmt: skip
    console.print(table)
    s = analysis.search
    console.print(
        f"lowest set point: {bar_g(s.min_psig):.2f} bar(g) (now {bar_g(s.now_psig):.2f}); "
        f"limiting actuator: {s.limiting_actuator or 'none found'}; saving "
        f"{analysis.set_point.saving_per_year:,.0f} $/yr",
        highlight=False,
        markup=False,
    )
    measures = Table(title="Measures, ranked by saving a year")
    for name in ("#", "measure", "does the job", "saving \\[$/yr]", "kWh/yr", "cycle \\[ms]"):
        measures.add_column(name, justify="left" if name == "measure" else "right")
    for i, m in enumerate(analysis.measures, start=1):
        measures.add_row(
            str(i), escape(m.name), "yes" if m.feasible else "no",
            f"{m.saving_per_year:,.0f}", f"{m.kwh_per_year:,.0f}",
            f"{1e3 * (m.cycle_after_s - m.cycle_before_s):+.0f}",
        )  # fmt: skip
    console.print(measures)
    for note in analysis.notes:
        console.print(f"note: {note}", highlight=False, markup=False)


def register(app: typer.Typer) -> None:
    """Attach the ``energy`` command to ``app``."""
    app.command("energy")(energy)
