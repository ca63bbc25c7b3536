"""File-level pipeline: recordings -> reference model; recording -> diagnosis.

Used by :class:`pneufdd.LeakDiagnoser`, the ``pneufdd reference build`` and
``pneufdd diagnose`` commands and the demo. Errors name the file and the problem:
another machine, PLC channels that do not match the machine description, a missing
channel, too few complete cycles.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.diagnosis.captures import capture_sessions, check_duplicates, startup_of
from pneufdd.diagnosis.cost import CostSettings
from pneufdd.diagnosis.effects.twin import (
    SIGNATURE_SIZES_SLPM,
    UNCERTAINTY_PLANTS,
    compute_signatures,
    signature_spread,
)
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.diagnosis.machine import (
    MachineLike,
    check_plc_channels,
    recording_description,
    recording_machine_name,
    resolve_machine,
)
from pneufdd.diagnosis.reference.model import DetectionSettings, ReferenceModel
from pneufdd.errors import (
    ChannelError,
    InputError,
    MachineError,
    NoCompleteCycleError,
    describe,
    naming,
)
from pneufdd.features.step_summaries import (
    build_step_table,
    machine_sequence,
    segment_cycles,
    sequence_from_records,
    sequence_to_records,
    trace_offsets,
)
from pneufdd.features.step_table import StepTable
from pneufdd.physics.units import kg_s_to_slpm, slpm_to_kg_s
from pneufdd.progress import Progress, counter
from pneufdd.recording.model import Recording
from pneufdd.signals.quality import check_channels
from pneufdd.signals.quantisation import channel_quanta
from pneufdd.signals.segmentation import Cycle

__all__ = [
    "SIGNATURE_MASS_FLOWS",
    "build_reference",
    "build_reference_from_recordings",
    "diagnose_pooled",
    "diagnose_recording",
    "parse_channels",
    "pooled_table",
    "run_table",
    "signature_ladder_slpm",
]

SIGNATURE_MASS_FLOWS: tuple[float, ...] = tuple(
    float(slpm_to_kg_s(size)) for size in SIGNATURE_SIZES_SLPM
)
"""Default ladder of leak flows simulated per location, at nominal supply pressure
(3, 8, 15, 30, 50, 80, 120, 170, 230 SLPM) [kg/s]."""


def signature_ladder_slpm(mass_flows: Sequence[float]) -> tuple[float, ...]:
    """A ladder of leak flows [kg/s] as the twin's leak valves are set [SLPM].

    The twin sets its leaks by their flow at nominal supply pressure in SLPM
    (:func:`pneufdd.diagnosis.effects.twin.compute_signatures`); each flow is converted
    with :func:`pneufdd.physics.units.kg_s_to_slpm` and rounded to 12 significant
    digits, so a ladder written as ``slpm_to_kg_s(size)`` simulates exactly ``size``
    (the round trip alone leaves 50.00000000000001 of 50).

    Parameters
    ----------
    mass_flows : sequence of float
        Leak flows at nominal supply pressure [kg/s].

    Returns
    -------
    tuple of float
        The same flows [SLPM: 0 degC, 1013 mbar].

    Examples
    --------
    >>> signature_ladder_slpm(SIGNATURE_MASS_FLOWS) == SIGNATURE_SIZES_SLPM
    True
    """
    return tuple(float(f"{float(kg_s_to_slpm(float(flow))):.12g}") for flow in mass_flows)


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


def build_reference_from_recordings(
    recordings: Sequence[Recording],
    channels: Sequence[str] | None = None,
    names: Sequence[str] | None = None,
    *,
    machine: MachineLike | None = None,
    with_signatures: bool = True,
    signature_cycles: int = 2,
    signature_mass_flows: Sequence[float] | None = None,
    uncertainty_plants: int = UNCERTAINTY_PLANTS,
    settings: DetectionSettings | None = None,
    localisation: LocalisationSettings | None = None,
    progress: Progress | None = None,
    workers: int | None = None,
    startup_cycles: int | None = None,
    log: list[str] | None = None,
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
    machine : str, Path, MachineDescription or mapping, optional
        The machine's description (a built-in name is a shorthand for its
        description); needed for recordings that carry none (CSV, TDMS), and
        overrides the one simulated recordings carry. Its PLC channels must be the
        recordings'.
    with_signatures : bool
        Compute leak signatures with the machine's digital twin (needs a
        description).
    signature_cycles : int
        Simulated cycles per signature point.
    signature_mass_flows : sequence of float, optional
        Signature ladder: leak flows at nominal supply pressure
        (:data:`SIGNATURE_MASS_FLOWS` when omitted) [kg/s].
    uncertainty_plants : int
        Plausible plants drawn around the description to measure the signatures'
        model uncertainty (:func:`~pneufdd.diagnosis.effects.twin.signature_spread`);
        0 trusts the twin exactly (as if the machine matched its description).
    settings : DetectionSettings, optional
        Detector tuning.
    localisation : LocalisationSettings, optional
        Tuning of leak location and sizing, stored with the reference.
    progress : callable, optional
        ``progress(task, done, total)`` (:mod:`pneufdd.progress`).
    workers : int, optional
        Processes simulating signatures in parallel (default: one per CPU).
    startup_cycles : int, optional
        Start-up cycles left out of every recording; default: the settings' for a
        continuous run, 0 for a recording detected as a capture starting at a cycle
        start of a running machine (:mod:`pneufdd.diagnosis.captures`).
    log : list of str, optional
        Receives what the build decided (start-up cycles detected, quantised channels).

    Returns
    -------
    ReferenceModel

    Raises
    ------
    InputError
        Among others, for duplicated recordings or cycles (identical samples).
    """
    if not recordings:
        raise InputError(describe("leak-free recordings", 0, "at least one"))
    labels = (
        list(names) if names is not None else [f"recording {i + 1}" for i in range(len(recordings))]
    )
    machine_name, description = resolve_machine(recordings, labels, machine)
    first = recordings[0]
    analog = tuple(first.analog_channels) if channels is None else tuple(channels)
    for rec, where in zip(recordings, labels, strict=True):
        missing = [c for c in analog if c not in rec.analog_channels]
        if missing:
            raise ChannelError(
                f"{where} lacks analog channel(s) {missing} of the requested sensor set; "
                f"it has {list(rec.analog_channels)}"
            )
        check_channels(rec, analog, where)
    advance = counter(progress, "segmenting reference", len(recordings))
    # from the machine description when there is one, else learned from the first
    sequence = machine_sequence(description)
    settings = settings or DetectionSettings()
    if startup_cycles is not None:
        settings = replace(settings, startup_cycles=startup_cycles)
    all_cycles, sequence, settings = _reference_cycles(
        recordings, labels, analog, sequence, settings, startup_cycles, advance, log
    )
    if sequence is None:  # pragma: no cover - segment_cycles always returns one
        raise InputError(describe("PLC sequence", None, "a sequence"))
    # each step's template length: the median over recordings of its median length
    lengths = np.stack([np.diff(trace_offsets(c, TRACE_RATE_HZ)) for c in all_cycles])
    offsets = np.concatenate([[0], np.cumsum(np.median(lengths, axis=0).round().astype(np.int64))])
    tables = [
        build_step_table(
            rec, cycles, machine_name, analog, offsets if analog else None, TRACE_RATE_HZ, where
        )
        for rec, cycles, where in zip(recordings, all_cycles, labels, strict=True)
    ]
    check_duplicates(tables, labels, recordings)
    table = StepTable.concatenate(tables)
    cycle_recording = np.repeat(np.arange(len(tables)), [t.n_cycles for t in tables])
    sessions = capture_sessions(recordings, [t.n_cycles for t in tables])
    signatures = None
    if with_signatures and description is not None:
        signatures = compute_signatures(
            description,
            table.feature_names(),
            sequence=sequence,
            cycles=signature_cycles,
            channels=analog,
            sizes_slpm=signature_ladder_slpm(
                SIGNATURE_MASS_FLOWS if signature_mass_flows is None else signature_mass_flows
            ),
            progress=progress,
            workers=workers,
        )
        if uncertainty_plants > 0:
            signatures = signatures.with_plant_deviations(
                *signature_spread(
                    description,
                    signatures,
                    sequence,
                    analog,
                    cycles=signature_cycles,
                    plants=uncertainty_plants,
                    workers=workers,
                    progress=progress,
                )
            )
    try:
        return _build_model(
            table,
            description,
            signatures,
            settings,
            labels,
            sequence,
            localisation,
            cycle_recording,
            sessions,
        )
    except InputError as exc:
        raise naming(exc, ", ".join(labels)) from exc


