"""The PLC's digital signals: valve and switch names, the steps of a sequence, edges.

The naming convention (``U_<ACT>_A/B`` solenoids, ``S_<ACT>_A/B`` switches), one step
of a machine's PLC sequence (:class:`StepSpec`) and the debounced valve-firing and
switch events a recording holds, which :mod:`pneufdd.signals.sequence` learns a
sequence from and :mod:`pneufdd.signals.segmentation` cuts into cycles and steps
(section 5.3.1.1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.errors import ChannelError, InputError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.digital import Edges, debounced_edges_many

__all__ = [
    "DEFAULT_SWITCH_DWELL_S",
    "DEFAULT_VALVE_DWELL_S",
    "RELEASE",
    "SWITCH_PREFIX",
    "VALVE_PREFIX",
    "StepSpec",
    "actuator_of",
    "direction_of",
    "held_valves",
    "target_switch",
]

VALVE_PREFIX = "U_"
SWITCH_PREFIX = "S_"
RELEASE = ":off"
DEFAULT_VALVE_DWELL_S = 0.015
DEFAULT_SWITCH_DWELL_S = 0.025
CHANGEOVER_S = 0.012
"""A held solenoid released this close to the firing of the other solenoid of its valve
(a double-solenoid valve switched over, the two outputs written in one or two PLC
scans) is released *by* that firing: one step event, never one of its own [s]."""


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


def target_switch(valve: str) -> str:
    """The switch that shows a solenoid's stroke done, by the naming convention.

    ``U_X_A`` (extend) drives to ``S_X_B``, ``U_X_B`` (retract) to ``S_X_A``, a lone
    ``U_X`` (vacuum ejector) to ``S_X``.

    Examples
    --------
    >>> target_switch("U_CYL_B"), target_switch("U_VAC")
    ('S_CYL_A', 'S_VAC')
    """
    act = actuator_of(valve)
    name = valve.removesuffix(RELEASE)
    if name.endswith("_A"):
        return f"{SWITCH_PREFIX}{act}_B"
    if name.endswith("_B"):
        return f"{SWITCH_PREFIX}{act}_A"
    return f"{SWITCH_PREFIX}{act}"


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
    end_gap_s : float, optional
        Time from the step's settling (its awaited switches satisfied) to the next
        step's start when the recording shows no next step: the description's dwell
        timer plus half a PLC scan [s]. Ends the last step of a one-cycle capture
        (:mod:`pneufdd.signals.final_step`); None when unknown (a learned sequence). Not
        part of the step's identity (equality and hash).
    """

    valves: frozenset[str]
    switches: frozenset[tuple[str, int]] = field(default_factory=frozenset)
    end_gap_s: float | None = field(default=None, compare=False)

    def describe_valves(self) -> str:
        """The valves as a sorted, readable list."""
        return "{" + ", ".join(sorted(self.valves)) + "}"


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


def _fired_at_start(
    recording: Recording,
    on_at_start: frozenset[str],
    first_firing: frozenset[str] | None,
    switch_min_dwell_s: float,
) -> frozenset[str]:
    """Which solenoids energised at the first sample fired there (rule in ``docs/signals.md``).

    With the sequence known (``first_firing``: the solenoids step 1 energises), they
    fired at t = 0 only when they are exactly step 1's; otherwise none did: they were
    on before the recording started (a triggered capture's pre-trigger, a start in
    mid-sequence). Without a sequence, a solenoid fired at t = 0 unless its actuator
    already stands where the solenoid drives it (:func:`target_switch` on at the first
    sample): then it has been holding the actuator there (a double-solenoid valve
    held by the PLC).
    """
    if not on_at_start:
        return on_at_start
    if first_firing is not None:
        return on_at_start if on_at_start == first_firing else frozenset()
    switches = sorted({target_switch(v) for v in on_at_start} & set(recording.digital_channels))
    there = {
        n
        for n, (clean, _) in _debounced(recording, switches, switch_min_dwell_s).items()
        if clean.size and clean[0] == 1
    }
    return frozenset(v for v in on_at_start if target_switch(v) not in there)


def _valve_edges(
    recording: Recording,
    valve_min_dwell_s: float,
    first_firing: frozenset[str] | None = None,
    switch_min_dwell_s: float = DEFAULT_SWITCH_DWELL_S,
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
    on_at_start = frozenset(v for v in valves if debounced[v][0].size and debounced[v][0][0] == 1)
    fired = _fired_at_start(recording, on_at_start, first_firing, switch_min_dwell_s)
    for name in valves:
        ch = recording.info(name)
        _, e = debounced[name]
        # A solenoid already energised at the first sample fired there only as the
        # run's first step (a simulation started at t = 0, a capture at its trigger).
        rising = np.r_[0, e.rising] if name in fired else e.rising
        out[name] = (ch.t0 + rising / ch.rate_hz, ch.t0 + e.falling / ch.rate_hz)
        period = max(period, 1.0 / ch.rate_hz)
        end_s = max(end_s, ch.t0 + ch.duration)
    return valves, out, period, end_s


def held_valves(
    recording: Recording,
    valve_min_dwell_s: float = DEFAULT_VALVE_DWELL_S,
    switch_min_dwell_s: float = DEFAULT_SWITCH_DWELL_S,
) -> frozenset[str]:
    """Solenoids held energised across steps, whose release starts a step.

    Rule (learned mode): a solenoid is *held* when most of its energised periods
    contain a firing of another solenoid, i.e. it stays on while later steps start
    (a ``hold`` command released by a ``reset`` in a later step, like the vacuum
    generator). Solenoids released by their own switch or after a pulse are off
    before the next step starts.
    """
    valves, e, period, _ = _valve_edges(recording, valve_min_dwell_s, None, switch_min_dwell_s)
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


def _partner(valve: str) -> str | None:
    """The other solenoid of a double-solenoid valve (``U_X_A`` <-> ``U_X_B``)."""
    if valve.endswith("_A"):
        return valve[:-2] + "_B"
    if valve.endswith("_B"):
        return valve[:-2] + "_A"
    return None


def _changeover(
    name: str, falls: FloatArray, e: dict[str, tuple[FloatArray, FloatArray]], period: float
) -> FloatArray:
    """Release times of ``name``, moved onto its partner's firing within :data:`CHANGEOVER_S`."""
    partner = _partner(name)
    if partner is None or partner not in e or falls.size == 0 or e[partner][0].size == 0:
        return falls
    rises = e[partner][0]
    k = np.clip(np.searchsorted(rises, falls), 1, rises.size) - 1
    k2 = np.minimum(k + 1, rises.size - 1)
    nearest = np.where(np.abs(rises[k2] - falls) < np.abs(rises[k] - falls), rises[k2], rises[k])
    gap = np.abs(nearest - falls)
    # edges within one sample period are one step already (and keep their times)
    return np.where((gap > period * 1.001) & (gap <= CHANGEOVER_S), nearest, falls)


def _events(
    recording: Recording,
    valve_min_dwell_s: float,
    switch_min_dwell_s: float,
    release: frozenset[str] = frozenset(),
    first_firing: frozenset[str] | None = None,
) -> _Events:
    valves, e, period, end_s = _valve_edges(
        recording, valve_min_dwell_s, first_firing, switch_min_dwell_s
    )
    names = [*valves, *(v + RELEASE for v in valves)]
    all_t: list[FloatArray] = []
    all_id: list[IntArray] = []
    for i, name in enumerate(valves):
        all_t.append(e[name][0])
        all_id.append(np.full(e[name][0].size, i, dtype=np.int64))
        if name in release:
            all_t.append(_changeover(name, e[name][1], e, period))
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
