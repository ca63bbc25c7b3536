"""``pneufdd simulate`` and ``pneufdd machines``: run the digital twin from the shell."""

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


def simulate_command(
    machine: Annotated[
        str, typer.Option(help="Built-in machine name (see `pneufdd machines`) or a TOML path.")
    ] = "festo-dsd",
    cycles: Annotated[int, typer.Option(min=1, help="Number of machine cycles.")] = 1,
    leak: Annotated[
        list[str] | None,
        typer.Option(
            help="LOCATION=SIZE[@TIME]; repeatable. SIZE: turns of the GR-3/8B valve (bare "
            "number, 0-6), '2.5mm' orifice, or '30slpm' at the nominal supply pressure. "
            "@TIME ('120s', '2min'): the leak appears in the first cycle starting then."
        ),
    ] = None,
    leak_growth: Annotated[
        list[str] | None,
        typer.Option(help="LOCATION=RATE: a scheduled leak grows, e.g. DNC_B=0.5/min."),
    ] = None,
    leak_repair: Annotated[
        list[str] | None,
        typer.Option(help="LOCATION@TIME: a scheduled leak is repaired, e.g. DNC_B@10min."),
    ] = None,
    seed: Annotated[int, typer.Option(min=0, help="Random seed (same seed, same bytes).")] = 0,
    out: Annotated[Path, typer.Option(help="Output Parquet file.")] = Path("run.parquet"),
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing output file.")
    ] = False,
    export_format: Annotated[
        str | None,
        typer.Option(
            "--export-format",
            help="Write OUT (.csv) as a field export instead of Parquet: twincat-scope, "
            "tia-trace, codesys-trace or csv-de (read back with `pneufdd import --format`).",
        ),
    ] = None,
    export_map: Annotated[
        Path | None,
        typer.Option(
            "--export-map",
            help="Tag map (.toml) giving the export's column names and units; default: the "
            "channel names in bar(g), l/min (ANR), mm, and the role map written as OUT.toml.",
        ),
    ] = None,
    max_cycle_s: Annotated[
        float,
        typer.Option(
            "--max-cycle-s",
            help="Longest a step may wait for its switch before the machine counts as stalled [s].",
        ),
    ] = 120.0,
    capture: Annotated[
        str,
        typer.Option(
            help="'continuous' (one file) or 'triggered': OUT is a folder with one file per "
            "capture, each starting at a cycle's first valve firing (its trigger)."
        ),
    ] = "continuous",
    files: Annotated[int, typer.Option(min=1, max=10_000, help="Triggered captures.")] = 1,
    cycles_per_file: Annotated[
        int, typer.Option(min=1, max=1000, help="Cycles from each capture's trigger.")
    ] = 1,
    pre_trigger_s: Annotated[
        float,
        typer.Option(
            "--pre-trigger-s",
            help="Span recorded before each trigger [s]: the capture starts with the previous "
            "cycle's last solenoid still on.",
        ),
    ] = 0.0,
    capture_s: Annotated[
        float | None,
        typer.Option(
            "--capture-s",
            help="Fixed capture length [s] (default: up to the next trigger); longer holds "
            "the start of the next cycle, cut mid-step.",
        ),
    ] = None,
    start_in_step: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="Start each file halfway through this step (a start in mid-sequence, "
            "the step's solenoids on).",
        ),
    ] = None,
    quantize: Annotated[
        list[str] | None,
        typer.Option(help="CHANNEL=STEP: quantise a channel, e.g. P_In=0.19bar; repeatable."),
    ] = None,
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
        )
    if export_format is not None:
        written = write_export(recording, export_format, out, export_map, overwrite)
        err.print(f"wrote {written}, {recording.duration:.1f} s", markup=False)
        return
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


def machines_command() -> None:
    """List the built-in machine descriptions."""
    from pneufdd.sim import builtin_machines, load_machine

    for name in builtin_machines():
        m = load_machine(name)
        typer.echo(f"{name}: {m.title} - {len(m.actuators)} actuators, {len(m.steps)} steps")


def register(app: typer.Typer) -> None:
    """Attach ``simulate`` and ``machines`` to ``app``."""
    app.command("simulate")(simulate_command)
    app.command("machines")(machines_command)
