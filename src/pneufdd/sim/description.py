"""Machine description: the typed, validated form of a machine TOML file.

The format is documented in ``docs/machine-format.md``. Every field is checked when a
description is parsed; an invalid one raises :class:`~pneufdd.errors.MachineError`
naming the file, the key path, the value received and what is allowed.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pneufdd.errors import MachineError, describe
from pneufdd.limits import MAX_ACTUATORS, MAX_STEPS

__all__ = [
    "ACTUATOR_KINDS",
    "DRAFT_MODEL",
    "SENSOR_KINDS",
    "SINGLE_SOLENOID_VALVES",
    "VALVE_KINDS",
    "Action",
    "Actuator",
    "MachineDescription",
    "ProgramStep",
    "Sensor",
    "Supply",
    "Vacuum",
    "Valve",
    "parse_description",
    "solenoid_slots",
]

DRAFT_MODEL = "unknown (drafted from the PLC signals; geometry assumed)"
"""The ``model`` of every drafted actuator (``pneufdd machine draft``): calibration
widens its priors and the signatures' model uncertainty varies it more on seeing it."""
CODE_DRAFT_NOTE = "(drafted; geometry from its order code, the rest assumed)"
"""The end of the ``model`` of an actuator drafted with an order code (``pneufdd machine
draft --actuator ID=CODE``): its geometry is the catalogue's, its masses, tube length
and throttles are assumed (:attr:`Actuator.code_drafted`)."""

ACTUATOR_KINDS = ("linear", "rodless", "slide", "rotary", "gripper")
VALVE_KINDS = ("5/2-bistable", "5/2-monostable", "5/3-closed-centre", "3/2-monostable")
SINGLE_SOLENOID_VALVES = ("5/2-monostable", "3/2-monostable")
"""Valves with one solenoid, ``U_<id>_A``, and a spring that returns the spool: the
3/2 drives a single-acting cylinder whose own spring returns it (B side vented)."""
SENSOR_KINDS = ("pressure", "flow", "position")
SENSOR_UNITS = {"pressure": "bar(g)", "flow": "SLPM", "position": "mm"}
METER_DIRECTIONS = ("forward", "bidirectional")
MAX_SUPPLY_PSIG = 145.0
MIN_CV = 1e-4
"""Smallest flow coefficient of a valve, line, regulator or flow control (a needle
valve nearly shut); a smaller one would divide by zero in eq. 3.8 (issue 39)."""
MAX_SENSORS = 4 * MAX_ACTUATORS + 8
"""Most sensors of a description: every line's pressure and flow, and the supply's."""
MAX_SENSOR_RANGE = 1e6
"""Largest magnitude of a sensor's range, in its unit (bar(g), SLPM or mm)."""
MIN_XT = 0.05
"""Smallest pressure-drop ratio factor xT (ISA-75.01; valves have 0.2 to 0.9)."""
"""Highest regulated supply pressure a description may ask for: 10 bar(g) [psig].

ISO 4414 machines and their standard components (ISO 15552 cylinders, ISO 5599
valves) are rated for at most 10 bar(g); most run at 6 bar(g) (87 psig)."""


