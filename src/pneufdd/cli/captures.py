"""``pneufdd simulate`` writing field recordings: triggered captures, quantised channels.

The options ``--capture``, ``--files``, ``--cycles-per-file``, ``--pre-trigger-s``,
``--capture-s``, ``--start-in-step`` and ``--quantize`` (issue 33, item 6); the rules of
the cut are in :mod:`pneufdd.sim.captures`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pneufdd.cli.outputs import check_place
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording

__all__ = [
    "CAPTURE_KINDS",
    "CaptureOptions",
    "parse_quantum",
    "simulate_continuous",
    "write_field_recordings",
]

CAPTURE_KINDS = ("continuous", "triggered")
"""``--capture`` values: one continuous file (today's), or one file per triggered capture."""


def parse_quantum(text: str, recording: Recording | None = None) -> tuple[str, float]:
    """``CHANNEL=STEP`` with a unit (``P_In=0.19bar``, ``Q_In=1slpm``) -> (channel, step [SI]).

    The step is a difference, so a gauge or absolute unit gives the same step.

    Examples
    --------
    >>> name, q = parse_quantum("P_In=0.19bar")
    >>> name, round(q)
    ('P_In', 19000)
    """
    import re

    from pneufdd.physics.units import to_si

    name, sep, size = text.partition("=")
    match = re.fullmatch(r"\s*([0-9.eE+-]+)\s*(\S*)\s*", size)
    if not sep or not name.strip() or match is None:
        raise InputError(
            describe("--quantize", text, "CHANNEL=STEP with a unit, e.g. P_In=0.19bar")
        )
    try:
        value = float(match.group(1))
    except ValueError:
        raise InputError(describe("--quantize step", size, "a number and a unit")) from None
    unit = match.group(2)
    if not unit:
        raise InputError(describe("--quantize unit", text, "a unit, e.g. 0.19bar or 1slpm"))
    si, _ = to_si([0.0, value], unit, f"of --quantize {text!r}")
    step = float(si[1] - si[0])
    if not step > 0.0:
        raise InputError(describe("--quantize step", text, "> 0"))
    if recording is not None and name.strip() not in recording.analog_channels:
        raise InputError(
            describe("--quantize channel", name.strip(), list(recording.analog_channels))
        )
    return name.strip(), step


class CaptureOptions:
    """The field-recording options of ``simulate``, validated."""

    def __init__(
        self,
        capture: str,
        files: int,
        cycles_per_file: int,
        pre_trigger_s: float,
        capture_s: float | None,
        start_in_step: int | None,
        quantize: Sequence[str],
    ) -> None:
        if capture not in CAPTURE_KINDS:
            raise InputError(describe("--capture", capture, list(CAPTURE_KINDS)))
        triggered = capture == "triggered"
        if not triggered and (files != 1 or cycles_per_file != 1 or capture_s is not None):
            raise InputError(
                describe(
                    "--files/--cycles-per-file/--capture-s",
                    "given without --capture triggered",
                    "--capture triggered",
                )
            )
        if not triggered and pre_trigger_s != 0.0:
            raise InputError(describe("--pre-trigger-s", pre_trigger_s, "with --capture triggered"))
        if not (pre_trigger_s >= 0.0 and pre_trigger_s <= 60.0):
            raise InputError(describe("--pre-trigger-s", pre_trigger_s, "0 to 60 [s]"))
        if capture_s is not None and not 0.0 < capture_s <= 3600.0:
            raise InputError(describe("--capture-s", capture_s, "> 0 and <= 3600 [s]"))
        self.triggered = triggered
        self.files, self.cycles_per_file = files, cycles_per_file
        self.pre_trigger_s, self.capture_s = pre_trigger_s, capture_s
        self.start_in_step = start_in_step
        self.quanta = dict(parse_quantum(q) for q in quantize)

    @property
    def cycles(self) -> int:
        """Cycles a triggered run covers at least (the captures' own)."""
        return self.files * self.cycles_per_file


def write_field_recordings(
    options: CaptureOptions,
    machine: Any,
    leaks: Any,
    seed: int,
    max_cycle_s: float,
    schedule: Any,
    out: Path,
    overwrite: bool,
    progress: Callable[[int, int], None] | None,
    faults: Any = None,
    nuisances: Any = None,
) -> list[Path]:
    """Simulate and write the captures into the folder ``out`` (``capture_0001.parquet``, ...).

    Raises
    ------
    InputError
        If ``out`` is a file, or a capture file exists and ``overwrite`` is false.
    """
    from pneufdd.sim.captures import quantize, simulate_captures

    if out.exists() and not out.is_dir():
        raise InputError(
            describe("--out with --capture triggered", str(out), "a folder (created if missing)")
        )
    check_place("--out", out, folder=True)
    paths = [out / f"capture_{k + 1:04d}.parquet" for k in range(options.files)]
    existing = [p for p in paths if p.exists()]
    if existing and not overwrite:
        raise InputError(
            describe("--out", str(existing[0]), "a file that does not exist yet, or --overwrite")
        )
    caps = simulate_captures(
        machine,
        options.files,
        options.cycles_per_file,
        options.pre_trigger_s,
        options.capture_s,
        options.start_in_step,
        leaks=leaks,
        seed=seed,
        max_cycle_s=max_cycle_s,
        progress=progress,
        schedule=schedule,
        faults=faults,
        nuisances=nuisances,
    )
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for cap, path in zip(caps, paths, strict=True):
        if options.quanta:
            cap = quantize(cap, options.quanta)
        written.append(cap.write(path, overwrite=overwrite))
    return written


def simulate_continuous(
    options: CaptureOptions,
    machine: Any,
    cycles: int,
    leaks: Any,
    seed: int,
    progress: Callable[[int, int], None] | None,
    max_cycle_s: float,
    schedule: Any,
    faults: Any = None,
    nuisances: Any = None,
) -> Recording:
    """One continuous run, started in mid-sequence and quantised as ``options`` ask."""
    from pneufdd.sim import run_simulation
    from pneufdd.sim.captures import quantize, start_mid_sequence

    # what pneufdd.sim.simulate runs; the step starts place a start in mid-sequence
    result = run_simulation(
        machine,
        cycles,
        leaks,
        seed,
        progress,
        keep_outputs=False,
        max_cycle_s=max_cycle_s,
        schedule=schedule,
        faults=faults,
        nuisances=nuisances,
    )
    recording = result.recording
    if options.start_in_step is not None:
        recording = start_mid_sequence(recording, result.step_start, options.start_in_step)
    if options.quanta:
        recording = quantize(recording, options.quanta)
    return recording
