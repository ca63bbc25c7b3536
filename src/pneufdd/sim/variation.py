"""Plant variation: a machine as it is built, drawn around its catalogue description.

A digital twin is built from catalogue data; the real machine differs from it. A
valve's flow capacity may be 15 % off its catalogue value (ISO 6358, JIS B 8390 and
ANSI/NFPA T3.21.3 all allow that, dissertation section 4.4.2), seals rub harder or
softer, throttles are set by hand, sensors carry calibration errors. Measuring a
diagnosis on recordings of its own twin is the "inverse crime": the model error that
dominates in the field is absent. :func:`vary_machine` returns a **plant**: the same
description with every physical parameter drawn around its value.

The model (``docs/plant-variation.md`` has the table of every parameter, its spread
and the source of that spread):

* A *relative* parameter ``x`` (flow capacities, friction, volumes, times, masses)
  becomes ``x (1 + T) ** (scale * z / 2)``: log-normal, median ``x``, truncated at
  two standard deviations ``z`` in [-2, 2], so that at ``scale`` 1 the plant lies
  within ``x / (1 + T)`` and ``x (1 + T)`` (within +-T) and at ``scale`` 2 within
  ``(1 + T) ** +-2`` (twice the spread of ``ln x``). A value of zero stays zero.
* An *absolute* parameter (regulator set point [psi], sensor gain [-]) or a
  *span* parameter (sensor offset, a fraction of the sensor's range) becomes
  ``x + scale * z * B / 2`` with the same truncated normal ``z``: within +-B at
  ``scale`` 1.
* ``z`` comes from a uniform number of its own per parameter: 53 bits of the SHA-256
  hash of ``seed`` and the parameter's key path (e.g. ``actuator.DNC.valve.cv``),
  through the inverse normal CDF. No random state is shared, so there is no drawing
  order to keep: a parameter's draw depends only on ``seed`` and its key path, never
  on the order of the file or on which other parameters exist; adding a parameter
  (or an actuator) later leaves every other draw unchanged, and ``scale`` 2 moves
  each parameter the same way as ``scale`` 1, twice as far.
* Static and Coulomb friction of one actuator share one draw (one seal, one
  lubrication state: their ratio, which decides stick-slip, is kept).
* Values are clipped to the limits of the format (``docs/machine-format.md``):
  ``xt`` <= 1, gains 0.5-1.5, the set point below the house pressure, ...; varied
  values are rounded to 5 significant digits (at most 0.005 % of a value, far
  below any spread) so that the written TOML is readable and reads back exactly.
* Not varied: names, ids, kinds, the PLC sequence, bores, rods, strokes (the order
  code states them), sensor ranges, bits, noise and time constants, leak locations.

The plant keeps the machine's name: it is diagnosed with the description as written.
"""

from __future__ import annotations

import copy
import hashlib
import math
import operator
import os
import statistics
from dataclasses import dataclass, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any, Literal

import numpy as np
import tomli_w

from pneufdd.errors import FileExistsInputError, InputError, MachineError, describe
from pneufdd.files import write_text_atomic
from pneufdd.physics.constants import PSI
from pneufdd.sim.description import (
    MAX_SUPPLY_PSIG,
    Actuator,
    MachineDescription,
    Sensor,
    Supply,
    Vacuum,
    parse_description,
)
from pneufdd.sim.loading import builtin_machines, load_machine

__all__ = [
    "MAX_SCALE",
    "SPREADS",
    "TRUNCATION",
    "ParameterChange",
    "Spread",
    "machine_to_toml",
    "noise_free",
    "parameter_changes",
    "vary_machine",
    "write_machine",
]

MAX_SCALE = 5.0
"""Largest accepted ``scale``: at 5 a +-15 % tolerance already spans a factor 0.5-2."""

TRUNCATION = 2.0
"""Every draw is a standard normal truncated to [-TRUNCATION, TRUNCATION]."""

SIGNIFICANT_DIGITS = 5


