"""Nuisances: what changes on a shop floor without any fault (issue 34, item 2).

* **Ambient temperature** over a shift (:class:`TemperatureProfile`): the wall and
  chamber air follow it, and so does the seal friction
  (:func:`pneufdd.physics.faults.seal_friction_temperature_factors`); the supply air
  follows the ambient unless a profile of its own is given.
* **Payload** that changes between products (:class:`PayloadChange`): the moving mass
  of an actuator from a time on.
* **Supply header dips** from other consumers on the same house line
  (:class:`HeaderDips`): half-sine pressure drops of the house air, upstream of the
  machine's regulator, at the times of a Poisson process drawn from their own seed.

Like leaks and faults they are applied between cycles at each cycle's start time
(dips act within the cycle), and their ground truth is kept in the recording's
metadata (``nuisances``, ``nuisance_timeline``, ``header_dips``). The command-line
forms (:func:`parse_temperature_profile`, :func:`parse_payload`,
:func:`parse_header_dips`): ``--ambient 15C..35C/8h``, ``--supply-air 25C``,
``--payload DNC=+2kg@2h``, ``--header-dips depth=0.3bar,duration=2s,rate=10/h``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pneufdd.errors import InputError, describe
from pneufdd.physics.faults import COULOMB_TEMPERATURE_COEFFICIENT
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.schedule import parse_duration

__all__ = [
    "MAX_DIP_RATE_PER_H",
    "MAX_PAYLOAD_CHANGES",
    "MAX_PROFILE_POINTS",
    "HeaderDips",
    "Nuisances",
    "PayloadChange",
    "TemperatureProfile",
    "nuisances_from_options",
    "parse_header_dips",
    "parse_payload",
    "parse_temperature_profile",
]

MAX_PROFILE_POINTS = 1000
"""Most points of a temperature profile (``docs/limits.md``)."""
MAX_PAYLOAD_CHANGES = 10_000
"""Most payload changes of a run."""
MAX_DIP_RATE_PER_H = 360.0
"""Most header dips per hour (one every 10 s on average)."""
_T_LOW, _T_HIGH = -20.0, 60.0  # ambient range of ISO 4414 machines' components [degC]
_NUMBER = r"([+-]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)"


@dataclass(frozen=True)
class TemperatureProfile:
    """A temperature over time: linear between ``(time [s], temperature [degC])`` points.

    Before the first point it holds the first temperature, after the last the last.

    Examples
    --------
    >>> profile = parse_temperature_profile("15C..35C/8h")
    >>> profile.at(0.0), profile.at(4 * 3600.0), profile.at(10 * 3600.0)
    (15.0, 25.0, 35.0)
    """

    points: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        pts = self.points
        if not 1 <= len(pts) <= MAX_PROFILE_POINTS:
            raise InputError(
                describe("temperature profile points", len(pts), f"1 to {MAX_PROFILE_POINTS:,}")
            )
        for k, (time, temp) in enumerate(pts):
            if not (math.isfinite(time) and time >= 0.0 and (k == 0 or time > pts[k - 1][0])):
                raise InputError(
                    describe("temperature profile time [s]", time, "increasing times >= 0")
                )
            if not (math.isfinite(temp) and _T_LOW <= temp <= _T_HIGH):
                raise InputError(
                    describe("temperature [degC]", temp, f"{_T_LOW:g} to {_T_HIGH:g} degC")
                )

    def at(self, time_s: float) -> float:
        """Temperature at ``time_s`` [degC]."""
        pts = self.points
        if time_s <= pts[0][0]:
            return pts[0][1]
        for (t0, c0), (t1, c1) in itertools.pairwise(pts):
            if time_s <= t1:
                return c0 + (c1 - c0) * (time_s - t0) / (t1 - t0)
        return pts[-1][1]

    def as_metadata(self) -> list[list[float]]:
        """JSON-ready form: ``[[time_s, degC], ...]``."""
        return [[t, c] for t, c in self.points]


def _temperature(text: str, where: str) -> float:
    match = re.fullmatch(r"\s*" + _NUMBER + r"\s*(C|degC|K)\s*", text)
    if match is None:
        raise InputError(describe(where, text, "a temperature such as '15C' or '288.15K'"))
    value = float(match.group(1))
    return value - 273.15 if match.group(2) == "K" else value


def parse_temperature_profile(text: str, where: str = "--ambient") -> TemperatureProfile:
    """``"25C"`` (constant), ``"15C..35C/8h"`` (a ramp from t = 0) or ``"15C@0,35C@4h,20C@8h"``.

    Examples
    --------
    >>> parse_temperature_profile("15C@0,35C@4h,20C@8h").points
    ((0.0, 15.0), (14400.0, 35.0), (28800.0, 20.0))
    >>> parse_temperature_profile("25C").at(100.0)
    25.0
    """
    ramp = re.fullmatch(r"\s*([^.]+?)\s*\.\.\s*([^/]+?)\s*/\s*(.+)", text)
    if ramp is not None:
        span = parse_duration(ramp.group(3), f"{where} {text!r} (duration)")
        if not span > 0.0:
            raise InputError(describe(f"{where} {text!r} (duration)", span, "> 0 [s]"))
        first = _temperature(ramp.group(1), f"{where} {text!r}")
        return TemperatureProfile(((0.0, first), (span, _temperature(ramp.group(2), where))))
    points = []
    for part in text.split(","):
        temp, at, when = part.partition("@")
        time = parse_duration(when, f"{where} {text!r} (time)") if at else 0.0
        points.append((time, _temperature(temp, f"{where} {text!r}")))
    return TemperatureProfile(tuple(points))


@dataclass(frozen=True)
class PayloadChange:
    """From ``start_s`` on, ``actuator`` moves ``mass_kg`` more than its description says.

    The next change of the same actuator replaces it (a product sequence). Only the
    moving mass changes: the twin has no gravity (its axes are horizontal), so a
    vertical axis's load weight is not modelled (``docs/faults.md``).
    """

    actuator: str
    mass_kg: float
    start_s: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_kg) and abs(self.mass_kg) <= 1000.0):
            raise InputError(describe(f"payload of {self.actuator} [kg]", self.mass_kg,
                                      "-1000 to 1000 kg"))  # fmt: skip
        if not (math.isfinite(self.start_s) and self.start_s >= 0.0):
            raise InputError(describe(f"payload time of {self.actuator} [s]", self.start_s, ">= 0"))

    def as_metadata(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {"actuator": self.actuator, "mass_kg": self.mass_kg, "start_s": self.start_s}


def parse_payload(text: str) -> PayloadChange:
    """``ACT=+2kg@2h`` (``g`` or ``kg``; no ``@``: from the start).

    Examples
    --------
    >>> parse_payload("DNC=+2kg@30min")
    PayloadChange(actuator='DNC', mass_kg=2.0, start_s=1800.0)
    >>> parse_payload("HGD2=150g").mass_kg
    0.15
    """
    actuator, sep, rest = text.partition("=")
    mass, at, when = rest.partition("@")
    match = re.fullmatch(r"\s*" + _NUMBER + r"\s*(kg|g)\s*", mass)
    if not sep or not actuator.strip() or match is None:
        raise InputError(describe("--payload", text, "ACT=MASS[@TIME], e.g. DNC=+2kg@2h"))
    kg = float(match.group(1)) * (1e-3 if match.group(2) == "g" else 1.0)
    start = parse_duration(when, f"time of --payload {text!r}") if at else 0.0
    return PayloadChange(actuator.strip(), kg, start)


@dataclass(frozen=True)
class HeaderDips:
    """Pressure dips of the house header, at the times of a Poisson process.

    Attributes
    ----------
    depth_pa : float
        Largest pressure drop of each dip [Pa].
    duration_s : float
        Duration of each dip, 0.3-600 s [s] (the house-pressure grid is 0.1 s).
    rate_per_s : float
        Mean number of dips per second [1/s].
    seed : int or None
        Seed of the dips' times (None: the run's seed). Their own random stream: the
        run's other random quantities are the same with and without dips.
    """

    depth_pa: float
    duration_s: float
    rate_per_s: float
    seed: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.depth_pa) and 0.0 < self.depth_pa <= 1.5e6):
            raise InputError(describe("header dip depth [Pa]", self.depth_pa, "> 0 and <= 15 bar"))
        if not (math.isfinite(self.duration_s) and 0.3 <= self.duration_s <= 600.0):
            raise InputError(describe("header dip duration [s]", self.duration_s, "0.3 to 600 s"))
        if not (
            math.isfinite(self.rate_per_s) and 0.0 < self.rate_per_s <= MAX_DIP_RATE_PER_H / 3600
        ):
            raise InputError(
                describe("header dip rate [1/h]", self.rate_per_s * 3600.0,
                         f"> 0 and <= {MAX_DIP_RATE_PER_H:g} per hour")
            )  # fmt: skip
        if self.seed is not None and not (isinstance(self.seed, int) and self.seed >= 0):
            raise InputError(describe("header dip seed", self.seed, "an integer >= 0"))

    def as_metadata(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "depth_pa": self.depth_pa,
            "duration_s": self.duration_s,
            "rate_per_h": self.rate_per_s * 3600.0,
            "seed": self.seed,
            "shape": "half sine",
        }


def parse_header_dips(text: str) -> HeaderDips:
    """``depth=0.3bar,duration=2s,rate=10/h[,seed=N]`` (depth in bar, psi, kPa or Pa).

    Examples
    --------
    >>> dips = parse_header_dips("depth=0.3bar,duration=2s,rate=10/h,seed=4")
    >>> round(dips.depth_pa), dips.duration_s, round(dips.rate_per_s * 3600, 6), dips.seed
    (30000, 2.0, 10.0, 4)
    """
    fields: dict[str, str] = {}
    for part in text.split(","):
        key, sep, value = part.partition("=")
        if not sep or key.strip() not in ("depth", "duration", "rate", "seed"):
            raise InputError(describe("--header-dips", text,
                                      "depth=0.3bar,duration=2s,rate=10/h[,seed=N]"))  # fmt: skip
        fields[key.strip()] = value.strip()
    missing = [k for k in ("depth", "duration", "rate") if k not in fields]
    if missing:
        raise InputError(describe("--header-dips (missing)", missing, "depth, duration and rate"))
    depth = re.fullmatch(_NUMBER + r"\s*(bar|psi|kPa|Pa)", fields["depth"])
    if depth is None:
        raise InputError(describe("--header-dips depth", fields["depth"], "e.g. 0.3bar, 4psi"))
    scale = {"bar": 1e5, "psi": 6894.757293168, "kPa": 1e3, "Pa": 1.0}[depth.group(2)]
    rate = re.fullmatch(_NUMBER + r"\s*/\s*(s|min|h)", fields["rate"])
    if rate is None:
        raise InputError(describe("--header-dips rate", fields["rate"], "e.g. 10/h"))
    per = {"s": 1.0, "min": 60.0, "h": 3600.0}[rate.group(2)]
    seed = fields.get("seed")
    if seed is not None and not seed.isdigit():
        raise InputError(describe("--header-dips seed", seed, "an integer >= 0"))
    return HeaderDips(
        float(depth.group(1)) * scale,
        parse_duration(fields["duration"], "--header-dips duration"),
        float(rate.group(1)) / per,
        int(seed) if seed is not None else None,
    )


@dataclass(frozen=True)
class Nuisances:
    """Everything that changes over a run without a fault.

    Attributes
    ----------
    ambient : TemperatureProfile, optional
        Ambient (wall, seal) temperature; None: the description's ``temperature_c``.
    supply_air : TemperatureProfile, optional
        Temperature of the air the regulator delivers; None: the ambient's.
    payloads : sequence of PayloadChange
        Product changes (moving mass added per actuator, from a time on).
    header_dips : HeaderDips, optional
        Dips of the house header from other consumers.
    friction_per_k : float
        Change of the breakaway and Coulomb friction per kelvin [1/K]
        (:data:`pneufdd.physics.faults.COULOMB_TEMPERATURE_COEFFICIENT`).
    """

    ambient: TemperatureProfile | None = None
    supply_air: TemperatureProfile | None = None
    payloads: tuple[PayloadChange, ...] = ()
    header_dips: HeaderDips | None = None
    friction_per_k: float = COULOMB_TEMPERATURE_COEFFICIENT

    def __post_init__(self) -> None:
        object.__setattr__(self, "payloads", tuple(self.payloads))
        if len(self.payloads) > MAX_PAYLOAD_CHANGES:
            raise InputError(describe("payload changes", len(self.payloads),
                                      f"at most {MAX_PAYLOAD_CHANGES:,}"))  # fmt: skip
        if not (math.isfinite(self.friction_per_k) and abs(self.friction_per_k) <= 0.05):
            raise InputError(
                describe("friction change per kelvin [1/K]", self.friction_per_k, "-0.05 to 0.05")
            )

    def check(self, machine: MachineDescription) -> None:
        """Payloads must name actuators and leave a positive moving mass; dips the house.

        Raises
        ------
        InputError
            Naming the payload or dip and what is allowed.
        """
        masses = {a.id: a.moving_mass_kg for a in machine.actuators}
        for change in self.payloads:
            if change.actuator not in masses:
                raise InputError(describe("--payload actuator", change.actuator, list(masses)))
            if masses[change.actuator] + change.mass_kg < 1e-3:
                raise InputError(
                    describe(f"payload of {change.actuator} [kg]", change.mass_kg,
                             f"> {1e-3 - masses[change.actuator]:g} kg (the moving mass of "
                             f"{masses[change.actuator]:g} kg stays positive)")
                )  # fmt: skip
        if self.header_dips is not None:
            house = machine.supply.house_psig * 6894.757293168
            if self.header_dips.depth_pa >= house:
                raise InputError(
                    describe("header dip depth [Pa]", self.header_dips.depth_pa,
                             f"< the house gauge pressure {house:.0f} Pa")
                )  # fmt: skip

    def payload_at(self, time_s: float) -> dict[str, float]:
        """Payload per actuator at ``time_s`` (the last change started by then) [kg]."""
        out: dict[str, float] = {}
        for change in sorted(self.payloads, key=lambda c: c.start_s):
            if change.start_s <= time_s:
                out[change.actuator] = change.mass_kg
        return out

    def as_metadata(self) -> dict[str, Any]:
        """JSON-ready ground truth."""
        return {
            "ambient_c": self.ambient.as_metadata() if self.ambient else None,
            "supply_air_c": self.supply_air.as_metadata() if self.supply_air else None,
            "payloads": [c.as_metadata() for c in self.payloads],
            "header_dips": self.header_dips.as_metadata() if self.header_dips else None,
            "friction_per_k": self.friction_per_k,
        }


def nuisances_from_options(
    ambient: str | None,
    supply_air: str | None,
    payload: Sequence[str],
    header_dips: str | None,
) -> Nuisances | None:
    """The nuisances of ``--ambient``, ``--supply-air``, ``--payload``, ``--header-dips``.

    Examples
    --------
    >>> n = nuisances_from_options("15C..35C/8h", None, ["DNC=+1kg@1h"], None)
    >>> n.ambient.at(3600.0 * 8), n.payload_at(7200.0)
    (35.0, {'DNC': 1.0})
    >>> nuisances_from_options(None, None, [], None) is None
    True
    """
    if ambient is None and supply_air is None and not payload and header_dips is None:
        return None
    return Nuisances(
        ambient=parse_temperature_profile(ambient) if ambient else None,
        supply_air=parse_temperature_profile(supply_air, "--supply-air") if supply_air else None,
        payloads=tuple(parse_payload(p) for p in payload),
        header_dips=parse_header_dips(header_dips) if header_dips else None,
    )