class _Reader:
    """Typed access to one TOML table, building error messages with the key path."""

    def __init__(self, data: Mapping[str, Any], path: str, source: str) -> None:
        if not isinstance(data, Mapping):
            raise MachineError(describe(f"{source}: {path}", data, "a table"))
        self.data = data
        self.path = path
        self.source = source
        self.used: set[str] = set()

    def where(self, key: str) -> str:
        return f"{self.source}: {self.path}.{key}" if self.path else f"{self.source}: {key}"

    def fail(self, key: str, value: object, allowed: object) -> MachineError:
        return MachineError(describe(self.where(key), value, allowed))  # type: ignore[arg-type]

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default: object = ...) -> Any:
        self.used.add(key)
        if key not in self.data:
            if default is ...:
                raise MachineError(describe(self.where(key), None, "a value (key is required)"))
            return default
        return self.data[key]

    def number(
        self,
        key: str,
        default: float | None = None,
        low: float = -math.inf,
        high: float = math.inf,
        low_open: bool = False,
    ) -> float:
        value = self.raw(key, ... if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, value, "a number")
        v = float(value)
        bad_low = v <= low if low_open else v < low
        if not math.isfinite(v) or bad_low or v > high:
            lo = f"> {low}" if low_open else f">= {low}"
            raise self.fail(key, value, f"a finite number {lo} and <= {high}")
        return v

    def text(self, key: str, default: str | None = None, choices: Sequence[str] = ()) -> str:
        value = self.raw(key, ... if default is None else default)
        if not isinstance(value, str) or not value:
            raise self.fail(key, value, list(choices) if choices else "a non-empty string")
        if choices and value not in choices:
            raise self.fail(key, value, list(choices))
        return value

    def table(self, key: str, default: Mapping[str, Any] | None = None) -> _Reader:
        value = self.raw(key, ... if default is None else default)
        sub = f"{self.path}.{key}" if self.path else key
        return _Reader(value, sub, self.source)

    def tables(self, key: str, most: int | None = None) -> list[_Reader]:
        value = self.raw(key, [])
        if not isinstance(value, list):
            raise self.fail(key, value, "an array of tables ([[...]])")
        if most is not None and len(value) > most:
            raise self.fail(
                f"{key} (count)", f"{len(value):,} tables", f"at most {most:,} (docs/limits.md)"
            )
        sub = f"{self.path}.{key}" if self.path else key
        return [_Reader(v, f"{sub}[{i}]", self.source) for i, v in enumerate(value)]

    def strings(self, key: str, default: Sequence[str] = ()) -> list[str]:
        value = self.raw(key, list(default))
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.fail(key, value, "a list of strings")
        return list(value)

    def finish(self) -> None:
        extra = sorted(set(self.data) - self.used)
        if extra:
            raise MachineError(
                describe(
                    f"{self.source}: unknown key in {self.path or 'top level'}",
                    extra[0],
                    sorted(self.used),
                )
            )


@dataclass(frozen=True)
class Supply:
    """House air, filter-regulator, reservoir and supply line (Fig. 4.13, section 4.4.1).

    Pressures are gauge [psig], volumes [l], times [s]; conversion to SI happens in
    :mod:`pneufdd.sim.compile`.
    """

    house_psig: float
    house_drift_psi: float
    house_drift_time_s: float
    compressor_band_psi: float
    compressor_period_s: float
    regulator_set_psig: float
    regulator_cv: float
    regulator_xt: float
    regulator_supply_effect: float
    reservoir_volume_l: float
    line_cv: float
    line_xt: float
    manifold_volume_l: float
    thermal_time_s: float


@dataclass(frozen=True)
class Valve:
    """Directional valve of one actuator (section 4.2.1, Fig. 4.3, eq. 4.6)."""

    kind: str
    cv: float
    xt: float
    on_delay_s: float
    off_delay_s: float
    catalogue: str = ""
    """The valve's order code (``docs/catalogue.md``), empty when not given."""