def _reference_cycles(
    recordings: Sequence[Recording],
    labels: Sequence[str],
    analog: Sequence[str],
    sequence: Any,
    settings: DetectionSettings,
    startup_cycles: int | None,
    advance: Any,
    log: list[str] | None,
) -> tuple[list[list[Cycle]], Any, DetectionSettings]:
    """Each recording's running cycles, the sequence, and the settings with the quanta."""
    all_cycles: list[list[Cycle]] = []
    detected = 0
    for rec, where in zip(recordings, labels, strict=True):
        cycles, sequence, _ = segment_cycles(rec, sequence, where)
        startup, found = startup_of(rec, cycles[0], settings.startup_cycles, startup_cycles)
        detected += found
        all_cycles.append(running_cycles(cycles, startup))
        advance()
    quanta = channel_quanta([rec.select(list(analog)) for rec in recordings] if analog else [])
    if quanta:
        settings = replace(settings, channel_quanta=tuple(sorted(quanta.items())))
    if log is not None:
        if detected:
            log.append(
                f"{detected} of {len(recordings)} recording(s) start at a cycle start of a "
                "running machine (a solenoid held over from the previous cycle): "
                "no start-up cycle left out of them"
            )
        for name, q in sorted(quanta.items()):
            log.append(
                f"{name} is quantised in steps of {q:.4g} {recordings[0].unit(name)}: its "
                "spreads are at least one step"
            )
    return all_cycles, sequence, settings


