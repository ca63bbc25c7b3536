"""``pneufdd simulate``, ``machines`` and ``faults``: the digital twin from the shell."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

import pneufdd.limits as limits
from pneufdd.cli.outputs import check_outputs
from pneufdd.errors import InputError, describe

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress

    from pneufdd.sim.description import MachineDescription
    from pneufdd.sim.faults import FaultSchedule
    from pneufdd.sim.nuisances import Nuisances
    from pneufdd.sim.schedule import LeakSchedule

__all__ = ["MAX_CYCLES", "parse_leak_option", "register"]

MAX_CYCLES = limits.MAX_CYCLES
"""Most cycles one ``simulate`` run may ask for (:mod:`pneufdd.limits`; the memory
they imply is checked after the first cycle)."""


def parse_leak_option(text: str) -> tuple[str, str]:
    """Split ``LOCATION=SIZE`` (``DNC_B=4``, ``supply=30slpm``) into its two parts.

    Examples
    --------
    >>> parse_leak_option("DNC_B=4")
    ('DNC_B', '4')
    """
    location, sep, size = text.partition("=")
    if not sep or not location.strip() or not size.strip():
        raise InputError(describe("--leak", text, "LOCATION=SIZE, e.g. DNC_B=4 or supply=30slpm"))
    return location.strip(), size.strip()


# the options of `simulate` (typed once here: the command's signature stays readable)
_Leak = Annotated[
    list[str] | None,
    typer.Option(
        help="LOCATION=SIZE[@TIME]; repeatable. SIZE: turns of the GR-3/8B valve (bare "
        "number, 0-6), '2.5mm' orifice, or '30slpm' at the nominal supply pressure. "
        "@TIME ('120s', '2min'): the leak appears in the first cycle starting then."
    ),
]
_LeakGrowth = Annotated[
    list[str] | None,
    typer.Option(help="LOCATION=RATE: a scheduled leak grows, e.g. DNC_B=0.5/min."),
]
_LeakRepair = Annotated[
    list[str] | None,
    typer.Option(help="LOCATION@TIME: a scheduled leak is repaired, e.g. DNC_B@10min."),
]
_Fault = Annotated[
    list[str] | None,
    typer.Option(
        help="LOC=KIND[:SIZE][@TIME]; repeatable. A fault other than a leak "
        "(`pneufdd faults` lists them, docs/faults.md), e.g. DNC=friction:+50%, "
        "DNC_A=throttle:-40%, DNC=piston-leak:20slpm, S_DNC_B=late:30ms, "
        "supply=regulator:-0.4bar; @TIME: it appears in the first cycle starting then."
    ),
]
_FaultGrowth = Annotated[
    list[str] | None,
    typer.Option(help="LOC=KIND:RATE: a fault's size changes, e.g. DNC=friction:+10%/h."),
]
_FaultRepair = Annotated[
    list[str] | None,
    typer.Option(help="LOC=KIND@TIME: a fault is repaired, e.g. DNC=friction@2h."),
]
_Ambient = Annotated[
    str | None,
    typer.Option(
        help="Ambient temperature over the run: '25C', '15C..35C/8h' (a ramp) or "
        "'15C@0,35C@4h,20C@8h'; moves the air's and the seals' temperature."
    ),
]
_SupplyAir = Annotated[
    str | None,
    typer.Option(
        "--supply-air", help="Supply air temperature, as --ambient (default: the ambient)."
    ),
]
_Payload = Annotated[
    list[str] | None,
    typer.Option(
        help="ACT=MASS[@TIME]; repeatable: from TIME the actuator moves MASS (kg or g) "
        "more than described, until its next --payload (a product sequence)."
    ),
]
_HeaderDips = Annotated[
    str | None,
    typer.Option(
        "--header-dips",
        help="Dips of the house air from other consumers: "
        "depth=0.3bar,duration=2s,rate=10/h[,seed=N] (half sines at Poisson times).",
    ),
]
_ExportFormat = Annotated[
    str | None,
    typer.Option(
        "--export-format",
        help="Write OUT (.csv) as a field export instead of Parquet: twincat-scope, "
        "tia-trace, codesys-trace or csv-de (read back with `pneufdd import --format`).",
    ),
]
_ExportMap = Annotated[
    Path | None,
    typer.Option(
        "--export-map",
        help="Tag map (.toml) giving the export's column names and units; default: the "
        "channel names in bar(g), l/min (ANR), mm, and the role map written as OUT.toml.",
    ),
]
_MaxCycleS = Annotated[
    float,
    typer.Option(
        "--max-cycle-s",
        help="Longest a step may wait for its switch before the machine counts as stalled [s].",
    ),
]
_Capture = Annotated[
    str,
    typer.Option(
        help="'continuous' (one file) or 'triggered': OUT is a folder with one file per "
        "capture, each starting at a cycle's first valve firing (its trigger)."
    ),
]
_PreTriggerS = Annotated[
    float,
    typer.Option(
        "--pre-trigger-s",
        help="Span recorded before each trigger [s]: the capture starts with the previous "
        "cycle's last solenoid still on.",
    ),
]
_CaptureS = Annotated[
    float | None,
    typer.Option(
        "--capture-s",
        help="Fixed capture length [s] (default: up to the next trigger); longer holds "
        "the start of the next cycle, cut mid-step.",
    ),
]
_StartInStep = Annotated[
    int | None,
    typer.Option(
        min=1,
        help="Start each file halfway through this step (a start in mid-sequence, "
        "the step's solenoids on).",
    ),
]
_Quantize = Annotated[
    list[str] | None,
    typer.Option(help="CHANNEL=STEP: quantise a channel, e.g. P_In=0.19bar; repeatable."),
]


def simulate_command(
    machine: Annotated[
        str, typer.Option(help="Built-in machine name (see `pneufdd machines`) or a TOML path.")
    ] = "festo-dsd",
    cycles: Annotated[int, typer.Option(min=1, help="Number of machine cycles.")] = 1,
    leak: _Leak = None,
    leak_growth: _LeakGrowth = None,
    leak_repair: _LeakRepair = None,
    fault: _Fault = None,
    fault_growth: _FaultGrowth = None,
    fault_repair: _FaultRepair = None,
    ambient: _Ambient = None,
    supply_air: _SupplyAir = None,
    payload: _Payload = None,
    header_dips: _HeaderDips = None,
    seed: Annotated[int, typer.Option(min=0, help="Random seed (same seed, same bytes).")] = 0,
    out: Annotated[Path, typer.Option(help="Output Parquet file.")] = Path("run.parquet"),
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing output file.")
    ] = False,
    export_format: _ExportFormat = None,
    export_map: _ExportMap = None,
    max_cycle_s: _MaxCycleS = 120.0,
    capture: _Capture = "continuous",
    files: Annotated[int, typer.Option(min=1, max=10_000, help="Triggered captures.")] = 1,
    cycles_per_file: Annotated[
        int, typer.Option(min=1, max=1000, help="Cycles from each capture's trigger.")
    ] = 1,
    pre_trigger_s: _PreTriggerS = 0.0,
    capture_s: _CaptureS = None,
    start_in_step: _StartInStep = None,
    quantize: _Quantize = None,
) -> None:
    """Simulate a machine with optional leaks and write the recording to OUT."""
    from rich.console import Console
    from rich.markup import escape

    from pneufdd.cli.captures import CaptureOptions, simulate_continuous, write_field_recordings
    from pneufdd.cli.simulate_export import check_export, write_export
    from pneufdd.sim import load_machine

    field = CaptureOptions(
        capture, files, cycles_per_file, pre_trigger_s, capture_s, start_in_step, quantize or []
    )
    if field.triggered and export_format is not None:
        raise InputError(
            describe("--export-format with --capture triggered", export_format, "Parquet captures")
        )
    if not field.triggered:
        check_outputs({"--out": out}, {"--machine": machine}, overwrite)
        check_export(export_format, out, export_map, overwrite)
    _check_run_options(cycles, max_cycle_s)
    desc = load_machine(machine)
    leaks, schedule = _leak_options(desc, leak or [], leak_growth or [], leak_repair or [])
    faults, nuisances = _condition_options(
        desc,
        (fault or [], fault_growth or [], fault_repair or []),
        (ambient, supply_air, payload or [], header_dips),
    )
    err = Console(stderr=True)
    with _cycle_bar(err) as bar:
        task = bar.add_task(escape(desc.name), total=cycles)  # a name is plain text
        if field.triggered:
            paths = write_field_recordings(
                field,
                desc,
                leaks,
                seed,
                max_cycle_s,
                schedule,
                out,
                overwrite,
                lambda done, total: bar.update(task, completed=done, total=total),
                faults,
                nuisances,
            )
            err.print(f"wrote {len(paths)} captures to {out}", markup=False)
            return
        recording = simulate_continuous(
            field,
            desc,
            cycles,
            leaks,
            seed,
            lambda done, total: bar.update(task, completed=done),
            max_cycle_s,
            schedule,
            faults,
            nuisances,
        )
    if export_format is not None:
        written = write_export(recording, export_format, out, export_map, overwrite)
        err.print(f"wrote {written}, {recording.duration:.1f} s", markup=False)
        return
    out.parent.mkdir(parents=True, exist_ok=True)  # as every output (cli/outputs.py)
    path = recording.write(out, overwrite=overwrite)
    err.print(
        f"wrote {path} ({recording.duration:.1f} s, {len(recording.channels)} channels)",
        markup=False,
    )


def _check_run_options(cycles: int, max_cycle_s: float) -> None:
    """Refuse a run length or a stall limit outside the documented bounds."""
    if cycles > MAX_CYCLES:
        raise InputError(describe("--cycles", cycles, f"1 to {MAX_CYCLES:,}"))
    if not 0.0 < max_cycle_s <= 3600.0:  # also refuses nan
        raise InputError(describe("--max-cycle-s", max_cycle_s, "> 0 and <= 3600 [s]"))


def _cycle_bar(console: Console) -> Progress:
    """The progress bar of a simulation: cycles done, time elapsed and left."""
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn("simulating {task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total} cycles"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
        console=console,
    )


def _leak_options(
    desc: MachineDescription, leak: list[str], growth: list[str], repair: list[str]
) -> tuple[dict[str, str], LeakSchedule | None]:
    """The constant leaks and the leak schedule of the ``--leak``/growth/repair options.

    Unknown locations and bad sizes are refused before any simulation.
    """
    from pneufdd.sim.leaks import resolve_leaks
    from pneufdd.sim.schedule import schedule_from_options

    leaks: dict[str, str] = {}
    timed = [item for item in leak if "@" in item]
    for item in leak:
        if "@" in item:
            continue
        location, size = parse_leak_option(item)
        if location in leaks:
            raise InputError(describe("--leak location given twice", location, "once"))
        leaks[location] = size
    specs = resolve_leaks(desc, leaks)
    schedule = schedule_from_options(timed, growth, repair)
    if schedule is not None:
        schedule.check(desc, specs)
    return leaks, schedule


def _condition_options(
    desc: MachineDescription,
    fault_options: tuple[list[str], list[str], list[str]],
    nuisance_options: tuple[str | None, str | None, list[str], str | None],
) -> tuple[FaultSchedule | None, Nuisances | None]:
    """The faults and nuisances of the options, checked against ``desc`` before any run."""
    if not any(fault_options) and not any(nuisance_options):
        return None, None  # a plain run imports none of them (they load numba)
    from pneufdd.sim.conditions import check_conditions
    from pneufdd.sim.faults import fault_schedule_from_options
    from pneufdd.sim.nuisances import nuisances_from_options

    faults = fault_schedule_from_options(*fault_options)
    nuisances = nuisances_from_options(*nuisance_options)
    check_conditions(desc, faults, nuisances)
    return faults, nuisances


def faults_command() -> None:
    """List the fault catalogue: each kind's location, size unit, scale and what it changes."""
    from pneufdd.sim.faults import FAULT_KINDS

    for kind in FAULT_KINDS.values():
        unit = f"[{kind.unit}]" if kind.unit else "(no size)"
        sizes = f", e.g. {kind.sizes[0]:g} or {kind.sizes[1]:g}" if kind.unit else ""
        where = {"actuator": "an actuator (DNC)", "line": "a line (DNC_A)",
                 "switch": "a switch (S_DNC_B)", "supply": "the supply"}[kind.target]  # fmt: skip
        typer.echo(f"{kind.name} ({kind.family}) on {where}, size {unit}{sizes}")
        typer.echo(f"    {kind.changes}")


def machines_command() -> None:
    """List the built-in machine descriptions."""
    from pneufdd.sim import builtin_machines, load_machine

    for name in builtin_machines():
        m = load_machine(name)
        typer.echo(f"{name}: {m.title} - {len(m.actuators)} actuators, {len(m.steps)} steps")


def register(app: typer.Typer) -> None:
    """Attach ``simulate``, ``machines`` and ``faults`` to ``app``."""
    app.command("simulate")(simulate_command)
    app.command("machines")(machines_command)
    app.command("faults")(faults_command)
