"""``pneufdd simulate`` and ``pneufdd machines``: run the digital twin from the shell."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

import pneufdd.limits as limits
from pneufdd.cli.outputs import check_outputs
from pneufdd.errors import InputError, describe

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
    overwrite: Annotated[bool, typer.Option(help="Replace an existing output file.")] = False,
    max_cycle_s: Annotated[
        float,
        typer.Option(
            "--max-cycle-s",
            help="Longest a step may wait for its switch before the machine counts as stalled [s].",
        ),
    ] = 120.0,
) -> None:
    """Simulate a machine with optional leaks and write the recording to OUT."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from pneufdd.sim import load_machine, simulate
    from pneufdd.sim.leaks import resolve_leaks
    from pneufdd.sim.schedule import schedule_from_options

    check_outputs({"--out": out}, {"--machine": machine}, overwrite)
    if cycles > MAX_CYCLES:
        raise InputError(describe("--cycles", cycles, f"1 to {MAX_CYCLES:,}"))
    if not 0.0 < max_cycle_s <= 3600.0:  # also refuses nan
        raise InputError(describe("--max-cycle-s", max_cycle_s, "> 0 and <= 3600 [s]"))
    desc = load_machine(machine)
    leaks: dict[str, str] = {}
    timed = [item for item in leak or [] if "@" in item]
    for item in leak or []:
        if "@" in item:
            continue
        location, size = parse_leak_option(item)
        if location in leaks:
            raise InputError(describe("--leak location given twice", location, "once"))
        leaks[location] = size
    specs = resolve_leaks(desc, leaks)  # unknown locations and bad sizes fail before the run
    schedule = schedule_from_options(timed, leak_growth or [], leak_repair or [])
    if schedule is not None:
        schedule.check(desc, specs)
    err = Console(stderr=True)
    with Progress(
        TextColumn("simulating {task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total} cycles"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
        console=err,
    ) as bar:
        task = bar.add_task(desc.name, total=cycles)
        recording = simulate(
            desc,
            cycles=cycles,
            leaks=leaks,
            seed=seed,
            max_cycle_s=max_cycle_s,
            progress=lambda done, total: bar.update(task, completed=done),
            schedule=schedule,
        )
    path = recording.write(out, overwrite=overwrite)
    err.print(
        f"wrote {path} ({recording.duration:.1f} s, {len(recording.channels)} channels)",
        markup=False,
    )


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