@dataclass(frozen=True)
class Actuator:
    """One double-acting actuator, reduced to an equivalent linear piston (eq. 4.11-4.14)."""

    id: str
    kind: str
    model: str
    bore_mm: float
    rod_mm: float
    stroke_mm: float
    moving_mass_kg: float
    static_friction_n: float
    coulomb_friction_n: float
    viscous_friction_n_s_m: float
    dead_volume_a_cm3: float
    dead_volume_b_cm3: float
    thermal_time_s: float
    tube_length_m: float
    tube_inner_diameter_mm: float
    meter_out_cv_a: float
    meter_out_cv_b: float
    initial: str
    valve: Valve
    cushion_length_mm: float = 0.0
    cushion_cv_a: float = 0.0
    cushion_cv_b: float = 0.0
    catalogue: str = ""
    """The actuator's order code (``docs/catalogue.md``), empty when not given."""
    spring_preload_n: float = 0.0
    spring_rate_n_per_mm: float = 0.0
    line_pressure_psig_a: float = 0.0
    line_pressure_psig_b: float = 0.0
    booster: bool = False

    def spring_force(self, position_m: float) -> float:
        """Force of the return spring at ``position_m`` from the home end [N]."""
        return self.spring_preload_n + self.spring_rate_n_per_mm * position_m * 1e3

    @property
    def drafted(self) -> bool:
        """Whether the actuator was drafted from PLC signals (its geometry assumed)."""
        return self.model == DRAFT_MODEL

    @property
    def code_drafted(self) -> bool:
        """Whether it was drafted with an order code (geometry known, the rest assumed)."""
        return self.model.endswith(CODE_DRAFT_NOTE)


@dataclass(frozen=True)
class Vacuum:
    """Vacuum ejector with its monostable valve and vacuum switch."""

    id: str
    nozzle_diameter_mm: float
    nozzle_cd: float
    evacuation_time_s: float
    release_time_s: float
    switch_level: float
    on_delay_s: float
    off_delay_s: float
    rated_psig: float | None = None


@dataclass(frozen=True)
class Sensor:
    """One analog sensor channel (Table 3.2; section 3.4.1)."""

    channel: str
    kind: str
    location: str
    range_low: float
    range_high: float
    noise: float
    bits: int
    time_constant_s: float
    direction: str
    gain: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Action:
    """One PLC output command at the start of a step.

    ``mode`` is ``"until"`` (energise, release when ``switch`` reads 1), ``"pulse"``
    (energise for ``duration_s``), ``"hold"`` (energise until a later ``reset``) or
    ``"reset"`` (de-energise).
    """

    solenoid: str
    mode: str
    switch: str = ""
    duration_s: float = 0.0


@dataclass(frozen=True)
class ProgramStep:
    """One PLC step: commands, then wait for switches (on/off) and a dwell timer."""

    name: str
    actions: tuple[Action, ...]
    wait: tuple[str, ...]
    wait_off: tuple[str, ...]
    dwell_s: float
    required_force_n: float = 0.0
    force_actuator: str = ""
    force_direction: int = 0


@dataclass(frozen=True)
class MachineDescription:
    """A complete, validated machine description."""

    name: str
    title: str
    scan_time_s: float
    switch_window_mm: float
    temperature_c: float
    friction_scatter: float
    supply: Supply
    actuators: tuple[Actuator, ...]
    vacuum: Vacuum | None
    sensors: tuple[Sensor, ...]
    steps: tuple[ProgramStep, ...]
    raw: dict[str, Any]
    source: str

    @property
    def actuator_ids(self) -> tuple[str, ...]:
        """Actuator ids in description order."""
        return tuple(a.id for a in self.actuators)

    @property
    def leak_locations(self) -> tuple[str, ...]:
        """Every place a leak may be injected: ``supply``, ``<ACT>_A``, ``<ACT>_B``."""
        locs = ["supply"]
        for a in self.actuators:
            locs += [f"{a.id}_A", f"{a.id}_B"]
        return tuple(locs)

    @property
    def solenoids(self) -> tuple[str, ...]:
        """The PLC's valve outputs ``U_<ACT>_A/B`` (and ``U_<VAC>``), as recorded.

        A 5/2 monostable (spring-return) valve has one solenoid, ``U_<ACT>_A``; the
        other valves have two.
        """
        return tuple(name for name in solenoid_slots(self) if name is not None)

    @property
    def switches(self) -> tuple[str, ...]:
        """Digital inputs ``S_<ACT>_A/B`` (and ``S_<VAC>``)."""
        names = [f"S_{a.id}_{s}" for a in self.actuators for s in "AB"]
        if self.vacuum is not None:
            names.append(f"S_{self.vacuum.id}")
        return tuple(names)

    @property
    def nominal_supply_psig(self) -> float:
        """Nominal supply pressure: the regulator set point [psig]."""
        return self.supply.regulator_set_psig


