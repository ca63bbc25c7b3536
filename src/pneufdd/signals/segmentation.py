"""Segmentation of a sequenced machine's recording into cycles and steps.

Section 5.3.1.1 of the dissertation synchronises the leaked and the reference data
"by utilizing the timing signals from the sensory information of valve's logic states
or proximity sensors": each step starts with its valve firing (Fig. 3.4), and valves
firing together are parallel motions of one step. This module finds those steps from
the digital channels only, assembles them into cycles and flags every cycle that is
not a full, valid repetition of the machine's sequence.

Rules (also in ``docs/signals.md``):

* **Step start**: the rising edge of any ``U_*`` (valve solenoid) channel after
  debouncing (a solenoid on at the first sample counts as firing there), or the
  falling edge of a solenoid held across steps and released by a later step
  (:func:`held_valves`, e.g. vacuum off). Edges no more than one digital sample
  period apart (chained) belong to the same step: parallel motions.
* **Step end**: the start of the next step (of any cycle). The last step of a
  recording ends when its awaited switches are satisfied plus the median gap of the
  same step in the other cycles (:mod:`pneufdd.signals.final_step`), at the latest
  with the digital data.
* **Moving actuators**: those whose solenoid fired (``U_<ACT>_A`` extends,
  ``U_<ACT>_B`` retracts).
* **Cycle**: a run of steps whose valve sets equal the machine's sequence, step 1
  first. The sequence comes from the machine description (:class:`StepSpec` list)
  or is learned from a reference recording (:func:`learn_sequence`); which one, is
  decided in one place for every consumer: :func:`plc_sequence`.
* **Validation**: every switch edge the sequence awaits in a step (arrival at the
  end position) must occur between that step's start and the next step's start;
  otherwise the cycle is rejected with the reason (stuck or failed switch, aborted
  motion, truncated recording). Rejected cycles are never merged into good ones.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.errors import ChannelError, InputError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.digital import Edges, debounced_edges_many
from pneufdd.signals.final_step import close_final_step

if TYPE_CHECKING:
    from pneufdd.sim.description import MachineDescription

__all__ = [
    "Cycle",
    "RecordedStep",
    "Segmentation",
    "StepSpec",
    "actuator_of",
    "held_valves",
    "learn_sequence",
    "plc_sequence",
    "segment",
    "sequence_from_machine",
    "sequence_from_metadata",
]

VALVE_PREFIX = "U_"
SWITCH_PREFIX = "S_"
RELEASE = ":off"
DEFAULT_VALVE_DWELL_S = 0.015
DEFAULT_SWITCH_DWELL_S = 0.025


def actuator_of(valve: str) -> str:
    """Actuator driven by a solenoid channel.

    Examples
    --------
    >>> actuator_of("U_HMPL_V_B")
    'HMPL_V'
    >>> actuator_of("U_VAC:off")
    'VAC'
    """
    name = valve.removesuffix(RELEASE)
    name = name[len(VALVE_PREFIX) :] if name.startswith(VALVE_PREFIX) else name
    if name.endswith(("_A", "_B")):
        return name[:-2]
    return name


def direction_of(valve: str) -> str:
    """``"extend"`` for an ``_A`` solenoid, ``"retract"`` for ``_B``, else ``"other"``."""
    if valve.endswith(RELEASE):
        return "other"
    if valve.endswith("_A"):
        return "extend"
    if valve.endswith("_B"):
        return "retract"
    return "other"


@dataclass(frozen=True)
class StepSpec:
    """One step of a machine's PLC sequence.

    Attributes
    ----------
    valves : frozenset of str
        Solenoid events at the step's start (parallel motions): a channel name for
        energising (``"U_DNC_B"``), the name with ``":off"`` for the release of a held
        solenoid (``"U_VAC:off"``).
    switches : frozenset of (str, int)
        Switch edges the step awaits: ``(channel, new_state)``, e.g.
        ``("S_DNC_A", 1)`` for DNC arriving home. Empty: derive from the naming
        convention (``U_X_A`` awaits ``S_X_B`` rising, ``U_X_B`` awaits ``S_X_A``).
    """

    valves: frozenset[str]
    switches: frozenset[tuple[str, int]] = field(default_factory=frozenset)

    def describe_valves(self) -> str:
        """The valves as a sorted, readable list."""
        return "{" + ", ".join(sorted(self.valves)) + "}"


@dataclass(frozen=True)
class RecordedStep:
    """One step found in a recording.

    Attributes
    ----------
    index : int
        Position in the cycle, 1-based as in Fig. 3.4.
    start_s : float
        Time of the valve firing [s].
    end_s : float
        Start of the next step [s]; for the recording's last step, the time its
        awaited switches were satisfied plus the median gap of the same step in the
        other cycles, at most the end of the data (:mod:`pneufdd.signals.final_step`).
    valves : tuple of str
        Solenoid channels that fired.
    """

    index: int
    start_s: float
    end_s: float
    valves: tuple[str, ...]

    @property
    def duration_s(self) -> float:
        """Step duration [s]."""
        return self.end_s - self.start_s

    @property
    def actuators(self) -> tuple[str, ...]:
        """Actuators moving in this step (sorted)."""
        return tuple(sorted({actuator_of(v) for v in self.valves}))

    def motion(self, actuator: str) -> str | None:
        """``"extend"``/``"retract"`` if ``actuator`` moves in this step, else None."""
        for valve in self.valves:
            if actuator_of(valve) == actuator:
                return direction_of(valve)
        return None


@dataclass(frozen=True)
class Cycle:
    """One cycle (or a rejected stretch of steps).

    Attributes
    ----------
    index : int
        1-based position among all cycles found, complete or not.
    steps : tuple of RecordedStep
        Steps in order.
    complete : bool
        True when the cycle is a full, validated repetition of the sequence.
    reason : str or None
        Why the cycle was rejected.
    """

    index: int
    steps: tuple[RecordedStep, ...]
    complete: bool = True
    reason: str | None = None

    @property
    def start_s(self) -> float:
        """Start of the first step [s]."""
        return self.steps[0].start_s if self.steps else float("nan")

    @property
    def end_s(self) -> float:
        """End of the last step [s]."""
        return self.steps[-1].end_s if self.steps else float("nan")

    def find(self, actuator: str, motion: str) -> RecordedStep | None:
        """The first step in which ``actuator`` makes ``motion`` (extend/retract)."""
        for step in self.steps:
            if step.motion(actuator) == motion:
                return step
        return None


@dataclass(frozen=True)
class Segmentation:
    """Cycles and steps of one recording.

    Attributes
    ----------
    cycles : tuple of Cycle
        Every cycle found, in time order; rejected ones have ``complete=False``.
    sequence : tuple of StepSpec
        The sequence the cycles were matched against (with the awaited switches).
    source : str
        ``"machine"`` (given sequence) or ``"learned"``.
    """

    cycles: tuple[Cycle, ...]
    sequence: tuple[StepSpec, ...]
    source: str = "machine"

    @property
    def complete(self) -> tuple[Cycle, ...]:
        """The complete, validated cycles."""
        return tuple(c for c in self.cycles if c.complete)

    @property
    def rejected(self) -> tuple[Cycle, ...]:
        """The cycles that were flagged and skipped."""
        return tuple(c for c in self.cycles if not c.complete)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: ``{"cycles": [...], "rejected": [...]}``."""
        cycles = [
            {
                "index": c.index,
                "complete": c.complete,
                "steps": [
                    {
                        "index": s.index,
                        "start_s": round(s.start_s, 6),
                        "duration_s": round(s.duration_s, 6),
                        "actuators": list(s.actuators),
                    }
                    for s in c.steps
                ],
            }
            for c in self.cycles
        ]
        rejected = [
            {
                "index": c.index,
                "start_s": round(c.start_s, 6),
                "steps_found": len(c.steps),
                "reason": c.reason,
            }
            for c in self.rejected
        ]
        return {"cycles": cycles, "rejected": rejected}