@dataclass(frozen=True)
class Spread:
    """How one parameter of a real machine scatters around its catalogue value.

    Attributes
    ----------
    kind : {"relative", "absolute", "span"}
        ``relative``: log-normal factor within ``(1 + bound) ** +-scale``;
        ``absolute``: shift within ``+-scale * bound`` in the parameter's unit;
        ``span``: shift within ``+-scale * bound`` times the sensor's range span.
    bound : float
        The tolerance at ``scale`` 1: relative [-], absolute [unit], or fraction of
        span [-].
    source : str
        Where the tolerance comes from (a standard, a datasheet, or an engineering
        assumption; the reasoning is in ``docs/plant-variation.md``).
    """

    kind: Literal["relative", "absolute", "span"]
    bound: float
    source: str

    @property
    def sigma(self) -> float:
        """Standard deviation of the untruncated normal at ``scale`` 1.

        ``ln(1 + bound) / 2`` of ``ln x`` for relative spreads, ``bound / 2`` otherwise;
        after truncation at two of them the standard deviation is
        :func:`truncated_sd` times this.
        """
        if self.kind == "relative":
            return math.log1p(self.bound) / TRUNCATION
        return self.bound / TRUNCATION


_ISO6358 = "ISO 6358 / JIS B 8390 / ANSI/NFPA T3.21.3 flow-rate tolerance (section 4.4.2)"
_EA = "engineering assumption"

SPREADS: dict[str, Spread] = {
    "machine.switch_window_mm": Spread("relative", 0.30, _EA + " (switch mounted by hand)"),
    "supply.house_psig": Spread("relative", 0.05, _EA + " (compressor setting, site)"),
    "supply.house_drift_psi": Spread("relative", 0.30, _EA + " (site air network)"),
    "supply.house_drift_time_s": Spread("relative", 0.30, _EA + " (site air network)"),
    "supply.compressor_band_psi": Spread("relative", 0.30, _EA + " (site air network)"),
    "supply.compressor_period_s": Spread("relative", 0.30, _EA + " (site air network)"),
    "supply.regulator_set_psig": Spread(
        "absolute", 0.16e5 / PSI, "EN 837-1 class 1.6 gauge, 0-10 bar: +-0.16 bar"
    ),
    "supply.regulator_cv": Spread("relative", 0.15, _ISO6358),
    "supply.regulator_xt": Spread("relative", 0.10, _EA + " (catalogue b is representative)"),
    "supply.regulator_supply_effect": Spread("relative", 0.30, _EA + " (typical datasheet)"),
    "supply.reservoir_volume_l": Spread("relative", 0.05, _EA + " (welded vessel)"),
    "supply.line_cv": Spread("relative", 0.20, _ISO6358 + " + fittings and tubing"),
    "supply.line_xt": Spread("relative", 0.10, _EA + " (catalogue b is representative)"),
    "supply.manifold_volume_l": Spread("relative", 0.20, _EA + " (tubing cut on site)"),
    "supply.thermal_time_s": Spread("relative", 0.30, _EA + " (convection correlations)"),
    "actuator.moving_mass_kg": Spread("relative", 0.10, _EA + " (payload, brackets)"),
    "actuator.friction": Spread("relative", 0.30, _EA + " (seal, lubrication, humidity)"),
    "actuator.viscous_friction_n_s_m": Spread("relative", 0.30, _EA + " (lubricant film)"),
    "actuator.dead_volume_cm3": Spread("relative", 0.20, _EA + " (cushion, port fittings)"),
    "actuator.thermal_time_s": Spread("relative", 0.30, _EA + " (convection correlations)"),
    "actuator.tube_length_m": Spread("relative", 0.20, _EA + " (tubing cut on site)"),
    "actuator.meter_out_cv": Spread("relative", 0.50, _EA + " (needle valve set by hand)"),
    "actuator.cushion_cv": Spread("relative", 0.50, _EA + " (cushion screw set by hand)"),
    "valve.cv": Spread("relative", 0.15, _ISO6358),
    "valve.xt": Spread("relative", 0.10, _EA + " (catalogue b is representative)"),
    "valve.switching_delay_s": Spread("relative", 0.20, _EA + " (coil voltage, temperature)"),
    "vacuum.nozzle_diameter_mm": Spread("relative", 0.03, _EA + " (nozzle bore tolerance)"),
    "vacuum.nozzle_cd": Spread("relative", 0.05, _EA + " (edge quality)"),
    "vacuum.time_constant_s": Spread("relative", 0.30, _EA + " (suction cup, workpiece)"),
    "vacuum.switch_level": Spread("relative", 0.10, _EA + " (vacuum switch set by hand)"),
    "vacuum.switching_delay_s": Spread("relative", 0.20, _EA + " (coil voltage, temperature)"),
    "sensor.pressure.gain": Spread(
        "absolute", 0.010, "Festo SPAU datasheet: +-1.5 % FS, +-0.05 % FS/K over 10 K"
    ),
    "sensor.pressure.offset": Spread(
        "span", 0.010, "Festo SPAU datasheet: +-1.5 % FS, +-0.05 % FS/K over 10 K"
    ),
    "sensor.flow.gain": Spread("absolute", 0.030, "Festo SFAM/SFAB manual: span error +-3 %"),
    "sensor.flow.offset": Spread("span", 0.003, "Festo SFAM/SFAB manual: zero point +-0.3 % FS"),
    "sensor.position.gain": Spread("absolute", 0.005, _EA + " (LVDT linearity class)"),
    "sensor.position.offset": Spread("span", 0.005, _EA + " (LVDT mounting, zeroing)"),
}
"""Every varied parameter (group) and its spread at ``scale`` 1."""


