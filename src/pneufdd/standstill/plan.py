"""A standstill leak test planned from a machine's description (issue 35, item 2).

At standstill a machine uses no air but its leaks. Held in one valve state, the air
the supply meter reads (or the pressure the connected volume loses with the supply
shut off) is the sum of the leaks on the lines that state pressurises, plus the
supply's own. The plan chooses the states that separate the lines' leaks best:

* **home**: every actuator at its ``initial`` end (the line of that end pressurised,
  a 5/3 closed-centre valve held energised there), the vacuum valve off;
* for every actuator, the same with that actuator alone **at its other end**;
* for every 5/3 closed-centre actuator, the same with its valve **in the centre**
  (both its lines cut off from the supply, holding their air).

State ``s`` pressurises a known set of locations; row ``s`` of the incidence matrix
has a 1 where it does (``supply`` in every row). A line flow meter adds a row per
state with a 1 for its line when pressurised. The supply meter's zero error is a
column of ones too. Which locations the rows *separate* (their unit vector lies in the
row space) and which pairs of leaks cannot be told apart is
:mod:`pneufdd.standstill.separability`'s. A 5/2 valve always pressurises one of its
two lines, so the sum of its two lines' columns equals the supply's: the supply and
the lines of 5/2 valves are separated only as differences ``A - B`` of each actuator
and one common level, which a single leak (or a pair the plan marks separable) still
locates because leaks are never negative. One state per actuator end is the most any
sequence of held states can separate (every other state is a combination of these).

**Two ways to measure** (``mode``): ``flow`` with a supply flow meter (``Q_In``): the
mean flow over a window after the state settled; ``decay`` with the supply pressure
(``P_In``) alone: the supply shut-off valve is closed for a window and the decay of
the connected volume gives its leaks' total effective area
(:func:`pneufdd.identification.decay.fit_pressure_decay`, the twin's thermal model);
the plan lists each state's connected volume from the description (reservoir and
manifold, and every pressurised line: dead volume, swept volume at that end, tube).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.physics.units import psig_to_pa, slpm_to_kg_s
from pneufdd.sim import MachineDescription
from pneufdd.sim.compile import piston_areas, series_cv, tube_cv

__all__ = [
    "MODES",
    "PLAN_VERSION",
    "StandstillPlan",
    "StandstillState",
    "plan_standstill",
]

MODES = ("flow", "decay")
PLAN_VERSION = 1
SETTLE_S = 5.0
"""Time held after a state is reached before the measurement (refill, heat exchange:
5 x the twin's 1 s supply thermal time constant) [s]."""
WINDOW_S = 5.0
"""Measurement window: mean supply flow, or shut-off valve closed [s]."""
MAX_DROP_PA = 1e5
"""A decay is fitted over at most its first bar of fall (docs/physics-validation.md:
a leak whose conductance changes with pressure is an orifice over that much)."""


@dataclass(frozen=True)
class StandstillState:
    """One held state of the test.

    Attributes
    ----------
    name : str
        ``home``, ``<ACT> extended``/``retracted`` or ``<ACT> centre``.
    positions : dict of str to str
        Per actuator: ``A`` (extended, line A pressurised), ``B`` (retracted, line B
        pressurised) or ``C`` (5/3 valve in the centre, at the end of ``ends``).
    ends : dict of str to str
        Per actuator, the end it stands at: ``extended`` or ``retracted``.
    pressurised : tuple of str
        Locations connected to the supply (``supply`` and lines).
    connected_volume_m3 : float
        Reservoir, manifold and pressurised lines [m^3] (the decay's volume).
    thermal_time_s : float
        Volume-weighted heat-exchange time constant of that volume [s].
    """

    name: str
    positions: dict[str, str]
    ends: dict[str, str]
    pressurised: tuple[str, ...]
    connected_volume_m3: float
    thermal_time_s: float


@dataclass(frozen=True)
class StandstillPlan:
    """The states, what they separate and how long each is held.

    ``separable``, ``groups`` and ``pairs_separable`` come from
    :func:`pneufdd.standstill.separability.analyse_incidence`.
    """

    machine: str
    mode: str
    locations: tuple[str, ...]
    states: tuple[StandstillState, ...]
    settle_s: float
    window_s: float
    supply_flow_channel: str
    supply_pressure_channel: str
    line_flow_channels: dict[str, str]
    valve_kinds: dict[str, str]
    reference_pressure_pa: float
    supply_volume_m3: float
    line_volumes_m3: dict[str, dict[str, float]]
    meter_spans_kg_s: dict[str, float] = field(default_factory=dict)
    line_paths: dict[str, tuple[float, float]] = field(default_factory=dict)
    separable: tuple[str, ...] = ()
    groups: tuple[tuple[str, ...], ...] = ()
    pairs_separable: tuple[tuple[str, str], ...] = ()
    pairs_not_separable: tuple[tuple[str, str], ...] = ()
    rank: int = 0
    notes: tuple[str, ...] = field(default_factory=tuple)

    def incidence(self) -> FloatArray:
        """States x locations: 1 where a state pressurises a location [-]."""
        out = np.zeros((len(self.states), len(self.locations)))
        for s, state in enumerate(self.states):
            for loc in state.pressurised:
                out[s, self.locations.index(loc)] = 1.0
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``plan.json``)."""
        out = asdict(self)
        out["version"] = PLAN_VERSION
        return out

    def to_json(self) -> str:
        """``plan.json`` text."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, data: dict[str, Any], where: str = "plan") -> StandstillPlan:
        """Read a plan written by :meth:`to_dict`.

        Raises
        ------
        InputError
            For another version or a missing field, naming ``where``.
        """
        if not isinstance(data, dict) or data.get("version") != PLAN_VERSION:
            version = data.get("version") if isinstance(data, dict) else data
            raise InputError(describe(f"{where}: version", version, [PLAN_VERSION]))
        try:
            body = {k: v for k, v in data.items() if k != "version"}
            states = tuple(
                StandstillState(
                    s["name"],
                    dict(s["positions"]),
                    dict(s["ends"]),
                    tuple(s["pressurised"]),
                    float(s["connected_volume_m3"]),
                    float(s["thermal_time_s"]),
                )
                for s in body.pop("states")
            )
            for key in ("locations", "separable", "notes"):
                body[key] = tuple(body[key])
            for key in ("groups", "pairs_separable", "pairs_not_separable"):
                body[key] = tuple(tuple(g) for g in body[key])
            body["line_paths"] = {
                k: (float(v[0]), float(v[1])) for k, v in body["line_paths"].items()
            }
            return cls(states=states, **body)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(describe(f"{where}: fields", repr(exc), "a plan.json")) from exc


