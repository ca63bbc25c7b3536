"""``pneufdd machine ...``: work with machine descriptions (``vary``: a plant from a twin)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd import __version__
from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption
from pneufdd.errors import InputError, describe, naming

if TYPE_CHECKING:
    from pneufdd.recording.model import Recording
    from pneufdd.sim import MachineDescription

__all__ = ["register"]

machine_app = typer.Typer(
    help="Work with machine descriptions: draw plants that differ from their twin.",
    no_args_is_help=True,
)


@machine_app.command("vary")
def vary(
    description: Annotated[
        str,
        typer.Argument(help="Built-in machine name (see `pneufdd machines`) or a TOML path."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Plant description to write (.toml).")],
    scale: Annotated[
        float,
        typer.Option(
            help="Spread relative to the documented tolerances: 0 = the description, "
            "1 = a plausible real machine, 2 = a badly documented one (at most 5)."
        ),
    ] = 1.0,
    seed: Annotated[int, typer.Option(min=0, help="Random seed (same seed, same plant).")] = 0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing OUT.")
    ] = False,
) -> None:
    """Draw a plant from DESCRIPTION (every physical parameter around its value) to OUT.

    Spreads and their sources: docs/plant-variation.md.
    """
    from rich.console import Console

    from pneufdd.sim import load_machine
    from pneufdd.sim.variation import MAX_SCALE, parameter_changes, vary_machine, write_machine

    if not 0.0 <= scale <= MAX_SCALE:  # also refuses nan
        raise InputError(
            describe("--scale", scale, f"a number from 0 to {MAX_SCALE:g} (1: a real machine)")
        )
    check_outputs({"--out": out}, {"DESCRIPTION": description}, overwrite)
    twin = load_machine(description)
    plant = vary_machine(twin, scale=scale, seed=seed)
    origin = twin.name if twin.source == twin.name else f"{twin.name} ({twin.source})"
    header = (
        f"plant varied from {origin} at scale {scale:g}, seed {seed} by pneufdd "
        f"{__version__}\nspreads: docs/plant-variation.md"
    )
    path = write_machine(plant, out, header=header, overwrite=overwrite)
    changes = parameter_changes(twin, plant)
    largest = ", ".join(str(c) for c in changes[:3]) or "none"
    Console(stderr=True).print(
        f"wrote {path}: plant of {twin.name} at scale {scale:g}, seed {seed}, "
        f"{len(changes)} parameters changed; largest: {largest}",
        highlight=False,
        markup=False,
        soft_wrap=True,
    )


def _checked(recordings: list[Path], tag_map: Path | None) -> list[Recording]:
    """The recordings, each refused (naming its file) if a channel is implausible or empty."""
    import numpy as np

    from pneufdd.cli.recordings import read_recordings
    from pneufdd.errors import ChannelError, naming
    from pneufdd.signals.quality import check_channels

    recs = read_recordings(recordings, tag_map)
    for rec, path in zip(recs, recordings, strict=True):
        try:
            check_channels(rec, rec.analog_channels, str(path))
            for channel in rec.analog_channels:
                if not np.isfinite(rec.info(channel).values).any():
                    raise ChannelError(
                        describe(f"channel {channel!r}", "no finite sample", "measured values")
                    )
        except InputError as exc:
            raise naming(exc, str(path)) from exc
    return recs


@machine_app.command("draft")
def draft(
    recordings: Annotated[
        list[Path],
        typer.Argument(help="Leak-free recordings of the plant (the first: >= 2 full cycles)."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Draft description to write (.toml).")],
    name: Annotated[str, typer.Option(help="Machine name.")] = "drafted",
    tag_map: MapOption = None,
    actuator: Annotated[
        list[str] | None,
        typer.Option(
            "--actuator",
            help="An actuator's order code, ID=CODE (e.g. PRESS=DSBC-63-100-PPVA-N3); "
            "repeat per actuator. Forms: docs/catalogue.md.",
        ),
    ] = None,
    valve: Annotated[
        list[str] | None,
        typer.Option(
            "--valve",
            help="The order code of an actuator's valve, ID=CODE (e.g. PRESS=VUVG-L14-P53C); "
            "repeat per valve.",
        ),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing OUT.")
    ] = False,
) -> None:
    """Draft a machine description from RECORDINGS (what the signals cannot tell: assumed).

    Actuators, valve kinds, the PLC sequence and the sensors come from the signals;
    bore, stroke, tubes and valve sizes are documented defaults marked '# assumed',
    or the catalogue's for the order codes given (--actuator, --valve), each line
    marked with its source. It lists the actuators found and the codes still missing.

    Rules and defaults: docs/calibration.md; order codes: docs/catalogue.md.
    """
    from rich.console import Console

    from pneufdd.calibration.draft import draft_machine
    from pneufdd.files import write_text_atomic
    from pneufdd.sim import load_machine

    inputs: dict[str, Path | None] = {f"RECORDINGS[{k}]": p for k, p in enumerate(recordings)}
    check_outputs({"--out": out}, {**inputs, "--map": tag_map}, overwrite)
    if not name.strip() or any(c in name for c in _NAME_FORBIDDEN):
        raise InputError(
            describe("--name", name, "a machine name without quotes, brackets or line breaks")
        )
    from pneufdd.catalogue import actuator_from_code, valve_from_code

    actuator_codes = _codes(actuator or [], "--actuator", actuator_from_code)
    valve_codes = _codes(valve or [], "--valve", valve_from_code)
    recs = _checked(recordings, tag_map)
    try:
        drafted = draft_machine(recs, name, actuator_codes, valve_codes)
    except InputError as exc:
        raise naming(exc, ", ".join(str(p) for p in recordings)) from exc
    machine = load_machine(drafted.data)  # the draft is a valid description
    sources = ", ".join(p.name for p in recordings)
    text = drafted.to_toml(f"drafted from {sources} by pneufdd {__version__}")
    write_text_atomic(out, text)
    lines = text.splitlines()
    assumed = sum(line.rstrip().endswith("# assumed") for line in lines)
    coded = sum("# from catalogue" in line or "# assumed by the" in line for line in lines)
    console = Console(stderr=True)
    say = partial(console.print, highlight=False, markup=False, soft_wrap=True)
    say(
        f"wrote {out}: {len(machine.actuators)} actuators, {len(machine.steps)} steps, "
        f"{len(machine.sensors)} sensors; {assumed} lines assumed (marked '# assumed'), "
        f"{coded} from order codes (marked '# from catalogue' or '# assumed by the ... rule')"
    )
    for line in _code_report(machine, actuator_codes, valve_codes):
        say(line)


_NAME_FORBIDDEN = '"\\\n\r\t[]'


def _codes(pairs: list[str], option: str, lookup: Callable[[str], object]) -> dict[str, str]:
    """``ID=CODE`` options as a mapping, each code resolved in the catalogue first.

    Raises
    ------
    InputError
        For a pair without ``=``, an id given twice, or a code that does not resolve
        (naming the option, the code, the part that failed and the forms allowed).
    """
    out: dict[str, str] = {}
    for pair in pairs:
        ident, sep, code = pair.partition("=")
        ident, code = ident.strip().upper(), code.strip()
        if not sep or not ident or not code:
            raise InputError(describe(option, pair, "ID=CODE, e.g. PRESS=DSBC-63-100-PPVA-N3"))
        if ident in out:
            raise InputError(describe(f"{option} for actuator {ident}", "given twice", "once"))
        try:
            lookup(code)
        except InputError as exc:
            raise InputError(f"{option} {ident}={code}: {exc}") from exc
        out[ident] = code
    return out


def _code_report(
    machine: MachineDescription, actuator_codes: dict[str, str], valve_codes: dict[str, str]
) -> list[str]:
    """The actuators found, and the exact options for the codes still missing."""
    ids = machine.actuator_ids
    lines = ["actuators found: " + ", ".join(
        f"{i} ({'code ' + actuator_codes[i] if i in actuator_codes else 'no order code'})"
        for i in ids
    )]  # fmt: skip
    missing = [i for i in ids if i not in actuator_codes]
    missing_valves = [i for i in ids if i not in valve_codes]
    if missing or missing_valves:
        lines.append(
            "their geometry and valves stay assumed; add the codes from their nameplates "
            "(forms: docs/catalogue.md):"
        )
        lines += [f"  --actuator {i}=<order code>" for i in missing]
        lines += [f"  --valve {i}=<order code>" for i in missing_valves]
    else:
        lines.append("every actuator and valve has its order code")
    return lines


@machine_app.command("calibrate")
def calibrate(
    description: Annotated[
        str,
        typer.Argument(
            help="Description to start from: a TOML path (e.g. a draft) or a built-in name."
        ),
    ],
    recordings: Annotated[list[Path], typer.Argument(help="Leak-free recordings of the plant.")],
    out: Annotated[Path, typer.Option("--out", help="Calibrated description to write (.toml).")],
    report: Annotated[
        Path | None, typer.Option("--report", help="Write an HTML report (before/after).")
    ] = None,
    tag_map: MapOption = None,
    max_evaluations: Annotated[
        int, typer.Option(min=2, max=100_000, help="Most least-squares iterations per fit.")
    ] = 40,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace existing outputs.")
    ] = False,
) -> None:
    """Fit DESCRIPTION to leak-free RECORDINGS with the digital twin in the loop.

    Fits the supply set point and line, each actuator's volume (air per stroke),
    valve and throttle capacities (step durations) and, with line pressure sensors,
    friction; parameters the data cannot inform stay at their prior and are listed.
    """
    from rich.console import Console

    from pneufdd.calibration.calibrate import calibrate_machine
    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.files import write_text_atomic
    from pneufdd.report.calibration import render_calibration_report
    from pneufdd.sim import load_machine
    from pneufdd.sim.variation import machine_to_toml

    inputs: dict[str, Path | None] = {f"RECORDINGS[{k}]": p for k, p in enumerate(recordings)}
    inputs["DESCRIPTION"] = Path(description)
    check_outputs({"--out": out, "--report": report}, {**inputs, "--map": tag_map}, overwrite)
    start = load_machine(description)
    recs = _checked(recordings, tag_map)
    console = Console(stderr=True)
    with progress_bars(console) as progress:
        result = calibrate_machine(
            start,
            recs,
            max_evaluations=max_evaluations,
            progress=progress,
            names=[str(p) for p in recordings],
        )
    sources = ", ".join(p.name for p in recordings)
    calibrated = result.calibrated_description(sources)
    lines = [f"calibrated from {start.source} to {sources} by pneufdd {__version__}"]
    lines.append(result.fit_line())
    lines += [f"{e.name}: {e.describe()}" for e in result.estimates]
    lines += result.identification_lines()
    text = machine_to_toml(calibrated, header="\n".join(lines))
    html = render_calibration_report(result, start.source, sources) if report is not None else None
    write_text_atomic(out, text)
    if report is not None and html is not None:
        write_text_atomic(report, html)
    console.print(
        f"wrote {out}: {result.fit_line()}; not informed (left at prior): "
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


def register(app: typer.Typer) -> None:
    """Attach the ``machine`` command group to ``app``."""
    app.add_typer(machine_app, name="machine")