def truncated_sd() -> float:
    """Standard deviation of a standard normal truncated to +-:data:`TRUNCATION` [-].

    Examples
    --------
    >>> round(truncated_sd(), 4)
    0.8796
    """
    a = TRUNCATION
    norm = statistics.NormalDist()
    mass = norm.cdf(a) - norm.cdf(-a)
    return math.sqrt(1.0 - 2.0 * a * norm.pdf(a) / mass)


def _check_scale(scale: object) -> float:
    allowed = f"a number from 0 to {MAX_SCALE:g} (0: the description itself, 1: a real machine)"
    if isinstance(scale, bool) or not isinstance(scale, int | float | np.floating | np.integer):
        raise InputError(describe("scale", scale, allowed))
    value = float(scale)
    if not math.isfinite(value) or value < 0.0 or value > MAX_SCALE:
        raise InputError(describe("scale", scale, allowed))
    return value


def _check_seed(seed: object) -> int:
    allowed = "a non-negative integer"
    if isinstance(seed, bool):
        raise InputError(describe("seed", seed, allowed))
    try:
        value = operator.index(seed)  # type: ignore[arg-type]
    except TypeError:
        raise InputError(describe("seed", seed, allowed)) from None
    if value < 0:
        raise InputError(describe("seed", seed, allowed))
    return int(value)


def _round(value: float) -> float:
    return float(f"{value:.{SIGNIFICANT_DIGITS}g}")


class _Draws:
    """One truncated-normal draw per key path, independent of the order of the calls."""

    def __init__(self, scale: float, seed: int) -> None:
        self.scale = scale
        self.seed = seed
        self._norm = statistics.NormalDist()
        self._low = self._norm.cdf(-TRUNCATION)
        self._high = self._norm.cdf(TRUNCATION)

    def z(self, key: str) -> float:
        digest = hashlib.sha256(f"pneufdd-plant seed={self.seed} key={key}".encode()).digest()
        u = (int.from_bytes(digest[:8], "big") >> 11) * 2.0**-53  # uniform in [0, 1), 53 bits
        return self._norm.inv_cdf(self._low + u * (self._high - self._low))

    def value(
        self,
        key: str,
        value: float,
        spread: Spread,
        low: float = 0.0,
        high: float = math.inf,
        span: float = 1.0,
    ) -> float:
        """``value`` moved by the draw of ``key`` (unchanged at scale 0), clipped, rounded."""
        if self.scale == 0.0:
            return value
        z = self.z(key)
        if spread.kind == "relative":
            new = value * math.exp(self.scale * z * spread.sigma)
        else:
            new = value + self.scale * z * spread.sigma * (span if spread.kind == "span" else 1)
        return _round(min(max(new, low), high))


def _put(table: dict[str, Any], key: str, old: float, new: float) -> None:
    """Write ``new`` where it differs from ``old`` (an unchanged value stays as written)."""
    if new != old:
        table[key] = new


