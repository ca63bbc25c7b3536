"""The PLC sequence of a machine: from its description, carried in a recording, or learned.

:func:`plc_sequence` decides, in one place for every consumer, where a recording's
sequence comes from: a machine description given by the caller, else the one the
recording carries in its metadata, else learned from the valve and switch signals
(:func:`learn_sequence`). :mod:`pneufdd.signals.segmentation` cuts recordings into
cycles of that sequence.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from pneufdd.array_types import IntArray
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording

if TYPE_CHECKING:
    from pneufdd.sim.description import MachineDescription

from pneufdd.signals.events import (
    DEFAULT_SWITCH_DWELL_S,
    DEFAULT_VALVE_DWELL_S,
    RELEASE,
    SWITCH_PREFIX,
    VALVE_PREFIX,
    StepSpec,
    _edge_present,
    _events,
    _windows,
    actuator_of,
    direction_of,
    held_valves,
)

__all__ = [
    "learn_sequence",
    "plc_sequence",
    "sequence_from_machine",
    "sequence_from_metadata",
]


def _convention_switches(
    valves: Iterable[str], available: Iterable[str]
) -> frozenset[tuple[str, int]]:
    have = set(available)
    out = set()
    for v in valves:
        act, direction = actuator_of(v), direction_of(v)
        target = {"extend": f"S_{act}_B", "retract": f"S_{act}_A"}.get(direction)
        if target is not None and target in have:
            out.add((target, 1))
    return frozenset(out)


# ------------------------------------------------------------ machine sequence
def _spec_from_actions(
    actions: Iterable[tuple[str, str, str]],
    wait: Iterable[str],
    wait_off: Iterable[str],
    end_gap_s: float | None = None,
) -> StepSpec:
    valves = set()
    for solenoid, mode, _switch in actions:
        valves.add(solenoid + RELEASE if mode == "reset" else solenoid)
    switches = {(w, 1) for w in wait} | {(w, 0) for w in wait_off}
    return StepSpec(frozenset(valves), frozenset(switches), end_gap_s)


def _number(value: object, default: float) -> float | None:
    """A raw TOML number (None when it is not one: the description's parser says why)."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _raw_end_gap(machine: Mapping[str, Any], step: object) -> float | None:
    """A raw step's dwell plus half the machine's PLC scan [s] (its ``end_gap_s``)."""
    table = machine.get("machine")
    scan = _number(table.get("scan_time_s") if isinstance(table, Mapping) else None, 0.005)
    dwell = _number(step.get("dwell_s") if isinstance(step, Mapping) else None, 0.0)
    if scan is None or dwell is None:
        return None
    return dwell + 0.5 * scan


def sequence_from_machine(machine: Any) -> tuple[StepSpec, ...]:
    """The step sequence of a machine description.

    Accepts a :class:`pneufdd.sim.MachineDescription` (its ``steps``, each with
    ``actions`` of ``solenoid``/``mode``/``switch``, ``wait`` and ``wait_off``) or
    the raw TOML mapping (``{"step": [{"do": [{"set": ..., "until": ...} |
    {"reset": ...}], "wait": [...], "wait_off": [...]}]}``). Each step's valve
    events are its ``set`` solenoids and the releases (``":off"``) of its
    ``reset`` solenoids; it awaits its ``wait`` switches rising (by default its
    ``until`` switches) and its ``wait_off`` switches falling. Its ``end_gap_s``
    is its ``dwell_s`` plus half the machine's ``scan_time_s`` (the PLC fires the next
    step at its next scan after the dwell).

    Examples
    --------
    >>> raw = {"step": [{"do": [{"set": "U_DNC_B", "until": "S_DNC_A"}]},
    ...                 {"do": [{"reset": "U_VAC"}], "wait_off": ["S_VAC"]}]}
    >>> [sorted(s.valves) for s in sequence_from_machine(raw)]
    [['U_DNC_B'], ['U_VAC:off']]
    >>> sorted(sequence_from_machine(raw)[0].switches)
    [('S_DNC_A', 1)]
    """
    specs = []
    if isinstance(machine, dict):
        steps = machine.get("step")
        if not isinstance(steps, list) or not steps:
            raise InputError(describe("machine description 'step'", steps, "a list of steps"))
        for k, step in enumerate(steps, start=1):
            actions, wait, wait_off = _raw_step(step, f"machine description step {k}")
            gap = _raw_end_gap(machine, step)
            specs.append(_spec_from_actions(actions, wait, wait_off, gap))
        return tuple(specs)
    steps = getattr(machine, "steps", None)
    if steps is None:
        raise InputError(
            describe("machine", type(machine).__name__, "a MachineDescription or its TOML mapping")
        )
    scan = float(getattr(machine, "scan_time_s", 0.005))
    for step in steps:
        actions = [(a.solenoid, a.mode, a.switch) for a in step.actions]
        gap = float(step.dwell_s) + 0.5 * scan
        specs.append(_spec_from_actions(actions, step.wait, step.wait_off, gap))
    return tuple(specs)


def _names(value: object, where: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise InputError(describe(where, value, "a list of channel names"))
    return list(value)


def _raw_step(step: object, where: str) -> tuple[list[tuple[str, str, str]], list[str], list[str]]:
    """Check one raw TOML step (types, required keys) and return its actions and waits."""
    if not isinstance(step, dict):
        raise InputError(describe(where, step, "a table with 'do' actions"))
    do = step.get("do", [])
    if not isinstance(do, list):
        raise InputError(describe(f"{where}: 'do'", do, "a list of actions"))
    actions = []
    for a in do:
        allowed = "{set = 'U_...', until = 'S_...'} or {reset = 'U_...'}"
        if not isinstance(a, dict):
            raise InputError(describe(f"{where}: action", a, allowed))
        if isinstance(a.get("reset"), str) and a["reset"]:
            actions.append((a["reset"], "reset", ""))
        elif isinstance(a.get("set"), str) and a["set"]:
            until = a.get("until", "")
            if not isinstance(until, str):
                raise InputError(describe(f"{where}: 'until'", until, "a switch name"))
            actions.append((a["set"], "set", until))
        else:
            raise InputError(describe(f"{where}: action", a, allowed))
    wait = _names(step.get("wait", [a[2] for a in actions if a[2]]), f"{where}: 'wait'")
    wait_off = _names(step.get("wait_off", []), f"{where}: 'wait_off'")
    return actions, wait, wait_off


def sequence_from_metadata(metadata: dict[str, Any]) -> tuple[StepSpec, ...] | None:
    """The sequence of the machine description stored in a recording's metadata.

    Looks for ``metadata["machine"]["description"]`` (the raw TOML mapping the
    simulator stores); None when there is none.
    """
    machine = metadata.get("machine")
    if isinstance(machine, dict):
        raw = machine.get("description")
        if isinstance(raw, dict) and raw.get("step"):
            return sequence_from_machine(raw)
    return None


def _sequence_and_origin(
    recording: Recording | None,
    machine: Any,
    carried: bool,
    valve_min_dwell_s: float,
    switch_min_dwell_s: float,
) -> tuple[tuple[StepSpec, ...], str]:
    """:func:`plc_sequence` and where it took it from: given, carried or learned."""
    if machine is not None:
        if isinstance(machine, dict) or hasattr(machine, "steps"):
            return sequence_from_machine(machine), "given"
        if isinstance(machine, str) or not isinstance(machine, Iterable):
            raise InputError(
                describe(
                    "machine",
                    type(machine).__name__,
                    "a MachineDescription, its TOML mapping or a sequence of StepSpec",
                )
            )
        return tuple(machine), "given"
    if recording is None:
        raise InputError(
            describe("PLC sequence", "neither a machine nor a recording", "either of them")
        )
    if carried:
        found = sequence_from_metadata(recording.metadata)
        if found is not None:
            return found, "carried"
    return learn_sequence(recording, valve_min_dwell_s, switch_min_dwell_s), "learned"


def plc_sequence(
    recording: Recording | None = None,
    machine: MachineDescription | Mapping[str, Any] | Sequence[StepSpec] | None = None,
    *,
    carried: bool = True,
    valve_min_dwell_s: float = DEFAULT_VALVE_DWELL_S,
    switch_min_dwell_s: float = DEFAULT_SWITCH_DWELL_S,
) -> tuple[StepSpec, ...]:
    """The PLC sequence of a recording: the one place that decides where it comes from.

    Order of precedence (``docs/signals.md``, "Sequence"):

    1. ``machine`` when given: a machine description (:func:`sequence_from_machine`),
       or a sequence itself (e.g. the one a reference stores), taken as it is;
    2. the machine description carried in ``recording``'s metadata
       (:func:`sequence_from_metadata`: simulated recordings carry theirs), unless
       ``carried`` is False;
    3. learned from ``recording``'s signals (:func:`learn_sequence`, with the
       debounce dwells given): the recording must start at a cycle start.

    Every consumer takes its sequence from here: :func:`segment` (and so the
    ``steps`` command, which refuses a malformed carried description first),
    :func:`pneufdd.features.feature_matrix` (carried description checked first),
    :func:`pneufdd.features.step_summaries.segment_cycles` and
    :func:`~pneufdd.features.step_summaries.machine_sequence` (the step table, so the
    diagnosis, its reference and the monitor, which segments with the sequence its
    reference stored), the evaluation campaigns and the calibration. One difference
    is kept on purpose: ``segment_cycles`` passes ``carried=False``, so a run
    segmented without a sequence (a reference of an old format that stored none)
    has its sequence learned from its own signals, as it always had. The reference
    build decides the description before this is called
    (:func:`pneufdd.diagnosis.machine.resolve_machine`: the description given, else
    the first of its recordings that carries one, parsed and checked), and without
    a description learns the sequence from its first recording. Drafting a
    description (:mod:`pneufdd.calibration.draft`) always learns, with the held
    solenoids it found itself.

    Parameters
    ----------
    recording : Recording, optional
        The recording to be segmented (needed unless ``machine`` is given).
    machine : MachineDescription, mapping or sequence of StepSpec, optional
        The machine description (or its raw TOML mapping), or the sequence itself.
    carried : bool
        Use the description carried in the recording's metadata (step 2).
    valve_min_dwell_s, switch_min_dwell_s : float
        Debounce dwell of the valve and switch channels when learning [s].

    Returns
    -------
    tuple of StepSpec

    Raises
    ------
    InputError
        Neither ``machine`` nor ``recording``; a ``machine`` of another type; or, when
        learning, a recording without a repeating pattern of at least two cycles.

    Examples
    --------
    >>> raw = {"step": [{"do": [{"set": "U_DNC_A", "until": "S_DNC_B"}]},
    ...                 {"do": [{"set": "U_DNC_B", "until": "S_DNC_A"}]}]}
    >>> [sorted(s.valves) for s in plc_sequence(machine=raw)]
    [['U_DNC_A'], ['U_DNC_B']]
    """
    return _sequence_and_origin(recording, machine, carried, valve_min_dwell_s, switch_min_dwell_s)[
        0
    ]


# -------------------------------------------------------------------- learning
def _period(codes: IntArray, min_match: float) -> int:
    """Smallest period whose repeat rate is within 2 points of the best period's."""
    n = codes.size
    periods = np.arange(1, n // 2 + 1)
    match = np.array([np.mean(codes[:-p] == codes[p:]) for p in periods])
    if match.size == 0 or match.max() < min_match:
        raise InputError(
            describe(
                "reference recording",
                f"{n} steps without a repeating pattern",
                f"at least two cycles whose step valve sets repeat (>= {min_match:.0%} of steps)",
            )
        )
    return int(periods[np.flatnonzero(match >= max(match.max() - 0.02, min_match))[0]])


def learn_sequence(
    reference: Recording,
    valve_min_dwell_s: float = DEFAULT_VALVE_DWELL_S,
    switch_min_dwell_s: float = DEFAULT_SWITCH_DWELL_S,
    min_match: float = 0.8,
    min_presence: float = 0.9,
    release: Iterable[str] | None = None,
) -> tuple[StepSpec, ...]:
    """Learn a machine's step sequence from a reference recording.

    Rule: the step signatures (sets of valves firing together) form a string; for
    each period ``p`` (up to half the steps) the repeat rate is the fraction of
    signatures equal to the one ``p`` steps later. The cycle length is the smallest
    ``p`` whose repeat rate is at least ``min_match`` and within 0.02 of the best
    rate (multiples of the true period repeat as well; shorter internal patterns
    repeat less). At least two full cycles are needed. The reference is assumed to start at
    the beginning of a cycle (the machine rests at home when the recording starts),
    so step 1 is its first valve firing. The switch edges awaited in each step are
    the edges of the switches of the actuators moving in it (``S_<ACT>_*``) that
    occur, after the step's first sample and up to the next step's start, in at
    least ``min_presence`` of the reference cycles that match the learned valve
    pattern.

    Parameters
    ----------
    reference : Recording
        A leak-free recording of at least two full cycles.
    valve_min_dwell_s, switch_min_dwell_s : float
        Debounce dwell of valve and switch channels [s].
    min_match : float
        Fraction of steps that must repeat with the period [-].
    min_presence : float
        Fraction of cycles in which a switch edge must occur to be awaited [-].
    release : iterable of str, optional
        Solenoids whose release starts a step (default: :func:`held_valves`).

    Returns
    -------
    tuple of StepSpec
    """
    released = (
        held_valves(reference, valve_min_dwell_s, switch_min_dwell_s)
        if release is None
        else frozenset(release)
    )
    ev = _events(reference, valve_min_dwell_s, switch_min_dwell_s, released)
    table: dict[frozenset[str], int] = {}
    codes = np.array([table.setdefault(s, len(table)) for s in ev.signatures], dtype=np.int64)
    p = _period(codes, min_match)
    pattern = codes[:p]
    m = codes.size // p
    blocks = codes[: m * p].reshape(m, p)
    good = np.flatnonzero(np.all(blocks == pattern, axis=1))
    lo_all, hi_all = _windows(ev)
    lo = lo_all[: m * p].reshape(m, p)[good]
    hi = hi_all[: m * p].reshape(m, p)[good]
    specs = []
    for j in range(p):
        awaited = set()
        moving = {actuator_of(v) for v in ev.signatures[j]}
        for name in ev.switch_rise:
            if actuator_of(name.replace(SWITCH_PREFIX, VALVE_PREFIX, 1)) not in moving:
                continue
            for state in (0, 1):
                if np.mean(_edge_present(ev, name, state, lo[:, j], hi[:, j])) >= min_presence:
                    awaited.add((name, state))
        specs.append(StepSpec(ev.signatures[j], frozenset(awaited)))
    return tuple(specs)


# -------------------------------------------------------------------- assembly