# ---------------------------------------------------------------------- events
@dataclass(frozen=True)
class _Events:
    """Valve-firing events (steps) and debounced switch edges of a recording."""

    times: FloatArray  # step start times [s]
    signatures: tuple[frozenset[str], ...]
    end_s: float
    period_s: float
    switch_rise: dict[str, FloatArray]
    switch_fall: dict[str, FloatArray]
    switch_state: dict[str, tuple[float, float, npt.NDArray[np.uint8]]]


def _digital(recording: Recording, prefix: str) -> list[str]:
    return [n for n in recording.digital_channels if n.startswith(prefix)]


def _debounced(
    recording: Recording, names: Sequence[str], min_dwell_s: float
) -> dict[str, tuple[npt.NDArray[np.uint8], Edges]]:
    """Debounced samples and edges of digital channels, channels on one time base at once."""
    out: dict[str, tuple[npt.NDArray[np.uint8], Edges]] = {}
    for (rate, _, _), members in recording.time_bases(names).items():
        stacked = np.stack([recording.info(m).values for m in members])
        clean, found = debounced_edges_many(stacked, rate, min_dwell_s)
        for k, m in enumerate(members):
            out[m] = (clean[k], found[k])
    return out


def _valve_edges(
    recording: Recording, valve_min_dwell_s: float
) -> tuple[list[str], dict[str, tuple[FloatArray, FloatArray]], float, float]:
    valves = _digital(recording, VALVE_PREFIX)
    if not valves:
        raise ChannelError(
            "segmentation needs digital valve-solenoid channels named 'U_<ACT>_A/B'; "
            f"the recording has: {list(recording.channels)}"
        )
    out: dict[str, tuple[FloatArray, FloatArray]] = {}
    period, end_s = 0.0, 0.0
    debounced = _debounced(recording, valves, valve_min_dwell_s)
    for name in valves:
        ch = recording.info(name)
        clean, e = debounced[name]
        # A solenoid already energised at the first sample fired there (a run that
        # starts with its first step, like a simulation started at t = 0).
        rising = np.r_[0, e.rising] if clean.size and clean[0] == 1 else e.rising
        out[name] = (ch.t0 + rising / ch.rate_hz, ch.t0 + e.falling / ch.rate_hz)
        period = max(period, 1.0 / ch.rate_hz)
        end_s = max(end_s, ch.t0 + ch.duration)
    return valves, out, period, end_s