def _vary_supply(table: dict[str, Any], s: Supply, d: _Draws) -> None:
    relative = {
        "house_drift_psi": 50.0,
        "house_drift_time_s": math.inf,
        "compressor_band_psi": 100.0,
        "compressor_period_s": math.inf,
        "regulator_cv": 50.0,
        "regulator_xt": 1.0,
        "regulator_supply_effect": 1.0,
        "reservoir_volume_l": math.inf,
        "line_cv": 50.0,
        "line_xt": 1.0,
        "manifold_volume_l": math.inf,
        "thermal_time_s": math.inf,
    }
    for key, high in relative.items():
        old = float(getattr(s, key))
        _put(table, key, old, d.value(f"supply.{key}", old, SPREADS[f"supply.{key}"], high=high))
    house = d.value("supply.house_psig", s.house_psig, SPREADS["supply.house_psig"], high=250.0)
    _put(table, "house_psig", s.house_psig, house)
    # a regulator only reduces pressure: keep the set point below the (varied) house air
    gap = min(1.0, (s.house_psig - s.regulator_set_psig) / 2.0)
    setp = d.value(
        "supply.regulator_set_psig",
        s.regulator_set_psig,
        SPREADS["supply.regulator_set_psig"],
        low=0.5 * s.regulator_set_psig,
        high=min(MAX_SUPPLY_PSIG, house - gap),
    )
    _put(table, "regulator_set_psig", s.regulator_set_psig, setp)


