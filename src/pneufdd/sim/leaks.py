"""Leak specifications: where, how big, and the ground truth stored with a simulation.

A leak is an orifice to the atmosphere at ``supply`` (the manifold downstream of the
supply flow meter, so ``Q_In`` sees it in every step, section 5.3.1.2) or on an
actuator line ``<ACT>_A`` / ``<ACT>_B`` (lumped with the chamber, downstream of the
line flow meter). Its size is given in turns of the GR-3/8B leak valve (section 3.2.5,
Table 3.3; a bare number), as an orifice diameter (``"2.5mm"``) or as a flow at the
machine's nominal supply pressure (``"30slpm"``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from pneufdd.errors import InputError, describe
from pneufdd.physics.units import kg_s_to_slpm, psig_to_pa
from pneufdd.sim.description import MachineDescription

__all__ = ["Leak", "LeakSpec", "parse_leak_size", "resolve_leaks"]

_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(mm|slpm|turns?)?\s*$", re.I)
MAX_TURNS = 6.0


@dataclass(frozen=True)
class Leak:
    """A leak as the user asked for it.

    Attributes
    ----------
    location : str
        ``supply``, ``<ACT>_A`` or ``<ACT>_B``.
    size : float
        Size in ``unit``.
    unit : str
        ``"turns"`` (GR-3/8B leak valve, 0-6), ``"mm"`` (orifice diameter) or
        ``"SLPM"`` (flow at the nominal supply pressure).
    """

    location: str
    size: float
    unit: str = "turns"


@dataclass(frozen=True)
class LeakSpec:
    """A resolved leak: the user's size plus its effective area and nominal flow."""

    location: str
    size: float
    unit: str
    area_m2: float
    nominal_mass_flow_kg_s: float
    nominal_slpm: float
    nominal_pressure_pa: float

    def as_metadata(self) -> dict[str, Any]:
        """JSON-ready ground truth for the recording's metadata."""
        return {
            "location": self.location,
            "size": self.size,
            "unit": self.unit,
            "effective_area_m2": self.area_m2,
            "mass_flow_kg_s": self.nominal_mass_flow_kg_s,
            "slpm": self.nominal_slpm,
            "at_pressure_pa": self.nominal_pressure_pa,
        }


MAX_SIZE = {"mm": 20.0, "SLPM": 20_000.0}
"""Largest leak sizes accepted: a 20 mm hole or 20,000 SLPM is a broken 3/4 in line."""


def parse_leak_size(text: str | float, where: str = "leak size") -> tuple[float, str]:
    """Parse a leak size: a number (turns), ``"2.5mm"``, ``"30slpm"`` or ``"3turns"``.

    Examples
    --------
    >>> parse_leak_size("2.5mm")
    (2.5, 'mm')
    >>> parse_leak_size(4)
    (4.0, 'turns')
    >>> parse_leak_size("30SLPM")
    (30.0, 'SLPM')
    """
    if isinstance(text, bool):
        raise InputError(describe(where, text, "a number of turns, '2.5mm' or '30slpm'"))
    if isinstance(text, int | float):
        value, unit = float(text), "turns"
    else:
        match = _SIZE.match(str(text))
        if match is None:
            raise InputError(describe(where, text, "a number of turns, '2.5mm' or '30slpm'"))
        value = float(match.group(1))
        word = (match.group(2) or "turns").lower()
        unit = {"mm": "mm", "slpm": "SLPM"}.get(word, "turns")
    if not math.isfinite(value) or value < 0.0:
        raise InputError(describe(where, text, ">= 0"))
    if unit == "turns" and value > MAX_TURNS:
        raise InputError(describe(where, text, "0 to 6 turns of the GR-3/8B valve (Table 3.3)"))
    limit = MAX_SIZE.get(unit)
    if limit is not None and value > limit:
        raise InputError(
            describe(where, text, f"at most {limit:g} {unit} (a broken supply line; issue 14)")
        )
    return value, unit


def _as_leaks(leaks: Mapping[str, Any] | Iterable[Leak] | None) -> list[Leak]:
    if leaks is None:
        return []
    if isinstance(leaks, Mapping):
        out = []
        for loc, size in leaks.items():
            value, unit = parse_leak_size(size, f"size of leak {loc!r}")
            out.append(Leak(str(loc), value, unit))
        return out
    result = []
    for item in leaks:
        if not isinstance(item, Leak):
            raise InputError(describe("leak", item, "Leak objects or a mapping location -> size"))
        value, unit = parse_leak_size(
            f"{item.size}{item.unit}" if item.unit != "turns" else item.size,
            f"size of leak {item.location!r}",
        )
        result.append(Leak(item.location, value, unit))
    return result


def resolve_leaks(
    machine: MachineDescription, leaks: Mapping[str, Any] | Iterable[Leak] | None
) -> list[LeakSpec]:
    """Check leak locations against ``machine`` and compute their effective areas.

    A location given twice is an error. SLPM sizes refer to the regulator set point
    (the machine's nominal supply pressure) and 20 degC.
    """
    valid = machine.leak_locations
    p_nom = float(psig_to_pa(machine.nominal_supply_psig))
    seen: set[str] = set()
    specs = []
    for leak in _as_leaks(leaks):
        if leak.location not in valid:
            raise InputError(describe("leak location", leak.location, valid))
        if leak.location in seen:
            raise InputError(describe("leak location given twice", leak.location, "once"))
        seen.add(leak.location)
        # the leak laws are compiled kernels, imported once there is a leak: a leak-free
        # run on the prebuilt twin (pneufdd.sim.prebuilt) never loads numba
        from pneufdd.physics.leaks import leak_area, leak_mass_flow

        ref = p_nom if leak.unit == "SLPM" else None
        area = float(leak_area(leak.size, leak.unit, ref))
        mdot = float(leak_mass_flow(p_nom, area))
        specs.append(
            LeakSpec(
                leak.location, leak.size, leak.unit, area, mdot, float(kg_s_to_slpm(mdot)), p_nom
            )
        )
    return specs