def held_valves(
    recording: Recording, valve_min_dwell_s: float = DEFAULT_VALVE_DWELL_S
) -> frozenset[str]:
    """Solenoids held energised across steps, whose release starts a step.

    Rule (learned mode): a solenoid is *held* when most of its energised periods
    contain a firing of another solenoid, i.e. it stays on while later steps start
    (a ``hold`` command released by a ``reset`` in a later step, like the vacuum
    generator). Solenoids released by their own switch or after a pulse are off
    before the next step starts.
    """
    valves, e, period, _ = _valve_edges(recording, valve_min_dwell_s)
    held = set()
    for name in valves:
        rise, fall = e[name]
        if rise.size == 0 or fall.size == 0:
            continue
        fall = fall[np.searchsorted(fall, rise[0]) :]
        n = min(rise.size, fall.size)
        if n == 0:
            continue
        others = np.sort(np.concatenate([e[v][0] for v in valves if v != name] or [np.empty(0)]))
        lo, hi = rise[:n] + period * 1.001, fall[:n] - period * 1.001
        inside = np.searchsorted(others, hi, side="right") - np.searchsorted(others, lo)
        if np.mean(inside > 0) > 0.5:
            held.add(name)
    return frozenset(held)


def _events(
    recording: Recording,
    valve_min_dwell_s: float,
    switch_min_dwell_s: float,
    release: frozenset[str] = frozenset(),
) -> _Events:
    valves, e, period, end_s = _valve_edges(recording, valve_min_dwell_s)
    names = [*valves, *(v + RELEASE for v in valves)]
    all_t: list[FloatArray] = []
    all_id: list[IntArray] = []
    for i, name in enumerate(valves):
        all_t.append(e[name][0])
        all_id.append(np.full(e[name][0].size, i, dtype=np.int64))
        if name in release:
            all_t.append(e[name][1])
            all_id.append(np.full(e[name][1].size, len(valves) + i, dtype=np.int64))
    t = np.concatenate(all_t)
    ids = np.concatenate(all_id)
    order = np.argsort(t, kind="stable")
    t, ids = t[order], ids[order]
    if t.size == 0:
        raise InputError(
            describe("valve channels", valves, "at least one valve firing (rising edge)")
        )
    new_group = np.r_[True, np.diff(t) > period * 1.001]
    starts = t[new_group]
    bounds = np.r_[np.flatnonzero(new_group), t.size]
    id_list, cut = ids.tolist(), bounds.tolist()
    signatures = tuple(
        frozenset(names[j] for j in id_list[cut[g] : cut[g + 1]]) for g in range(starts.size)
    )
    rise: dict[str, FloatArray] = {}
    fall: dict[str, FloatArray] = {}
    state: dict[str, tuple[float, float, npt.NDArray[np.uint8]]] = {}
    switches = _digital(recording, SWITCH_PREFIX)
    debounced = _debounced(recording, switches, switch_min_dwell_s)
    for name in switches:
        ch = recording.info(name)
        clean, sw = debounced[name]
        rise[name] = ch.t0 + sw.rising / ch.rate_hz
        fall[name] = ch.t0 + sw.falling / ch.rate_hz
        state[name] = (ch.t0, ch.rate_hz, clean)
        end_s = max(end_s, ch.t0 + ch.duration)
    return _Events(starts, signatures, end_s, period, rise, fall, state)


