"""File-level pipeline: recordings -> reference model; recording -> diagnosis.

Used by the ``pneufdd reference build`` and ``pneufdd diagnose`` commands and by the
demo. Errors name the file and the problem: another machine, a missing channel, too
few complete cycles.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rich.progress import Progress

from pneufdd.diagnosis.adapter import (
    machine_name,
    machine_sequence,
    segment_cycles,
    sequence_from_records,
    sequence_to_records,
    step_table,
    trace_offsets,
)
from pneufdd.diagnosis.cost import CostSettings
from pneufdd.diagnosis.engine import Diagnosis, diagnose
from pneufdd.diagnosis.reference import DetectionSettings, ReferenceModel
from pneufdd.diagnosis.simulated import (
    SIGNATURE_SIZES_SLPM,
    candidate_locations,
    compute_signatures,
)
from pneufdd.diagnosis.steps import StepTable
from pneufdd.errors import ChannelError, InputError, MachineError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.segmentation import Cycle, StepSpec

__all__ = [
    "build_reference",
    "build_reference_from_recordings",
    "diagnose_recording",
    "parse_channels",
    "run_table",
]

TRACE_RATE_HZ = 100.0
"""Rate of the step-aligned templates of the band method [Hz]."""


def parse_channels(text: str | None) -> tuple[str, ...] | None:
    """Parse ``--channels``: None = all analog, ``none`` = digital only, else a list.

    Examples
    --------
    >>> parse_channels("P_In, Q_In"), parse_channels("none"), parse_channels(None)
    (('P_In', 'Q_In'), (), None)
    """
    if text is None:
        return None
    if text.strip().lower() == "none":
        return ()
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise InputError(describe("--channels", text, "a comma-separated list or 'none'"))
    return names


def _read(path: Path) -> Recording:
    return Recording.read(path)


def build_reference_from_recordings(
    recordings: Sequence[Recording],
    channels: Sequence[str] | None = None,
    names: Sequence[str] | None = None,
    with_signatures: bool = True,
    signature_cycles: int = 2,
    settings: DetectionSettings | None = None,
    progress: Progress | None = None,
    signature_sizes: Sequence[float] | None = None,
) -> ReferenceModel:
    """Build a reference model from leak-free recordings already in memory.

    Parameters
    ----------
    recordings : sequence of Recording
        Leak-free recordings of one machine.
    channels : sequence of str, optional
        Analog channels of the sensor set (None: all; empty: digital only).
    names : sequence of str, optional
        Names of the recordings (files) for messages and the reference's sources.
    with_signatures : bool
        Compute leak signatures with the simulator.
    signature_cycles : int
        Simulated cycles per signature point.
    settings : DetectionSettings, optional
        Detector tuning.
    progress : rich Progress, optional
        Progress display.
    signature_sizes : sequence of float, optional
        Signature ladder [SLPM at nominal supply pressure]; the default ladder of
        :mod:`pneufdd.diagnosis.simulated` when omitted.

    Returns
    -------
    ReferenceModel
    """
    if not recordings:
        raise InputError(describe("leak-free recordings", 0, "at least one"))
    labels = (
        list(names) if names is not None else [f"recording {i + 1}" for i in range(len(recordings))]
    )
    machines = [machine_name(r, where) for r, where in zip(recordings, labels, strict=True)]
    if len(set(machines)) > 1:
        raise MachineError(
            describe(
                "machines of the reference recordings",
                dict(zip(labels, machines, strict=True)),
                "one machine",
            )
        )
    first = recordings[0]
    analog = tuple(first.analog_channels) if channels is None else tuple(channels)
    for rec, where in zip(recordings, labels, strict=True):
        missing = [c for c in analog if c not in rec.analog_channels]
        if missing:
            raise ChannelError(
                f"{where} lacks analog channel(s) {missing} of the requested sensor set; "
                f"it has {list(rec.analog_channels)}"
            )
    task = progress.add_task("segmenting reference", total=len(recordings)) if progress else None
    # from the machine description when there is one, else learned from the first
    sequence: tuple[StepSpec, ...] | None = machine_sequence(first, machines[0])
    all_cycles: list[list[Cycle]] = []
    for rec, where in zip(recordings, labels, strict=True):
        cycles, sequence, _ = segment_cycles(rec, sequence, where)
        all_cycles.append(cycles)
        if progress is not None and task is not None:
            progress.advance(task)
    assert sequence is not None
    # each step's template length: the median over recordings of its median length
    lengths = np.stack([np.diff(trace_offsets(c, TRACE_RATE_HZ)) for c in all_cycles])
    offsets = np.concatenate([[0], np.cumsum(np.median(lengths, axis=0).round().astype(np.int64))])
    tables = [
        step_table(rec, cycles, machines[0], analog, offsets if analog else None, TRACE_RATE_HZ)
        for rec, cycles in zip(recordings, all_cycles, strict=True)
    ]
    table = StepTable.concatenate(tables)
    signatures = None
    if with_signatures:
        try:
            candidate_locations(machines[0])
        except InputError:
            with_signatures = False  # the simulator does not know this machine
    if with_signatures:
        signatures = compute_signatures(
            machines[0],
            table.feature_names(),
            sequence=sequence,
            cycles=signature_cycles,
            channels=analog,
            sizes_slpm=SIGNATURE_SIZES_SLPM if signature_sizes is None else signature_sizes,
            progress=progress,
        )
    meta = first.metadata.get("machine")
    description: dict[str, Any] = dict(meta) if isinstance(meta, dict) else {"name": machines[0]}
    return ReferenceModel.build(
        table,
        machine_description=description,
        signatures=signatures,
        settings=settings,
        sources=labels,
        sequence=sequence_to_records(sequence),
    )


def build_reference(
    paths: Sequence[Path],
    channels: Sequence[str] | None = None,
    with_signatures: bool = True,
    signature_cycles: int = 2,
    settings: DetectionSettings | None = None,
    progress: Progress | None = None,
    signature_sizes: Sequence[float] | None = None,
) -> ReferenceModel:
    """Read leak-free recordings from ``paths`` and build a reference model."""
    task = progress.add_task("reading recordings", total=len(paths)) if progress else None
    recordings = []
    for path in paths:
        recordings.append(_read(Path(path)))
        if progress is not None and task is not None:
            progress.advance(task)
    return build_reference_from_recordings(
        recordings,
        channels,
        [str(p) for p in paths],
        with_signatures,
        signature_cycles,
        settings,
        progress,
        signature_sizes,
    )


def run_table(model: ReferenceModel, recording: Recording, where: str = "run") -> StepTable:
    """Segment and summarise a run exactly as the reference was.

    Raises
    ------
    MachineError
        If the run comes from another machine.
    ChannelError
        If the run lacks a channel of the reference's sensor set or sequence.
    """
    machine = machine_name(recording, where)
    if machine != model.machine:
        raise MachineError(
            describe(f"machine of {where}", machine, [model.machine])
            + " (the reference was built for another machine)"
        )
    sequence = sequence_from_records(model.sequence) if model.sequence else None
    needed = list(model.channels)
    if sequence:
        needed += sorted({v.removesuffix(":off") for s in sequence for v in s.valves})
    missing = [c for c in needed if c not in recording.channels]
    if missing:
        raise ChannelError(
            f"{where} lacks channel(s) {missing} that the reference needs; "
            f"it has {list(recording.channels)}"
        )
    cycles, _, _ = segment_cycles(recording, sequence, where)
    return step_table(
        recording, cycles, machine, model.channels, model.trace_offsets, model.trace_rate_hz
    )


def diagnose_recording(
    model: ReferenceModel,
    path: Path | Recording,
    settings: CostSettings | None = None,
    max_leaks: int = 2,
    progress: Progress | None = None,
    simulate_explanations: bool = True,
) -> tuple[StepTable, Diagnosis]:
    """Read (if a path), segment and diagnose one run against ``model``.

    ``simulate_explanations`` is passed to :func:`~pneufdd.diagnosis.engine.diagnose`.
    """
    task = progress.add_task("diagnosing", total=3) if progress else None

    def step() -> None:
        if progress is not None and task is not None:
            progress.advance(task)

    recording = path if isinstance(path, Recording) else _read(Path(path))
    where = "run" if isinstance(path, Recording) else str(path)
    step()
    table = run_table(model, recording, where)
    step()
    result = diagnose(
        model, table, settings, max_leaks=max_leaks, simulate_explanations=simulate_explanations
    )
    step()
    return table, result