def _line_volumes(machine: MachineDescription) -> dict[str, dict[str, float]]:
    """Per line, its volume with the piston at each end [m^3]: dead + tube (+ swept)."""
    out = {}
    for a in machine.actuators:
        area_a, area_b, _ = piston_areas(a)
        tube = math.pi * (a.tube_inner_diameter_mm * 1e-3) ** 2 / 4.0 * a.tube_length_m
        stroke = a.stroke_mm * 1e-3
        dead_a = a.dead_volume_a_cm3 * 1e-6 + tube
        dead_b = a.dead_volume_b_cm3 * 1e-6 + tube
        out[f"{a.id}_A"] = {"extended": dead_a + area_a * stroke, "retracted": dead_a}
        out[f"{a.id}_B"] = {"extended": dead_b, "retracted": dead_b + area_b * stroke}
    return out


def _state(
    machine: MachineDescription,
    name: str,
    positions: dict[str, str],
    volumes: dict[str, dict[str, float]],
) -> StandstillState:
    """A state from its positions: what it pressurises, its volume and thermal time."""
    supply_volume = (machine.supply.reservoir_volume_l + machine.supply.manifold_volume_l) * 1e-3
    pressurised = ["supply"]
    ends = {}
    volume = supply_volume
    heat = supply_volume * machine.supply.thermal_time_s
    for a in machine.actuators:
        position = positions[a.id]
        end = "extended" if position == "A" else "retracted"
        if position == "C":
            end = "extended" if a.initial == "extended" else "retracted"
        ends[a.id] = end
        if position in "AB":
            line = f"{a.id}_{position}"
            pressurised.append(line)
            volume += volumes[line][end]
            heat += volumes[line][end] * a.thermal_time_s
    return StandstillState(name, positions, ends, tuple(pressurised), volume, heat / volume)