def _windows(ev: _Events) -> tuple[FloatArray, FloatArray]:
    """Start and end [s] of every step event (end = next start or end of data)."""
    return ev.times, np.r_[ev.times[1:], ev.end_s]


def _edge_present(
    ev: _Events, switch: str, state: int, lo: FloatArray, hi: FloatArray
) -> npt.NDArray[np.bool_]:
    """Whether ``switch`` reaches ``state`` inside each window ``(lo, hi]``.

    An edge at the very sample a step starts belongs to the step before; one at
    the sample the next step starts still belongs to this step (the PLC fired the
    next step on seeing it).
    """
    times = (ev.switch_rise if state == 1 else ev.switch_fall).get(switch)
    if times is None:
        return np.ones(lo.shape, dtype=bool)
    tol = 1e-9
    n = np.searchsorted(times, hi + tol, side="right") - np.searchsorted(
        times, lo + tol, side="right"
    )
    return np.asarray(n > 0)


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
    actions: Iterable[tuple[str, str, str]], wait: Iterable[str], wait_off: Iterable[str]
) -> StepSpec:
    valves = set()
    for solenoid, mode, _switch in actions:
        valves.add(solenoid + RELEASE if mode == "reset" else solenoid)
    switches = {(w, 1) for w in wait} | {(w, 0) for w in wait_off}
    return StepSpec(frozenset(valves), frozenset(switches))