def _replace_key(table: dict[str, Any], old_key: str, new: dict[str, float]) -> dict[str, Any]:
    """``table`` with ``old_key`` replaced by the items of ``new`` at its position."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        if key == old_key:
            out.update(new)
        elif key not in new:
            out[key] = value
    for key, value in new.items():
        out.setdefault(key, value)
    return out


def _vary_cushion(table: dict[str, Any], a: Actuator, d: _Draws) -> None:
    """End-position cushion screws (Festo PPV), where described: one draw per end."""
    if a.cushion_length_mm <= 0.0:
        return
    spread = SPREADS["actuator.cushion_cv"]
    table.pop("cushion_cv", None)  # the two screws are set independently
    for key in ("cushion_cv_a", "cushion_cv_b"):
        old = float(getattr(a, key))
        table[key] = d.value(f"actuator.{a.id}.{key}", old, spread, high=50.0)


def _vary_actuator(table: dict[str, Any], a: Actuator, d: _Draws) -> dict[str, Any]:
    p = f"actuator.{a.id}"
    _put(
        table,
        "moving_mass_kg",
        a.moving_mass_kg,
        d.value(f"{p}.moving_mass_kg", a.moving_mass_kg, SPREADS["actuator.moving_mass_kg"]),
    )
    for key in ("static_friction_n", "coulomb_friction_n"):  # one seal: one shared draw
        old = float(getattr(a, key))
        _put(table, key, old, d.value(f"{p}.friction", old, SPREADS["actuator.friction"]))
    spread = SPREADS["actuator.viscous_friction_n_s_m"]
    old = a.viscous_friction_n_s_m
    _put(table, "viscous_friction_n_s_m", old, d.value(f"{p}.viscous_friction_n_s_m", old, spread))
    for key in ("dead_volume_a_cm3", "dead_volume_b_cm3"):
        old = float(getattr(a, key))
        _put(table, key, old, d.value(f"{p}.{key}", old, SPREADS["actuator.dead_volume_cm3"]))
    old = a.thermal_time_s
    spread = SPREADS["actuator.thermal_time_s"]
    _put(table, "thermal_time_s", old, d.value(f"{p}.thermal_time_s", old, spread))
    old = a.tube_length_m
    spread = SPREADS["actuator.tube_length_m"]
    _put(table, "tube_length_m", old, d.value(f"{p}.tube_length_m", old, spread, high=100.0))
    # one-way flow controls: only where the description has one (absent or 0 = free
    # exhaust); one setting for both lines becomes two needle valves set independently
    single = float(table.get("meter_out_cv", 0.0)) > 0.0
    throttles: dict[str, float] = {}
    for key in ("meter_out_cv_a", "meter_out_cv_b"):
        if key in table or single:
            old = float(getattr(a, key))
            spread = SPREADS["actuator.meter_out_cv"]
            throttles[key] = d.value(f"{p}.{key}", old, spread, high=50.0)
    if single and any(v != getattr(a, k) for k, v in throttles.items()):
        table = _replace_key(table, "meter_out_cv", throttles)
    else:
        for key, value in throttles.items():
            _put(table, key, float(getattr(a, key)), value)
    _vary_cushion(table, a, d)
    valve = table["valve"]
    v = a.valve
    _put(valve, "cv", v.cv, d.value(f"{p}.valve.cv", v.cv, SPREADS["valve.cv"], high=50.0))
    _put(valve, "xt", v.xt, d.value(f"{p}.valve.xt", v.xt, SPREADS["valve.xt"], high=1.0))
    for key in ("on_delay_s", "off_delay_s"):
        old = float(getattr(v, key))
        spread = SPREADS["valve.switching_delay_s"]
        _put(valve, key, old, d.value(f"{p}.valve.{key}", old, spread, high=1.0))
    return table


def _vary_vacuum(table: dict[str, Any], v: Vacuum, d: _Draws) -> None:
    limits = {
        "nozzle_diameter_mm": ("vacuum.nozzle_diameter_mm", 20.0),
        "nozzle_cd": ("vacuum.nozzle_cd", 1.0),
        "evacuation_time_s": ("vacuum.time_constant_s", math.inf),
        "release_time_s": ("vacuum.time_constant_s", math.inf),
        "switch_level": ("vacuum.switch_level", 0.99),
        "on_delay_s": ("vacuum.switching_delay_s", 1.0),
        "off_delay_s": ("vacuum.switching_delay_s", 1.0),
    }
    for key, (spread, high) in limits.items():
        old = float(getattr(v, key))
        _put(table, key, old, d.value(f"vacuum.{key}", old, SPREADS[spread], high=high))


def _vary_sensor(table: dict[str, Any], s: Sensor, d: _Draws) -> None:
    span = s.range_high - s.range_low
    p = f"sensor.{s.channel}"
    gain = d.value(f"{p}.gain", s.gain, SPREADS[f"sensor.{s.kind}.gain"], low=0.5, high=1.5)
    _put(table, "gain", s.gain, gain)
    offset = d.value(
        f"{p}.offset", s.offset, SPREADS[f"sensor.{s.kind}.offset"], -span, span, span=span
    )
    _put(table, "offset", s.offset, offset)


def noise_free(machine: MachineDescription) -> MachineDescription:
    """The description with every analog sensor's noise set to zero (resolution kept).

    A fault that shifts a step's timing shifts where the twin draws its sensor noise,
    so its simulated change against a noisy baseline holds two draws of noise that do
    not cancel; without noise the change is the physics' alone (the fault check,
    ``docs/faults.md``).

    Examples
    --------
    >>> m = noise_free(load_machine("press-fit-cell"))
    >>> {s.noise for s in m.sensors}
    {0.0}
    """
    return replace(machine, sensors=tuple(replace(s, noise=0.0) for s in machine.sensors))


def vary_machine(
    machine: MachineDescription | str | Path, scale: float, seed: int
) -> MachineDescription:
    """A plant: ``machine`` with every physical parameter drawn around its value.

    Parameters
    ----------
    machine : MachineDescription, str or Path
        The description as written (the twin): a description, a built-in name or a
        TOML path.
    scale : float
        Spread relative to the documented tolerances (``docs/plant-variation.md``):
        0 returns the description's values, 1 a plausible real machine, 2 a badly
        documented one (twice the spread); at most :data:`MAX_SCALE` [-].
    seed : int
        Non-negative seed; the same ``(machine, scale, seed)`` gives the same plant.

    Returns
    -------
    MachineDescription
        The plant, validated like any description, with the machine's name, ids,
        sequence, bores and strokes unchanged and its ``source``.

    Raises
    ------
    InputError
        If ``scale`` or ``seed`` is invalid (the message names it), or the machine
        cannot be loaded.

    Examples
    --------
    >>> twin = load_machine("festo-dsd")
    >>> plant = vary_machine(twin, scale=1.0, seed=7)
    >>> plant.name, plant.actuators[0].stroke_mm
    ('festo-dsd', 200.0)
    >>> plant.actuators[0].valve.cv != twin.actuators[0].valve.cv
    True
    >>> vary_machine(twin, scale=0.0, seed=7).actuators == twin.actuators
    True
    """
    value = _check_scale(scale)
    seed_value = _check_seed(seed)
    desc = load_machine(machine)
    raw = copy.deepcopy(desc.raw)
    draws = _Draws(value, seed_value)
    spread = SPREADS["machine.switch_window_mm"]
    old = desc.switch_window_mm
    window = draws.value("machine.switch_window_mm", old, spread, high=50.0)
    _put(raw["machine"], "switch_window_mm", old, window)
    _vary_supply(raw["supply"], desc.supply, draws)
    if desc.vacuum is not None:
        _vary_vacuum(raw["vacuum"], desc.vacuum, draws)
    raw["actuator"] = [
        _vary_actuator(table, act, draws)
        for table, act in zip(raw["actuator"], desc.actuators, strict=True)
    ]
    for table, sensor in zip(raw.get("sensor", []), desc.sensors, strict=True):
        _vary_sensor(table, sensor, draws)
    return parse_description(raw, desc.source)


@dataclass(frozen=True)
class ParameterChange:
    """One parameter that differs between a description and a plant.

    Attributes
    ----------
    path : str
        Key path, e.g. ``actuator[DNC].valve.cv`` or ``sensor[P_In].offset``.
    reference, plant : float
        The value in the description and in the plant (the description's unit).
    relative : float
        ``(plant - reference) / |reference|``; for sensor offsets the change as a
        fraction of the sensor's span (``basis`` ``"span"``) [-].
    basis : str
        ``"value"`` or ``"span"``.
    """

    path: str
    reference: float
    plant: float
    relative: float
    basis: str = "value"

    def __str__(self) -> str:
        of = " of span" if self.basis == "span" else ""
        return f"{self.path} {100 * self.relative:+.1f} %{of}"


def _relative(x: float, y: float) -> float:
    return (y - x) / abs(x) if x != 0 else math.copysign(math.inf, y - x)


def _numeric_changes(path: str, a: Any, b: Any) -> list[ParameterChange]:
    out = []
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, float) and isinstance(y, float) and x != y:
            out.append(ParameterChange(f"{path}.{f.name}", x, y, _relative(x, y)))
    return out


def parameter_changes(
    reference: MachineDescription, plant: MachineDescription
) -> tuple[ParameterChange, ...]:
    """Every physical parameter that differs, largest relative change first.

    Parameters
    ----------
    reference : MachineDescription
        The description as written (the twin).
    plant : MachineDescription
        A plant of it, e.g. from :func:`vary_machine`.

    Returns
    -------
    tuple of ParameterChange
        Sorted by ``|relative|``, largest first.

    Raises
    ------
    InputError
        If the two do not describe the same actuators, vacuum and sensors.

    Examples
    --------
    >>> twin = load_machine("festo-dsd")
    >>> changes = parameter_changes(twin, vary_machine(twin, 1.0, seed=7))
    >>> abs(changes[0].relative) >= abs(changes[-1].relative)
    True
    >>> parameter_changes(twin, twin)
    ()
    """
    if reference.actuator_ids != plant.actuator_ids:
        raise InputError(
            describe("actuators of the plant", plant.actuator_ids, [reference.actuator_ids])
        )
    channels = [s.channel for s in reference.sensors]
    if [s.channel for s in plant.sensors] != channels:
        raise InputError(
            describe("sensors of the plant", [s.channel for s in plant.sensors], [channels])
        )
    if (reference.vacuum is None) != (plant.vacuum is None):
        raise InputError(describe("vacuum of the plant", plant.vacuum, "as in the reference"))
    changes: list[ParameterChange] = []
    for f in ("scan_time_s", "switch_window_mm", "temperature_c", "friction_scatter"):
        x, y = getattr(reference, f), getattr(plant, f)
        if x != y:
            changes.append(ParameterChange(f"machine.{f}", x, y, _relative(x, y)))
    changes += _numeric_changes("supply", reference.supply, plant.supply)
    if reference.vacuum is not None and plant.vacuum is not None:
        changes += _numeric_changes("vacuum", reference.vacuum, plant.vacuum)
    for a, b in zip(reference.actuators, plant.actuators, strict=True):
        changes += _numeric_changes(f"actuator[{a.id}]", a, b)
        changes += _numeric_changes(f"actuator[{a.id}].valve", a.valve, b.valve)
    for s, t in zip(reference.sensors, plant.sensors, strict=True):
        for change in _numeric_changes(f"sensor[{s.channel}]", s, t):
            if change.path.endswith(".offset"):
                span = s.range_high - s.range_low
                rel = (change.plant - change.reference) / span
                change = replace(change, relative=rel, basis="span")
            changes.append(change)
    return tuple(sorted(changes, key=lambda c: (-abs(c.relative), c.path)))


def machine_to_toml(machine: MachineDescription, header: str = "") -> str:
    """The description as TOML text, with ``header`` as comment lines first.

    Parameters
    ----------
    machine : MachineDescription
        A description (its ``raw`` mapping is written, so keys stay as the author
        wrote them).
    header : str
        Text for the leading comment, e.g. provenance; each line becomes ``# line``.

    Returns
    -------
    str
        TOML that :func:`~pneufdd.sim.parse_description` reads back to an equal
        description.

    Raises
    ------
    MachineError
        If ``machine.raw`` does not describe ``machine`` (e.g. a description edited
        with :func:`dataclasses.replace`; build descriptions with
        :func:`~pneufdd.sim.parse_description`).

    Examples
    --------
    >>> import tomllib
    >>> text = machine_to_toml(load_machine("festo-dsd"), header="a copy")
    >>> text.splitlines()[0]
    '# a copy'
    >>> parse_description(tomllib.loads(text)).actuators == load_machine("festo-dsd").actuators
    True
    >>> text = machine_to_toml(load_machine("festo-dsd"), header="from bell\x07\x1b[31m")
    >>> tomllib.loads(text)["machine"]["name"]  # a control character is no TOML comment
    'festo-dsd'
    """
    parsed = parse_description(machine.raw, machine.source)
    if replace(parsed, raw=machine.raw, source=machine.source) != machine:
        raise MachineError(
            f"{machine.source}: the description's fields differ from its raw TOML mapping "
            "(edited with dataclasses.replace?); build descriptions with parse_description"
        )
    try:
        body = tomli_w.dumps(machine.raw)
    except TypeError as exc:
        raise MachineError(f"{machine.source}: not writable as TOML: {exc}") from None
    # a TOML comment holds no control character but a tab: a name read from a file (a
    # machine named "bell\x07") would make the written file unreadable
    header = header.translate(_COMMENT_UNSAFE)
    lines = [line if line.startswith("#") else f"# {line}".rstrip() for line in header.splitlines()]
    return ("\n".join(lines) + "\n\n" if lines else "") + body


_COMMENT_UNSAFE = {c: "\ufffd" for c in (*range(0x09), *range(0x0E, 0x20), 0x7F)}
"""Control characters a TOML comment may not hold (line ends split it into lines)."""


def _input_files(machine: MachineDescription) -> list[Path]:
    """Files the description was read from (its TOML file, or the built-in file)."""
    files = []
    if machine.source in builtin_machines():
        res = resources.files("pneufdd.sim") / "machines" / f"{machine.source}.toml"
        files.append(Path(str(res)))
    files.append(Path(machine.source))
    return [f for f in files if f.is_file()]


def write_machine(
    machine: MachineDescription,
    path: str | Path,
    header: str = "",
    overwrite: bool = False,
) -> Path:
    """Write ``machine`` as TOML to ``path`` atomically (temporary file, then rename).

    Parameters
    ----------
    machine : MachineDescription
        The description or plant to write.
    path : str or Path
        Output file (``.toml``).
    header : str
        Comment lines written first (provenance), see :func:`machine_to_toml`.
    overwrite : bool
        Replace an existing file. The file the description was read from is never
        replaced, even with ``overwrite``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    FileExistsInputError
        If ``path`` exists and ``overwrite`` is False.
    InputError
        If ``path`` is the description's own input file, a folder, or its folder is
        missing.

    Examples
    --------
    >>> import tempfile
    >>> plant = vary_machine("festo-dsd", 1.0, seed=7)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     out = write_machine(plant, Path(folder) / "plant.toml", header="plant, seed 7")
    ...     load_machine(out).actuators == plant.actuators
    True
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(describe("output file", str(path), "a file path, not a folder"))
    if not path.parent.is_dir():
        raise InputError(describe(f"folder of output file {str(path)!r}", "missing", "a folder"))
    if path.exists():
        for source in _input_files(machine):
            if os.path.samefile(source, path):
                raise InputError(
                    describe(
                        "output file",
                        str(path),
                        f"a file other than the description it was made from ({source})",
                    )
                )
        if not overwrite:
            raise FileExistsInputError(
                describe(f"output file {str(path)!r}", "exists", "a new file, or overwrite=True")
            )
    text = machine_to_toml(machine, header)
    return write_text_atomic(path, text, overwrite)
