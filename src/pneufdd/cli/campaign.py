"""``pneufdd campaign``: diagnosis accuracy on simulated plants that differ from their twin."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from pneufdd.errors import InputError, describe

__all__ = ["register"]


def _split(text: str, what: str) -> tuple[str, ...]:
    items = tuple(x.strip() for x in text.split(",") if x.strip())
    if not items:
        raise InputError(describe(what, text, "a comma-separated list"))
    return items


def _counts(text: str | None) -> tuple[int, ...]:
    """``--leaks-per-run`` as integers (empty when not given)."""
    if text is None:
        return ()
    items = _split(text, "--leaks-per-run")
    if not all(item.isdigit() for item in items):
        raise InputError(describe("--leaks-per-run", text, "comma-separated integers, e.g. 3,4,6"))
    return tuple(int(item) for item in items)


# the options of --capture triggered (docs/captures.md)
CaptureOption = Annotated[
    str,
    typer.Option(
        help="How plants are recorded: continuous (one file per reference recording "
        "and run) or triggered (short captures from a trigger, pooled: docs/captures.md)."
    ),
]
CapturesPerReferenceOption = Annotated[
    int, typer.Option(min=1, help="--capture triggered: captures per plant reference.")
]
CapturesPerRunOption = Annotated[
    int, typer.Option(min=1, help="--capture triggered: captures pooled into one run.")
]
CyclesPerFileOption = Annotated[
    int, typer.Option(min=1, help="--capture triggered: cycles from each trigger.")
]
PreTriggerOption = Annotated[
    float, typer.Option(help="--capture triggered: span recorded before each trigger [s].")
]


def campaign(
    machine: Annotated[
        list[str],
        typer.Option(help="Machine (built-in name or TOML path); repeatable."),
    ],
    out: Annotated[Path, typer.Option(help="New folder for manifest, plants, references, runs.")],
    plant_scale: Annotated[
        list[float] | None,
        typer.Option(
            help="Plant variation scale; repeatable (0: the twin itself, 1: a real machine, "
            "2: a badly documented one). Default 1."
        ),
    ] = None,
    plants: Annotated[int, typer.Option(min=1, max=9, help="Plants per machine and scale.")] = 3,
    sensor_sets: Annotated[
        str,
        typer.Option(
            help="Comma separated: full, line-flows (every analog channel but Q_In), "
            "supply-only (P_In, Q_In), pressure-only (P_In), digital-only, or analog "
            "channels joined by '+' (P_In+X_DNC). A set a machine lacks is skipped."
        ),
    ] = "full,supply-only",
    sizes: Annotated[
        str,
        typer.Option(
            help="Single-leak sizes, comma separated: turns of the GR-3/8B leak valve (3), "
            "orifice ('2.5mm') or flow at nominal supply pressure ('30slpm')."
        ),
    ] = "1,2,3,4,5,6",
    reps: Annotated[
        int, typer.Option(min=0, help="Runs per location, size and plant (0: no single leaks).")
    ] = 1,
    leak_free_runs: Annotated[int, typer.Option(min=0, help="Leak-free runs per plant.")] = 70,
    pairs: Annotated[int, typer.Option(min=0, help="Two-leak runs per plant.")] = 20,
    leaks_per_run: Annotated[
        str | None,
        typer.Option(
            help="Designs with this many simultaneous leaks at random locations and sizes "
            "(of --sizes), comma separated, e.g. 3,4,6; beside the single leaks and pairs.",
        ),
    ] = None,
    multi_leak_runs: Annotated[
        int, typer.Option(min=0, help="Runs per plant of each --leaks-per-run design.")
    ] = 20,
    run_cycles: Annotated[int, typer.Option(min=1, help="Cycles judged per run.")] = 10,
    reference_cycles: Annotated[
        int, typer.Option(min=10, help="Leak-free cycles of each plant's reference.")
    ] = 100,
    reference_recordings: Annotated[
        int,
        typer.Option(
            min=1, max=9, help="Recordings the reference cycles are split into (own seeds)."
        ),
    ] = 4,
    uncertainty_plants: Annotated[
        int,
        typer.Option(min=0, help="Plausible plants measuring the signatures' model uncertainty."),
    ] = 12,
    seed_offset: Annotated[
        int,
        typer.Option(
            min=0,
            help="First seed; the campaign uses [offset, offset + 10,000,000). Use a range "
            "never used while developing.",
        ),
    ] = 100_000_000,
    calibrate: Annotated[
        bool,
        typer.Option(
            "--calibrate",
            help="Calibrate the description to each plant's leak-free reference recordings "
            "and take that plant's signatures from the calibrated twin.",
        ),
    ] = False,
    capture: CaptureOption = "continuous",
    captures_per_reference: CapturesPerReferenceOption = 20,
    captures_per_run: CapturesPerRunOption = 10,
    cycles_per_file: CyclesPerFileOption = 1,
    pre_trigger_s: PreTriggerOption = 0.3,
    workers: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="Worker processes of the local Dask cluster (default: one per CPU; "
            "1: no cluster).",
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Run on an existing Dask cluster: its scheduler's address "
            "(tcp://host:8786); its workers must see --out at the same path.",
        ),
    ] = None,
) -> None:
    """Simulate plants varied from each MACHINE, diagnose their runs, print the figures."""
    from rich.console import Console

    from pneufdd.cli.outputs import check_outputs
    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.evaluation import CampaignDesign, run_campaign
    from pneufdd.evaluation.campaign import campaign_files
    from pneufdd.evaluation.captures import CAPTURE_KINDS, CaptureDesign

    if capture not in CAPTURE_KINDS:
        raise InputError(describe("--capture", capture, list(CAPTURE_KINDS)))
    # the capture options are checked with or without --capture triggered: a value
    # given but not used must still be one the option allows
    captures = CaptureDesign(
        captures_per_reference, captures_per_run, cycles_per_file, pre_trigger_s
    )
    triggered = captures if capture == "triggered" else None

    design = CampaignDesign(
        machines=tuple(machine),
        plant_scales=tuple(plant_scale or (1.0,)),
        plants=plants,
        sensor_sets=_split(sensor_sets, "--sensor-sets"),
        leak_sizes=_split(sizes, "--sizes"),
        reps=reps,
        leak_free_runs=leak_free_runs,
        pairs=pairs,
        run_cycles=run_cycles,
        reference_cycles=reference_cycles,
        reference_recordings=reference_recordings,
        uncertainty_plants=uncertainty_plants,
        seed_offset=seed_offset,
        calibrate=calibrate,
        capture=triggered,
        leaks_per_run=_counts(leaks_per_run),
        multi_leak_runs=multi_leak_runs,
    )
    # every file the campaign will write, checked before any work against its inputs
    inputs = {f"--machine {name}": Path(name) for name in machine}
    check_outputs(campaign_files(design, out), inputs, overwrite=True)
    console = Console()
    with progress_bars() as progress:
        result = run_campaign(
            design,
            out,
            workers,
            progress,
            lambda line: console.print(line, highlight=False, markup=False),
            scheduler,
        )
    for line in result.lines():
        console.print(line, highlight=False, markup=False)


def register(app: typer.Typer) -> None:
    """Attach the ``campaign`` command to ``app``."""
    app.command("campaign")(campaign)