def _build_model(
    table: StepTable,
    description: Any,
    signatures: Any,
    settings: DetectionSettings | None,
    labels: Sequence[str],
    sequence: Sequence[Any],
    localisation: LocalisationSettings | None,
    cycle_recording: npt.NDArray[np.int64],
    sessions: Sequence[int] = (),
) -> ReferenceModel:
    return ReferenceModel.build(
        table,
        machine_description=None if description is None else description.raw,
        signatures=signatures,
        settings=settings,
        sources=labels,
        sequence=sequence_to_records(sequence),
        localisation=localisation,
        cycle_recording=cycle_recording,
        recording_session=sessions,
    )


def build_reference(
    paths: Sequence[Path],
    channels: Sequence[str] | None = None,
    *,
    progress: Progress | None = None,
    tag_map: Path | None = None,
    **options: Any,
) -> ReferenceModel:
    """Read leak-free recordings from ``paths`` and build a reference model.

    ``tag_map`` is a tag-map file (:mod:`pneufdd.recording.tag_map`) for exports under
    PLC tag names; ``options`` are those of :func:`build_reference_from_recordings`.
    """
    advance = counter(progress, "reading recordings", len(paths))
    parsed = None
    if tag_map is not None:
        from pneufdd.recording.tag_map import load_tag_map

        parsed = load_tag_map(tag_map)
    recordings = []
    for path in paths:
        if parsed is None:
            recordings.append(Recording.read(Path(path)))
        else:
            from pneufdd.recording.tag_map import read_mapped

            recordings.append(read_mapped(Path(path), parsed))
        advance()
    return build_reference_from_recordings(
        recordings,
        channels,
        [str(p) for p in paths],
        progress=progress,
        **options,
    )


def running_cycles(cycles: Sequence[Cycle], startup_cycles: int) -> list[Cycle]:
    """The cycles of a running machine: ``cycles`` without the first ``startup_cycles``.

    The first cycle of a recording may follow a stop of unknown length (see
    :attr:`DetectionSettings.startup_cycles`); a recording with no more complete
    cycles than that keeps them all rather than leaving nothing to judge.
    """
    if len(cycles) > startup_cycles:
        return list(cycles[startup_cycles:])
    return list(cycles)


def run_table(model: ReferenceModel, recording: Recording, where: str = "run") -> StepTable:
    """Segment and summarise a run exactly as the reference was.

    The run's start-up cycles (:attr:`DetectionSettings.startup_cycles`) are left out.
    """
    return _run_table(model, recording, where)[0]


def _run_cycles(model: ReferenceModel, recording: Recording, where: str) -> list[Cycle]:
    """The complete cycles of a run, segmented as the reference was (all checks first).

    Raises
    ------
    MachineError
        If the run names another machine.
    ChannelError
        If the run's PLC channels are not those of the reference's machine
        description, or it lacks a channel of the reference's sensor set.
    """
    name = recording_machine_name(recording)
    if name is not None and name != model.machine:
        raise MachineError(
            describe(f"machine of {where}", name, [model.machine])
            + " (the reference was built for another machine)"
        )
    recording_description(recording, where)  # a malformed description it carries is refused
    if model.description is not None:
        check_plc_channels(recording, model.description, where)
    sequence = sequence_from_records(model.sequence) if model.sequence else None
    needed = list(model.channels)
    if sequence:
        needed += sorted({v.removesuffix(":off") for s in sequence for v in s.valves})
        needed += sorted({name for s in sequence for name, _ in s.switches} - set(needed))
    missing = [c for c in needed if c not in recording.channels]
    if missing:
        raise ChannelError(
            f"{where} lacks channel(s) {missing} that the reference needs; "
            f"it has {list(recording.channels)}"
        )
    check_channels(recording, model.channels, where)
    cycles, _, _ = segment_cycles(recording, sequence, where)
    return cycles


def _table(
    model: ReferenceModel, recording: Recording, cycles: list[Cycle], where: str
) -> StepTable:
    return build_step_table(
        recording,
        cycles,
        model.machine,
        model.channels,
        model.trace_offsets,
        model.trace_rate_hz,
        where,
    )


