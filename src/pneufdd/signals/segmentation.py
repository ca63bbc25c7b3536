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

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.events import (
    DEFAULT_SWITCH_DWELL_S,
    DEFAULT_VALVE_DWELL_S,
    RELEASE,
    StepSpec,
    _edge_present,
    _Events,
    _events,
    _windows,
    actuator_of,
    direction_of,
    held_valves,
)
from pneufdd.signals.final_step import close_final_step
from pneufdd.signals.sequence import (
    _convention_switches,
    _sequence_and_origin,
    learn_sequence,
    plc_sequence,
    sequence_from_machine,
    sequence_from_metadata,
)

__all__ = [
    "DEFAULT_SWITCH_DWELL_S",
    "DEFAULT_VALVE_DWELL_S",
    "RELEASE",
    "Cycle",
    "RecordedStep",
    "Segmentation",
    "StepSpec",
    "actuator_of",
    "direction_of",
    "held_valves",
    "learn_sequence",
    "plc_sequence",
    "segment",
    "sequence_from_machine",
    "sequence_from_metadata",
]


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
    first = frozenset(v for v in specs[0].valves if not v.endswith(RELEASE))
    ev = _events(recording, valve_min_dwell_s, switch_min_dwell_s, release, first)
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