def solenoid_slots(machine: MachineDescription) -> tuple[str | None, ...]:
    """Two solenoid slots per actuator (A, B), then the vacuum valve's.

    The simulator's valve logic addresses solenoids by slot (``2 i`` and ``2 i + 1``
    for actuator ``i``); a slot a valve does not have (the B side of a 5/2
    monostable valve) is None.
    """
    slots: list[str | None] = []
    for a in machine.actuators:
        slots.append(f"U_{a.id}_A")
        slots.append(None if a.valve.kind in SINGLE_SOLENOID_VALVES else f"U_{a.id}_B")
    if machine.vacuum is not None:
        slots.append(f"U_{machine.vacuum.id}")
    return tuple(slots)


def _supply(r: _Reader) -> Supply:
    s = Supply(
        house_psig=r.number("house_psig", low=0.0, high=250.0),
        house_drift_psi=r.number("house_drift_psi", 0.0, low=0.0, high=50.0),
        house_drift_time_s=r.number("house_drift_time_s", 60.0, low=0.01, high=1e6),
        compressor_band_psi=r.number("compressor_band_psi", 0.0, low=0.0, high=100.0),
        compressor_period_s=r.number("compressor_period_s", 60.0, low=0.01, high=1e6),
        regulator_set_psig=r.number(
            "regulator_set_psig", low=0.0, low_open=True, high=MAX_SUPPLY_PSIG
        ),
        regulator_cv=r.number("regulator_cv", low=MIN_CV, high=50.0),
        regulator_xt=r.number("regulator_xt", 0.7, low=MIN_XT, high=1.0),
        regulator_supply_effect=r.number("regulator_supply_effect", 0.0, low=0.0, high=1.0),
        reservoir_volume_l=r.number("reservoir_volume_l", low=1e-3, high=1e5),
        line_cv=r.number("line_cv", low=MIN_CV, high=50.0),
        line_xt=r.number("line_xt", 1.0, low=MIN_XT, high=1.0),
        manifold_volume_l=r.number("manifold_volume_l", low=1e-3, high=1e5),
        thermal_time_s=r.number("thermal_time_s", 1.0, low=1e-3, high=1e4),
    )
    if s.regulator_set_psig >= s.house_psig:
        raise r.fail(
            "regulator_set_psig",
            s.regulator_set_psig,
            f"< house_psig ({s.house_psig:g}): a pressure regulator only reduces pressure",
        )
    r.finish()
    return s


def _valve(r: _Reader) -> Valve:
    v = Valve(
        kind=r.text("kind", choices=VALVE_KINDS),
        cv=r.number("cv", low=MIN_CV, high=50.0),
        xt=r.number("xt", 1.0, low=MIN_XT, high=1.0),
        on_delay_s=r.number("on_delay_s", 0.020, low=0.0, high=1.0),
        off_delay_s=r.number("off_delay_s", 0.042, low=0.0, high=1.0),
        catalogue=_code(r),
    )
    r.finish()
    return v


def _code(r: _Reader) -> str:
    """The table's ``catalogue`` order code ('' when absent)."""
    code = r.raw("catalogue", "")
    if not isinstance(code, str):
        raise r.fail("catalogue", code, "an order code (docs/catalogue.md)")
    return code