def sequence_from_machine(machine: Any) -> tuple[StepSpec, ...]:
    """The step sequence of a machine description.

    Accepts a :class:`pneufdd.sim.MachineDescription` (its ``steps``, each with
    ``actions`` of ``solenoid``/``mode``/``switch``, ``wait`` and ``wait_off``) or
    the raw TOML mapping (``{"step": [{"do": [{"set": ..., "until": ...} |
    {"reset": ...}], "wait": [...], "wait_off": [...]}]}``). Each step's valve
    events are its ``set`` solenoids and the releases (``":off"``) of its
    ``reset`` solenoids; it awaits its ``wait`` switches rising (by default its
    ``until`` switches) and its ``wait_off`` switches falling.

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
            specs.append(_spec_from_actions(actions, wait, wait_off))
        return tuple(specs)
    steps = getattr(machine, "steps", None)
    if steps is None:
        raise InputError(
            describe("machine", type(machine).__name__, "a MachineDescription or its TOML mapping")
        )
    for step in steps:
        actions = [(a.solenoid, a.mode, a.switch) for a in step.actions]
        specs.append(_spec_from_actions(actions, step.wait, step.wait_off))
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
    released = held_valves(reference, valve_min_dwell_s) if release is None else frozenset(release)
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
def _reject_reason(
    seg: IntArray,
    pattern: IntArray,
    specs: Sequence[StepSpec],
    sig: Sequence[frozenset[str]],
    at_end: bool,
    at_start: bool,
) -> str:
    p = pattern.size
    if seg.size == 0:
        return "no steps"
    if seg[0] != pattern[0]:
        if at_start:
            return (
                f"recording starts mid-cycle: first valves {StepSpec(sig[0]).describe_valves()} "
                f"are not step 1's {specs[0].describe_valves()}"
            )
        return f"steps do not start with step 1's valves {specs[0].describe_valves()}"
    k = min(seg.size, p)
    mismatch = np.flatnonzero(seg[:k] != pattern[:k])
    if mismatch.size:
        j = int(mismatch[0])
        return (
            f"step {j + 1}: expected valves {specs[j].describe_valves()}, "
            f"found {StepSpec(sig[j]).describe_valves()} (aborted or out-of-sequence cycle)"
        )
    if seg.size < p:
        if at_end:
            return f"truncated: the recording ends after step {seg.size} of {p}"
        return f"aborted after step {seg.size} of {p}: the next cycle starts"
    return f"{seg.size} steps where the sequence has {p}"


def segment(
    recording: Recording,
    sequence: Sequence[StepSpec] | None = None,
    valve_min_dwell_s: float = DEFAULT_VALVE_DWELL_S,
    switch_min_dwell_s: float = DEFAULT_SWITCH_DWELL_S,
) -> Segmentation:
    """Split a recording into cycles and steps from its digital channels.

    Parameters
    ----------
    recording : Recording
        Needs ``U_*`` valve channels; ``S_*`` switch channels are used to validate.
    sequence : sequence of StepSpec, optional
        The machine's PLC sequence (:func:`sequence_from_machine`, or
        :func:`learn_sequence` on a reference recording). When omitted, the machine
        description in the recording's metadata is used if there is one
        (:func:`sequence_from_metadata`), else the sequence is learned from
        ``recording`` itself with the rule of :func:`learn_sequence`: the order of
        :func:`plc_sequence`.
    valve_min_dwell_s : float
        Debounce dwell of the valve channels [s] (default 15 ms: one 100 Hz glitch).
    switch_min_dwell_s : float
        Debounce dwell of the switch channels [s] (default 25 ms: reed chatter of
        up to two 100 Hz samples is removed).

    Returns
    -------
    Segmentation
    """
    specs, origin = _sequence_and_origin(
        recording, sequence, True, valve_min_dwell_s, switch_min_dwell_s
    )
    source = "learned" if origin == "learned" else "machine"
    if not specs:
        raise InputError(describe("sequence", "an empty sequence", "at least one step"))
    used = set().union(*(s.valves for s in specs))
    recording.require(sorted({v.removesuffix(RELEASE) for v in used}), "the machine's sequence")
    release = frozenset(v.removesuffix(RELEASE) for v in used if v.endswith(RELEASE))
    ev = _events(recording, valve_min_dwell_s, switch_min_dwell_s, release)
    specs = tuple(
        s if s.switches else replace(s, switches=_convention_switches(s.valves, ev.switch_rise))
        for s in specs
    )
    table: dict[frozenset[str], int] = {}
    pattern = np.array([table.setdefault(s.valves, len(table)) for s in specs], dtype=np.int64)
    codes = np.array([table.get(s, -1) for s in ev.signatures], dtype=np.int64)
    n, p = codes.size, pattern.size
    lo_all, hi_all = _windows(ev)

    # Candidate cycle starts and whether the full pattern follows each (vectorised).
    cand = np.flatnonzero(codes == pattern[0])
    idx = cand[:, None] + np.arange(p)[None, :]
    inside = idx < n
    full = np.all(inside & (codes[np.minimum(idx, n - 1)] == pattern[None, :]), axis=1)

    ordered = {sig: tuple(sorted(sig)) for sig in set(ev.signatures)}
    lo_list, hi_list = lo_all.tolist(), hi_all.tolist()

    def steps_of(a: int, b: int) -> tuple[RecordedStep, ...]:
        return tuple(
            RecordedStep(i - a + 1, lo_list[i], hi_list[i], ordered[ev.signatures[i]])
            for i in range(a, b)
        )

    # Switch validation of every full candidate at once.
    problems: dict[int, str] = {}
    if full.any():
        starts = cand[full]
        lo = lo_all[starts[:, None] + np.arange(p)]
        hi = hi_all[starts[:, None] + np.arange(p)]
        bad = np.zeros(starts.size, dtype=bool)
        why = [""] * starts.size
        present = _awaited_edges_present(ev, specs, lo, hi)
        for j, spec in enumerate(specs):
            for switch, state in sorted(spec.switches):
                ok = present[(j, switch, state)]
                if ok.all():
                    continue
                for r in np.flatnonzero(~ok & ~bad):
                    why[r] = _switch_reason(ev, switch, state, j, lo[r, j], hi[r, j])
                bad |= ~ok
        problems = {int(s): why[r] for r, s in enumerate(starts) if bad[r]}

    cycles: list[Cycle] = []
    pos = 0
    for c, is_full in zip(cand.tolist(), full.tolist(), strict=True):
        if c < pos or not is_full:
            continue
        if c > pos:
            reason = _reject_reason(
                codes[pos:c], pattern, specs, ev.signatures[pos:c], False, pos == 0
            )
            cycles.append(Cycle(len(cycles) + 1, steps_of(pos, c), False, reason))
        problem = problems.get(c)
        cycles.append(Cycle(len(cycles) + 1, steps_of(c, c + p), problem is None, problem))
        pos = c + p
    if pos < n:
        reason = _reject_reason(codes[pos:], pattern, specs, ev.signatures[pos:], True, pos == 0)
        cycles.append(Cycle(len(cycles) + 1, steps_of(pos, n), False, reason))
    cycles = close_final_step(cycles, specs, ev.end_s, ev.switch_rise, ev.switch_fall)
    return Segmentation(tuple(cycles), specs, source)


def _awaited_edges_present(
    ev: _Events, specs: Sequence[StepSpec], lo: FloatArray, hi: FloatArray
) -> dict[tuple[int, str, int], npt.NDArray[np.bool_]]:
    """Whether each step's awaited switch edges occur, per candidate cycle.

    ``lo``, ``hi``: step windows, shape (candidates, steps). One search per switch
    edge for all the steps that await it. Keys: (step index, switch, state).
    """
    steps_of_edge: dict[tuple[str, int], list[int]] = {}
    for j, spec in enumerate(specs):
        for edge in spec.switches:
            steps_of_edge.setdefault(edge, []).append(j)
    out: dict[tuple[int, str, int], npt.NDArray[np.bool_]] = {}
    for (switch, state), steps in steps_of_edge.items():
        ok = _edge_present(ev, switch, state, lo[:, steps], hi[:, steps])
        for k, j in enumerate(steps):
            out[(j, switch, state)] = ok[:, k]
    return out


def _switch_reason(ev: _Events, switch: str, state: int, j: int, lo: float, hi: float) -> str:
    verb = "rise" if state == 1 else "fall"
    t0, fs, values = ev.switch_state[switch]
    a = max(int(np.ceil((lo - t0) * fs - 1e-9)), 0)
    b = min(int(np.floor((hi - t0) * fs + 1e-9)) + 1, values.size)
    seen = np.unique(values[a:b])
    if b >= values.size and hi >= ev.end_s - 1e-9:
        return f"step {j + 1}: awaited switch {switch} did not {verb} before the recording ended"
    if seen.size == 1:
        return (
            f"step {j + 1}: awaited switch {switch} did not {verb} "
            f"(stuck at {int(seen[0])} throughout the step)"
        )
    return f"step {j + 1}: awaited switch {switch} did not {verb} within the step"