def plan_standstill(
    machine: MachineDescription,
    mode: str = "auto",
    settle_s: float = SETTLE_S,
    window_s: float = WINDOW_S,
) -> StandstillPlan:
    """Plan the standstill leak test of ``machine`` (module docstring).

    Parameters
    ----------
    machine : MachineDescription
        The description as written (its valve kinds, ends and sensors).
    mode : {"auto", "flow", "decay"}
        ``auto``: ``flow`` when the description has a supply flow meter, else
        ``decay`` when it has a supply pressure sensor.
    settle_s, window_s : float
        Time held before measuring, and the measurement window [s] (1-600).

    Returns
    -------
    StandstillPlan

    Raises
    ------
    InputError
        For an unknown mode, times out of range, or a machine without the sensor the
        mode needs (a supply flow meter, or a supply pressure sensor).
    """
    if mode not in ("auto", *MODES):
        raise InputError(describe("standstill mode", mode, ["auto", *MODES]))
    for what, value in (("settle time", settle_s), ("measurement window", window_s)):
        if not 1.0 <= value <= 600.0:
            raise InputError(describe(f"standstill {what}", value, "1 to 600 s"))
    flow = next(
        (s.channel for s in machine.sensors if s.kind == "flow" and s.location == "supply"), ""
    )
    pressure = next(
        (s.channel for s in machine.sensors if s.kind == "pressure" and s.location == "supply"), ""
    )
    if mode == "auto":
        mode = "flow" if flow else "decay"
    needed = flow if mode == "flow" else pressure
    if not needed:
        sensor = "a supply flow meter" if mode == "flow" else "a supply pressure sensor"
        raise InputError(
            describe(
                f"sensors of machine {machine.name!r} for a {mode} standstill test",
                [s.channel for s in machine.sensors],
                sensor,
            )
        )
    volumes = _line_volumes(machine)
    home = {a.id: "A" if a.initial == "extended" else "B" for a in machine.actuators}
    states = [_state(machine, "home", home, volumes)]
    for a in machine.actuators:
        other = "B" if home[a.id] == "A" else "A"
        name = f"{a.id} {'extended' if other == 'A' else 'retracted'}"
        states.append(_state(machine, name, {**home, a.id: other}, volumes))
    for a in machine.actuators:
        if a.valve.kind == "5/3-closed-centre":
            states.append(_state(machine, f"{a.id} centre", {**home, a.id: "C"}, volumes))
    line_meters = {
        s.location: s.channel
        for s in machine.sensors
        if s.kind == "flow" and s.location != "supply" and mode == "flow"
    }
    plan = StandstillPlan(
        machine=machine.name,
        mode=mode,
        locations=machine.leak_locations,
        states=tuple(states),
        settle_s=float(settle_s),
        window_s=float(window_s),
        supply_flow_channel=flow,
        supply_pressure_channel=pressure,
        line_flow_channels=line_meters,
        valve_kinds={a.id: a.valve.kind for a in machine.actuators},
        reference_pressure_pa=float(_set_point_pa(machine)),
        supply_volume_m3=(machine.supply.reservoir_volume_l + machine.supply.manifold_volume_l)
        * 1e-3,
        line_volumes_m3=volumes,
        meter_spans_kg_s={
            s.channel: float(slpm_to_kg_s(s.range_high - s.range_low))
            for s in machine.sensors
            if s.kind == "flow"
        },
        line_paths={
            f"{a.id}_{side}": (
                series_cv(a.valve.cv, tube_cv(a.tube_length_m, a.tube_inner_diameter_mm)),
                a.valve.xt,
            )
            for a in machine.actuators
            for side in "AB"
        },
    )
    from pneufdd.standstill.separability import with_separability

    return with_separability(plan)


def _set_point_pa(machine: MachineDescription) -> float:
    return float(psig_to_pa(machine.nominal_supply_psig))


def measurement_rows(plan: StandstillPlan) -> tuple[FloatArray, list[tuple[int, str]]]:
    """The rows of the measurement model: the supply meter (or decay) per state, and
    each line flow meter per state; ``(state index, channel)`` of each row."""
    inc = plan.incidence()
    rows = [inc[s] for s in range(len(plan.states))]
    which = [(s, plan.supply_flow_channel or plan.supply_pressure_channel)
             for s in range(len(plan.states))]  # fmt: skip
    for location, channel in plan.line_flow_channels.items():
        k = plan.locations.index(location)
        for s in range(len(plan.states)):
            row = np.zeros(len(plan.locations))
            row[k] = inc[s, k]
            rows.append(row)
            which.append((s, channel))
    return np.array(rows), which


def positions_of(states: Sequence[StandstillState], actuator: str) -> list[str]:
    """The positions one actuator takes over the states (for the program)."""
    return [s.positions[actuator] for s in states]