def _actuator(r: _Reader) -> Actuator:
    ident = r.text("id")
    if not ident.replace("_", "").isalnum() or not ident[0].isalpha() or ident != ident.upper():
        raise r.fail("id", ident, "upper-case letters, digits and '_', starting with a letter")
    kind = r.text("kind", choices=ACTUATOR_KINDS)
    bore = r.number("bore_mm", low=0.0, low_open=True, high=1000.0)
    rod = r.number("rod_mm", 0.0, low=0.0, high=1000.0)
    if rod >= bore:
        raise r.fail("rod_mm", rod, f"< bore_mm ({bore})")
    if r.has("angle_deg"):
        angle = r.number("angle_deg", low=0.0, low_open=True, high=360.0)
        lever = r.number("lever_mm", low=0.1, high=10_000.0)
        stroke = math.radians(angle) * lever
    else:
        stroke = r.number("stroke_mm", low=0.0, low_open=True, high=10_000.0)
    window = 0.5
    if stroke <= 2 * window:
        raise r.fail("stroke_mm", stroke, "> 1 mm")
    meter_out = r.number("meter_out_cv", 0.0, low=0.0, high=50.0)
    if 0.0 < meter_out < MIN_CV:  # 0: no flow control (the line alone)
        raise r.fail("meter_out_cv", meter_out, f"0 (none) or from {MIN_CV:g} to 50")
    cushion = _cushion(r, stroke)
    act = Actuator(
        id=ident,
        kind=kind,
        model=r.text("model", "unspecified"),
        bore_mm=bore,
        rod_mm=rod,
        stroke_mm=stroke,
        moving_mass_kg=r.number("moving_mass_kg", low=1e-3, high=1e5),
        static_friction_n=r.number("static_friction_n", low=0.0, high=1e6),
        coulomb_friction_n=r.number("coulomb_friction_n", low=0.0, high=1e6),
        viscous_friction_n_s_m=r.number("viscous_friction_n_s_m", low=0.0, high=1e7),
        dead_volume_a_cm3=r.number("dead_volume_a_cm3", low=1e-3, high=1e6),
        dead_volume_b_cm3=r.number("dead_volume_b_cm3", low=1e-3, high=1e6),
        thermal_time_s=r.number("thermal_time_s", 0.5, low=1e-3, high=1e4),
        tube_length_m=r.number("tube_length_m", low=1e-3, high=100.0),
        tube_inner_diameter_mm=r.number("tube_inner_diameter_mm", low=0.1, high=50.0),
        meter_out_cv_a=r.number("meter_out_cv_a", meter_out or 50.0, low=MIN_CV, high=50.0),
        meter_out_cv_b=r.number("meter_out_cv_b", meter_out or 50.0, low=MIN_CV, high=50.0),
        initial=r.text("initial", "retracted", choices=("retracted", "extended")),
        valve=_valve(r.table("valve")),
        cushion_length_mm=cushion[0],
        cushion_cv_a=cushion[1],
        cushion_cv_b=cushion[2],
        catalogue=_code(r),
        **_energy_keys(r),
    )
    if act.valve.kind in SINGLE_SOLENOID_VALVES and act.initial != "retracted":
        raise r.fail(
            "initial",
            act.initial,
            f"'retracted' (a {act.valve.kind} valve's spring holds the actuator retracted "
            "while no solenoid is energised)",
        )
    if act.valve.kind == "3/2-monostable" and act.spring_preload_n <= 0.0:
        raise r.fail(
            "spring_preload_n",
            act.spring_preload_n,
            "> 0 N with a 3/2-monostable valve (a single-acting cylinder returns by its spring)",
        )
    r.finish()
    return act


def _cushion(r: _Reader, stroke_mm: float) -> tuple[float, float, float]:
    """End-position cushioning (Festo PPV): length [mm], screw Cv of the A and B ends."""
    length = r.number("cushion_length_mm", 0.0, low=0.0, high=stroke_mm / 2.0)
    both = r.number("cushion_cv", 0.0, low=0.0, high=50.0)
    cvs = [r.number(f"cushion_cv_{side}", both, low=0.0, high=50.0) for side in "ab"]
    if length > 0.0 and min(cvs) < MIN_CV:
        raise r.fail(
            "cushion_cv", both, f"from {MIN_CV:g} to 50 on both ends with cushion_length_mm > 0"
        )
    if length == 0.0 and max(cvs) > 0.0:
        raise r.fail("cushion_length_mm", length, "> 0 [mm] when a cushion_cv is given")
    return length, cvs[0], cvs[1]


