"""``pneufdd reference build``: a leak-free reference model (``.pnref``) from recordings."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

import pneufdd.limits as limits
from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption
from pneufdd.errors import InputError, describe
from pneufdd.limits import check_count

if TYPE_CHECKING:
    from rich.console import Console

if TYPE_CHECKING:
    from pneufdd.diagnosis.machine import MachineLike
    from pneufdd.sim import MachineDescription

__all__ = ["register"]

reference_app = typer.Typer(
    help="Build and inspect leak-free reference models.", no_args_is_help=True
)


@reference_app.command("build")
def build(
    recordings: Annotated[
        list[Path],
        typer.Argument(
            help="Leak-free recordings (.parquet) of one machine: files, folders or glob "
            "patterns (many short triggered captures are pooled)."
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="Reference file to write (.pnref).")],
    machine: Annotated[
        str | None,
        typer.Option(
            help="The machine's description: a TOML file (docs/machine-format.md) or a "
            "built-in name (see `pneufdd machines`). Needed for recordings that carry no "
            "description (CSV, TDMS); overrides the one simulated recordings carry. The "
            "reference keeps it: signatures, checks by simulation and costs come from it."
        ),
    ] = None,
    channels: Annotated[
        str | None,
        typer.Option(
            help="Analog channels to use, comma separated (e.g. P_In,Q_In); 'none' for the "
            "PLC's digital signals only. Default: every analog channel."
        ),
    ] = None,
    signatures: Annotated[
        bool,
        typer.Option(
            help="Compute leak signatures with the simulator (needed to locate and size)."
        ),
    ] = True,
    signature_cycles: Annotated[
        int, typer.Option(help="Simulated cycles per signature point.")
    ] = 2,
    signature_sizes: Annotated[
        str | None,
        typer.Option(
            help="Leak sizes of the signature ladder [SLPM at nominal supply pressure], "
            "comma separated (default 3,8,15,30,50,80,120,170,230)."
        ),
    ] = None,
    uncertainty_plants: Annotated[
        int | None,
        typer.Option(
            min=0,
            help="Plausible plants drawn around the description to measure how far a real "
            "machine's leak effects may differ from the twin's (0: trust the twin exactly; "
            "default 4).",
        ),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing OUT.")
    ] = False,
    tag_map: MapOption = None,
    calibrate: Annotated[
        bool,
        typer.Option(
            "--calibrate",
            help="Calibrate the description (--machine, else a draft from the recordings) "
            "to these leak-free recordings with the twin first (pneufdd machine calibrate).",
        ),
    ] = False,
    startup_cycles: Annotated[
        int | None,
        typer.Option(
            min=0,
            max=10,
            help="Complete cycles left out at the start of each recording (default 1 for a "
            "continuous run; 0 for a capture detected as starting at a cycle start).",
        ),
    ] = None,
) -> None:
    """Build a reference from leak-free RECORDINGS and write it to OUT."""
    from rich.console import Console

    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.diagnosis.batch import expand_runs
    from pneufdd.diagnosis.recordings import build_reference, parse_channels
    from pneufdd.diagnosis.reference.file import save_reference
    from pneufdd.diagnosis.reference.honesty import reference_honesty
    from pneufdd.diagnosis.reference.sensor_sets import sensor_set_report
    from pneufdd.physics.units import slpm_to_kg_s

    console = Console(stderr=True)
    recordings = expand_runs(recordings)
    inputs: dict[str, str | Path | None] = {f"RECORDINGS[{i}]": r for i, r in enumerate(recordings)}
    inputs["--machine"] = machine
    inputs["--map"] = tag_map
    check_outputs({"--out": out}, inputs, overwrite)
    check_count("--signature-cycles", signature_cycles, limits.MAX_SIGNATURE_CYCLES, low=1)
    if uncertainty_plants is not None:
        check_count("--uncertainty-plants", uncertainty_plants, limits.MAX_UNCERTAINTY_PLANTS)
    ladder = None
    if signature_sizes is not None:
        try:
            ladder = tuple(float(x) for x in signature_sizes.split(",") if x.strip())
        except ValueError as exc:
            raise InputError(
                describe("--signature-sizes", signature_sizes, "numbers [SLPM], comma separated")
            ) from exc
        if not ladder or any(b <= a for a, b in itertools.pairwise(ladder)):
            raise InputError(describe("--signature-sizes", signature_sizes, "increasing sizes"))
        if not all(0 < x <= 20_000 for x in ladder):  # also refuses nan and inf
            raise InputError(
                describe("--signature-sizes", signature_sizes, "sizes > 0 and <= 20000 [SLPM]")
            )
    description: MachineLike | None = machine
    if calibrate:
        description = _calibrated(recordings, machine, tag_map, console)
    log: list[str] = []
    with progress_bars(console) as progress:
        model = build_reference(
            recordings,
            parse_channels(channels),
            tag_map=tag_map,
            machine=description,
            with_signatures=signatures,
            signature_cycles=signature_cycles,
            signature_mass_flows=None if ladder is None else [slpm_to_kg_s(x) for x in ladder],
            progress=progress,
            startup_cycles=startup_cycles,
            log=log,
            **({} if uncertainty_plants is None else {"uncertainty_plants": uncertainty_plants}),
        )
    save_reference(model, out, overwrite=overwrite)
    if model.signatures is not None:
        sig = f"{len(model.signatures.locations)} locations"
    elif model.description is None:
        sig = "none (no machine description: pass --machine to locate and size leaks)"
    else:
        sig = "none"
    console.print(
        f"reference: {model.n_cycles} leak-free cycles of {model.machine!r}, "
        f"{model.n_steps} steps, channels {list(model.channels) or 'digital only'}, "
        f"signatures: {sig} -> {out}",
        highlight=False,
        markup=False,
    )
    honesty = reference_honesty(model)
    for line in [*log, *sensor_set_report(model.channels).lines(), *honesty.lines()]:
        console.print(line, highlight=False, markup=False)
    for warning in honesty.warnings:
        console.print(f"warning: {warning}", highlight=False, markup=False)


def _calibrated(
    recordings: list[Path], machine: str | None, tag_map: Path | None, console: Console
) -> MachineDescription:
    """Draft (without --machine) and calibrate: the description the reference keeps."""
    from pneufdd.calibration import draft_machine
    from pneufdd.calibration.calibrate import calibrate_machine
    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.cli.recordings import read_recordings
    from pneufdd.diagnosis.machine import recording_machine_name
    from pneufdd.sim import load_machine

    recs = read_recordings(recordings, tag_map)
    if machine is None:
        name = recording_machine_name(recs[0]) or "drafted"
        start = load_machine(draft_machine(recs, name=name).data)
        origin = "a draft from the recordings"
    else:
        start = load_machine(machine)
        origin = start.source
    with progress_bars(console) as progress:
        result = calibrate_machine(
            start, recs, progress=progress, names=[str(p) for p in recordings]
        )
    sources = ", ".join(p.name for p in recordings)
    calibrated = result.calibrated_description(sources)
    console.print(
        f"calibrated {origin}: {result.fit_line()}; not informed: "
        f"{', '.join(result.not_informed) or 'none'}",
        highlight=False,
        markup=False,
        soft_wrap=True,
    )
    for line in result.identification_lines():
        console.print(line, highlight=False, markup=False, soft_wrap=True)
    gaps = result.measured.gap_line([str(p) for p in recordings])
    if gaps is not None:
        console.print(gaps, highlight=False, markup=False, soft_wrap=True)
    return calibrated


def register(app: typer.Typer) -> None:
    """Attach the ``reference`` command group to ``app``."""
    app.add_typer(reference_app, name="reference")