def _run_table(
    model: ReferenceModel, recording: Recording, where: str, startup_cycles: int | None = None
) -> tuple[StepTable, int]:
    """:func:`run_table` and the number of start-up cycles it left out."""
    cycles = _run_cycles(model, recording, where)
    startup, _ = startup_of(recording, cycles[0], model.settings.startup_cycles, startup_cycles)
    if startup and len(cycles) <= startup:
        # a start-up cycle alone is not a running machine: judging it would be a guess
        raise NoCompleteCycleError(
            describe(
                f"complete cycles of {where}",
                len(cycles),
                f"more than its {startup} start-up cycle(s) (docs/assumptions.md; "
                "--startup-cycles 0 for a capture that starts at a cycle start, "
                "--pool to judge several captures together)",
            )
        )
    running = running_cycles(cycles, startup)
    return _table(model, recording, running, where), len(cycles) - len(running)


def diagnose_pooled(
    model: ReferenceModel,
    sources: Sequence[Path | Recording],
    settings: CostSettings | None = None,
    progress: Progress | None = None,
    localisation: LocalisationSettings | None = None,
    threads: int | None = None,
    startup_cycles: int | None = None,
    tag_map: Path | None = None,
) -> tuple[StepTable, Diagnosis]:
    """Diagnose many short recordings (triggered captures) of one run as one: cycles pooled.

    Each recording leaves out its start-up cycles (``startup_cycles``, else the
    reference's, 0 for a capture detected as starting at a cycle start of a running
    machine, :mod:`pneufdd.diagnosis.captures`); a recording with no more complete
    cycles than that keeps them (as in the reference build). The run is judged on all
    the cycles together. ``tag_map``: files are exports read through this tag map
    (:mod:`pneufdd.recording.tag_map`).
    """
    parsed = None
    if tag_map is not None:
        from pneufdd.recording.tag_map import load_tag_map

        parsed = load_tag_map(tag_map)

    def read(source: Path | Recording) -> Recording:
        if isinstance(source, Recording):
            return source
        if parsed is not None:
            from pneufdd.recording.tag_map import read_mapped

            return read_mapped(Path(source), parsed)
        return Recording.read(Path(source))

    names = ["run" if isinstance(s, Recording) else str(s) for s in sources]
    left: list[int] = []
    table = pooled_table(model, (read(s) for s in sources), names, startup_cycles, progress, left)
    result = diagnose(model, table, settings, localisation, threads)
    return table, replace(result, startup_cycles=sum(left))


def pooled_table(
    model: ReferenceModel,
    recordings: Iterable[Recording],
    names: Sequence[str],
    startup_cycles: int | None = None,
    progress: Progress | None = None,
    left_out: list[int] | None = None,
) -> StepTable:
    """The cycles of many short recordings (triggered captures) of one run, pooled.

    Each recording, segmented as the reference was, leaves out its start-up cycles
    (``startup_cycles``, else the reference's, 0 for a capture detected as starting at
    a cycle start of a running machine); one with no more complete cycles than that
    keeps them. ``left_out`` receives each recording's number of cycles left out.
    ``recordings`` may be a generator: each is read when its turn comes.
    """
    advance = counter(progress, "reading and segmenting", len(names))
    tables: list[StepTable] = []
    for recording, where in zip(recordings, names, strict=True):
        cycles = _run_cycles(model, recording, where)
        startup, _ = startup_of(recording, cycles[0], model.settings.startup_cycles, startup_cycles)
        running = running_cycles(cycles, startup)
        if left_out is not None:
            left_out.append(len(cycles) - len(running))
        tables.append(_table(model, recording, running, where))
        advance()
    if not tables:
        raise InputError(describe("recordings to pool", 0, "at least one"))
    return StepTable.concatenate(tables)


def diagnose_recording(
    model: ReferenceModel,
    path: Path | Recording,
    settings: CostSettings | None = None,
    progress: Progress | None = None,
    localisation: LocalisationSettings | None = None,
    threads: int | None = None,
    startup_cycles: int | None = None,
) -> tuple[StepTable, Diagnosis]:
    """Read (if a path), segment and diagnose one run against ``model``.

    ``localisation`` overrides the reference's localisation settings; ``threads``
    is :func:`~pneufdd.diagnosis.engine.diagnose`'s (None: every core);
    ``startup_cycles`` overrides the reference's start-up cycles.
    """
    advance = counter(progress, "diagnosing", 3)
    recording = path if isinstance(path, Recording) else Recording.read(Path(path))
    where = "run" if isinstance(path, Recording) else str(path)
    advance()
    table, startup = _run_table(model, recording, where, startup_cycles)
    advance()
    result = diagnose(model, table, settings, localisation, threads)
    advance()
    return table, replace(result, startup_cycles=startup)