def _energy_keys(r: _Reader) -> dict[str, Any]:
    """The optional return spring and the lines' own pressures of an ``[[actuator]]``."""
    both = r.number("line_pressure_psig", 0.0, low=0.0, high=MAX_SUPPLY_PSIG)
    keys: dict[str, Any] = {
        "spring_preload_n": r.number("spring_preload_n", 0.0, low=0.0, high=1e6),
        "spring_rate_n_per_mm": r.number("spring_rate_n_per_mm", 0.0, low=0.0, high=1e6),
        "line_pressure_psig_a": r.number(
            "line_pressure_psig_a", both, low=0.0, high=MAX_SUPPLY_PSIG
        ),
        "line_pressure_psig_b": r.number(
            "line_pressure_psig_b", both, low=0.0, high=MAX_SUPPLY_PSIG
        ),
    }
    booster = r.raw("booster", False)
    if not isinstance(booster, bool):
        raise r.fail("booster", booster, "true or false")
    if booster and keys["line_pressure_psig_a"] <= 0 and keys["line_pressure_psig_b"] <= 0:
        raise r.fail("booster", booster, "false, or true with line_pressure_psig (> 0)")
    keys["booster"] = booster
    return keys


def _vacuum(r: _Reader) -> Vacuum:
    v = Vacuum(
        id=r.text("id"),
        nozzle_diameter_mm=r.number("nozzle_diameter_mm", low=0.01, high=20.0),
        nozzle_cd=r.number("nozzle_cd", 0.8, low=0.05, high=1.0),
        evacuation_time_s=r.number("evacuation_time_s", low=1e-3, high=600.0),
        release_time_s=r.number("release_time_s", low=1e-3, high=600.0),
        switch_level=r.number("switch_level", 0.6, low=0.0, low_open=True, high=0.99),
        on_delay_s=r.number("on_delay_s", 0.020, low=0.0, high=1.0),
        off_delay_s=r.number("off_delay_s", 0.042, low=0.0, high=1.0),
        rated_psig=(
            r.number("rated_psig", low=0.0, low_open=True, high=MAX_SUPPLY_PSIG)
            if r.has("rated_psig")
            else None
        ),
    )
    r.finish()
    return v


def _sensor(r: _Reader, locations: Sequence[str], actuators: Sequence[str]) -> Sensor:
    channel = r.text("channel")
    kind = r.text("kind", choices=SENSOR_KINDS)
    allowed = list(actuators) if kind == "position" else list(locations)
    location = r.text("location", choices=allowed)
    unit = r.text("unit", SENSOR_UNITS[kind], choices=(SENSOR_UNITS[kind],))
    del unit
    rng = r.raw("range")
    if (
        not isinstance(rng, list)
        or len(rng) != 2
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in rng)
        or not -MAX_SENSOR_RANGE <= rng[0] < rng[1] <= MAX_SENSOR_RANGE  # also nan, inf
    ):
        raise r.fail(
            "range",
            rng,
            f"[low, high] with -{MAX_SENSOR_RANGE:g} <= low < high <= {MAX_SENSOR_RANGE:g}",
        )
    span = float(rng[1]) - float(rng[0])
    s = Sensor(
        channel=channel,
        kind=kind,
        location=location,
        range_low=float(rng[0]),
        range_high=float(rng[1]),
        noise=r.number("noise", 0.0, low=0.0, high=span),
        bits=int(r.number("bits", 12, low=1, high=24)),
        time_constant_s=r.number("time_constant_s", 0.0, low=0.0, high=10.0),
        direction=r.text("direction", "forward", choices=METER_DIRECTIONS),
        gain=r.number("gain", 1.0, low=0.5, high=1.5),
        offset=r.number("offset", 0.0, low=-span, high=span),
    )
    r.finish()
    return s


