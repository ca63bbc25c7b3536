"""``pneufdd steps RUN.parquet``: the cycles and steps found in a recording."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd.cli.recordings import MapOption, read_recording

if TYPE_CHECKING:
    from rich.console import Console

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pneufdd.recording.model import Recording
    from pneufdd.signals.segmentation import Segmentation, StepSpec

__all__ = ["register", "render_steps", "steps"]


def render_steps(
    recording: Recording,
    as_json: bool = False,
    all_steps: bool = False,
    console: Console | None = None,
    sequence: Sequence[StepSpec] | None = None,
) -> Segmentation:
    """Segment ``recording`` and print the result (rich tables, or JSON when ``as_json``).

    JSON: ``{"cycles": [{"index", "complete", "steps": [{"index", "start_s",
    "duration_s", "actuators"}]}], "rejected": [{"index", "start_s", "steps_found",
    "reason"}]}``. ``sequence``: the machine's (else the recording's own, see
    :func:`pneufdd.signals.segmentation.plc_sequence`).
    """
    import numpy as np
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from pneufdd.signals.segmentation import actuator_of, segment

    seg = segment(recording, sequence)
    if as_json:
        typer.echo(json.dumps(seg.to_dict()))
        return seg
    out = console or Console()
    good = seg.complete
    seq = Table(title=f"Sequence: {len(seg.sequence)} steps ({escape(str(seg.source))})")
    for col in ("step", "actuators", "median duration [s]", "min [s]", "max [s]"):
        seq.add_column(escape(col))
    durations = np.array([[s.duration_s for s in c.steps] for c in good]) if good else None
    for j, spec in enumerate(seg.sequence):
        acts = escape(", ".join(sorted({actuator_of(v) for v in spec.valves})))
        if durations is not None:
            d = durations[:, j]
            seq.add_row(str(j + 1), acts, f"{np.median(d):.3f}", f"{d.min():.3f}", f"{d.max():.3f}")
        else:
            seq.add_row(str(j + 1), acts, "-", "-", "-")
    out.print(seq)
    cyc = Table(title=f"Cycles: {len(good)} complete, {len(seg.rejected)} rejected")
    for col in ("cycle", "start [s]", "duration [s]", "steps", "complete", "reason"):
        cyc.add_column(escape(col))
    for c in seg.cycles:
        cyc.add_row(
            str(c.index),
            f"{c.start_s:.3f}",
            f"{c.end_s - c.start_s:.3f}",
            str(len(c.steps)),
            "yes" if c.complete else "[red]no[/]",
            escape(c.reason or ""),
        )
    out.print(cyc)
    if all_steps:
        for c in seg.cycles:
            t = Table(title=f"Cycle {c.index}")
            for col in ("step", "start [s]", "duration [s]", "actuators"):
                t.add_column(escape(col))
            for s in c.steps:
                t.add_row(
                    str(s.index),
                    f"{s.start_s:.3f}",
                    f"{s.duration_s:.3f}",
                    escape(", ".join(s.actuators)),
                )
            out.print(t)
    return seg


def steps(
    run: Annotated[Path, typer.Argument(help="Recording to segment (.parquet).")],
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of tables.")] = False,
    all_steps: Annotated[
        bool, typer.Option("--all-steps", help="List every step of every cycle.")
    ] = False,
    tag_map: MapOption = None,
    machine: Annotated[
        str | None,
        typer.Option(
            help="The machine's description (a TOML file or a built-in name): its PLC "
            "sequence segments RUN, so a capture of one cycle can be inspected (without it "
            "the sequence is the one RUN carries, else learned from RUN: two cycles needed)."
        ),
    ] = None,
) -> None:
    """Show the cycles and steps found in RUN, and the cycles rejected with their reason."""
    from pneufdd.errors import InputError, naming
    from pneufdd.signals.quality import check_carried_description, check_channels

    recording = read_recording(run, tag_map)
    sequence = None
    if machine is not None:
        from pneufdd.diagnosis.machine import check_plc_channels
        from pneufdd.signals.segmentation import sequence_from_machine
        from pneufdd.sim import load_machine

        description = load_machine(machine)
        check_plc_channels(recording, description, str(run))
        sequence = sequence_from_machine(description)
    try:
        check_channels(recording, (), str(run))
        if sequence is None:
            check_carried_description(recording, str(run))
        render_steps(recording, as_json=as_json, all_steps=all_steps, sequence=sequence)
    except InputError as exc:
        raise naming(exc, str(run)) from exc


def register(app: typer.Typer) -> None:
    """Attach the ``steps`` command to ``app``."""
    app.command("steps")(steps)