def _step(
    r: _Reader,
    solenoids: Sequence[str],
    switches: Sequence[str],
    index: int,
    actuators: Sequence[str] = (),
) -> ProgramStep:
    actions: list[Action] = []
    for a in r.tables("do"):
        if a.has("reset"):
            sol = a.text("reset", choices=solenoids)
            actions.append(Action(sol, "reset"))
        else:
            sol = a.text("set", choices=solenoids)
            if a.has("until"):
                actions.append(Action(sol, "until", switch=a.text("until", choices=switches)))
            elif a.has("for_s"):
                dur = a.number("for_s", low=0.0, low_open=True, high=60.0)
                actions.append(Action(sol, "pulse", duration_s=dur))
            else:
                actions.append(Action(sol, "hold"))
        a.finish()
    default_wait = [a.switch for a in actions if a.mode == "until"]
    wait = r.strings("wait", default_wait)
    for w in wait:
        if w not in switches:
            raise r.fail("wait", w, list(switches))
    wait_off = r.strings("wait_off")
    for w in wait_off:
        if w not in switches:
            raise r.fail("wait_off", w, list(switches))
    step = ProgramStep(
        name=r.text("name", f"step {index + 1}"),
        actions=tuple(actions),
        wait=tuple(wait),
        wait_off=tuple(wait_off),
        dwell_s=r.number("dwell_s", 0.0, low=0.0, high=600.0),
        **_required_force(r, actions, actuators),
    )
    if not step.actions and not step.wait and not step.wait_off and step.dwell_s == 0.0:
        raise r.fail("do", [], "at least one action, wait or dwell_s")
    r.finish()
    return step


def _required_force(
    r: _Reader, actions: Sequence[Action], actuators: Sequence[str]
) -> dict[str, Any]:
    """A force-holding step's ``required_force_n``, its actuator and direction (+1 extend).

    The actuator defaults to the one the step commands when it commands one; the
    direction to the one that command drives it (``U_<id>_A`` set: extend; ``U_<id>_B``
    set or ``U_<id>_A`` reset: retract).
    """
    force = r.number("required_force_n", 0.0, low=0.0, high=1e7)
    if not r.has("required_force_n"):
        return {}
    commanded: dict[str, int] = {}
    for act in actions:
        ident, _, side = act.solenoid[2:].rpartition("_")
        if ident and side in "AB":
            extend = (side == "A") == (act.mode != "reset")
            commanded[ident] = 1 if extend else -1
    default = next(iter(commanded)) if len(commanded) == 1 else None
    if r.has("force_actuator") or default is None:
        ident = r.text("force_actuator", choices=actuators)
    else:
        ident = default
    direction = commanded.get(ident, 0)
    if r.has("force_direction") or direction == 0:
        text = r.text("force_direction", choices=("extend", "retract"))
        direction = 1 if text == "extend" else -1
    return {"required_force_n": force, "force_actuator": ident, "force_direction": direction}


def parse_description(data: Mapping[str, Any], source: str = "<machine>") -> MachineDescription:
    """Validate a parsed TOML mapping and return a :class:`MachineDescription`.

    Parameters
    ----------
    data : mapping
        The parsed TOML document.
    source : str
        File name (or other origin) used in error messages.

    Returns
    -------
    MachineDescription

    Raises
    ------
    MachineError
        On any invalid field, naming ``source``, the key path, the value and what is allowed.

    Notes
    -----
    An ``[[actuator]]`` or its ``valve`` may give an order code (``catalogue =
    "DSBC-63-100-PPVA-N3"``, ``docs/catalogue.md``): the keys it gives (geometry and
    the family's rules for an actuator; kind, Cv and xT for a valve) default to the
    code's, and the returned description's ``raw`` mapping states them.
    """
    if isinstance(data, Mapping):
        from pneufdd.sim.order_codes import with_catalogue

        data = with_catalogue(data, source)
    top = _Reader(data, "", source)
    m = top.table("machine")
    name = m.text("name")
    title = m.text("title", name)
    scan = m.number("scan_time_s", 0.005, low=0.0, high=1.0)
    window = m.number("switch_window_mm", 1.0, low=0.0, low_open=True, high=50.0)
    temp = m.number("temperature_c", 20.0, low=-40.0, high=80.0)
    scatter = m.number("friction_scatter", 0.02, low=0.0, high=0.5)
    m.finish()
    supply = _supply(top.table("supply"))
    actuators = tuple(_actuator(a) for a in top.tables("actuator", MAX_ACTUATORS))
    if not actuators:
        raise MachineError(describe(f"{source}: actuator", [], "at least one [[actuator]]"))
    ids = [a.id for a in actuators]
    dup = {i for i, n in Counter(ids).items() if n > 1}
    if dup:
        raise MachineError(describe(f"{source}: actuator id", sorted(dup)[0], "unique ids"))
    vacuum = _vacuum(top.table("vacuum")) if top.has("vacuum") else None
    if vacuum is not None and vacuum.id in ids:
        raise MachineError(describe(f"{source}: vacuum.id", vacuum.id, "an id no actuator has"))
    locations = ["supply"] + [f"{i}_{s}" for i in ids for s in "AB"]
    sensors = tuple(_sensor(s, locations, ids) for s in top.tables("sensor", MAX_SENSORS))
    chans = [s.channel for s in sensors]
    dupc = {c for c, n in Counter(chans).items() if n > 1}
    if dupc:
        raise MachineError(describe(f"{source}: sensor channel", sorted(dupc)[0], "unique"))
    solenoids = [f"U_{a.id}_A" for a in actuators] + [
        f"U_{a.id}_B" for a in actuators if a.valve.kind not in SINGLE_SOLENOID_VALVES
    ]
    switches = [f"S_{i}_{s}" for i in ids for s in "AB"]
    if vacuum is not None:
        solenoids.append(f"U_{vacuum.id}")
        switches.append(f"S_{vacuum.id}")
    monostable = {
        f"U_{a.id}_B": (a.id, a.valve.kind)
        for a in actuators
        if a.valve.kind in SINGLE_SOLENOID_VALVES
    }
    for k, raw_step in enumerate(top.tables("step", MAX_STEPS)):
        for a, raw_action in enumerate(raw_step.tables("do")):
            for verb in ("set", "reset"):
                sol = raw_action.data.get(verb)
                if isinstance(sol, str) and sol in monostable:
                    ident, kind = monostable[sol]
                    raise MachineError(
                        describe(f"{source}: step[{k}].do[{a}].{verb}", sol, "an existing solenoid")
                        + f"; actuator {ident}'s {kind} valve has one "
                        f"solenoid, U_{ident}_A: it retracts by spring when that "
                        f'solenoid is released ({{ reset = "U_{ident}_A" }})'
                    )
    steps = tuple(_step(s, solenoids, switches, i, ids) for i, s in enumerate(top.tables("step")))
    for k, step in enumerate(steps):
        for a, act in enumerate(step.actions):
            ident, _, side = act.solenoid[2:].rpartition("_")
            if act.mode != "until" or ident not in ids:
                continue
            expected = f"S_{ident}_{'B' if side == 'A' else 'A'}"
            if act.switch != expected:
                raise MachineError(
                    describe(
                        f"{source}: step[{k}].do[{a}].until (for {act.solenoid})",
                        act.switch,
                        [expected],
                    )
                    + "; a solenoid is released at the end its actuator moves to"
                )
    if not steps:
        raise MachineError(describe(f"{source}: step", [], "at least one [[step]]"))
    top.finish()
    return MachineDescription(
        name=name,
        title=title,
        scan_time_s=scan,
        switch_window_mm=window,
        temperature_c=temp,
        friction_scatter=scatter,
        supply=supply,
        actuators=actuators,
        vacuum=vacuum,
        sensors=sensors,
        steps=steps,
        raw=dict(data),
        source=source,
    )
