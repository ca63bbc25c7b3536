"""Changes to a machine, as a technician would make them, applied to its description.

Each :class:`Change` edits the description's TOML data (``MachineDescription.raw``)
and re-validates it, so a changed machine is an ordinary description the twin runs
(and one the acceptance applies unchanged to a plant). Absolute changes (a new set
point, tube, valve, spring, line pressure) are parts or settings; relative ones
(throttles opened by a factor) are adjustments of what is there, since a plant's
needle valves are not where its twin's are.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from pneufdd.errors import InputError, describe
from pneufdd.physics.units import pa_to_bar_gauge, psig_to_pa
from pneufdd.sim.description import (
    MIN_CV,
    SINGLE_SOLENOID_VALVES,
    MachineDescription,
    parse_description,
)

__all__ = [
    "ISO_BORES_MM",
    "MAX_THROTTLE_CV",
    "TUBE_BORES_MM",
    "VALVE_CVS",
    "Change",
    "apply_changes",
    "bar_g",
    "next_size",
    "standstill",
]

MAX_THROTTLE_CV = 50.0
"""A meter-out Cv this large is no throttle at all (the description's 'none') [-]."""

ISO_BORES_MM = (8, 10, 12, 16, 20, 25, 32, 40, 50, 63, 80, 100, 125, 160, 200, 250, 320)
"""Cylinder bores of ISO 6432 (8-25 mm) and ISO 15552 (32-320 mm) [mm]."""

TUBE_BORES_MM = (1.8, 2.5, 4.0, 5.5, 7.0, 8.0, 11.0)
"""Inner diameters of standard PU tubes: 3x0.6, 4x0.75, 6x1, 8x1.25, 10x1.5, 12x2,
16x2.5 mm [mm]."""

VALVE_CVS = (0.08, 0.12, 0.16, 0.21, 0.3, 0.4, 0.53, 0.74, 1.0, 1.4, 2.0)
"""A ladder of directional valve sizes (Cv, about qnN / 1050 l/min ANR: M3 to G3/8
valves of a typical catalogue) [-]."""


@dataclass(frozen=True)
class Change:
    """One change to a machine.

    Attributes
    ----------
    kind : str
        ``set_point`` (``psig``), ``throttles`` (``factor_a``, ``factor_b``: meter-out
        Cv multipliers), ``spring_return`` (``preload_n``, ``rate_n_per_mm``,
        ``throttle_factor_a``, optional ``bore_mm``), ``tube`` (``length_m``,
        optional ``inner_diameter_mm``), ``valve`` (``cv``), ``line_pressure``
        (``psig``, ``side`` a/b/both, ``booster``), ``bore`` (``bore_mm``), ``air_off``
        (a shut-off valve closed at standstill: no change to the running machine).
    actuator : str
        The actuator changed ('' for the supply).
    values : dict
        The change's numbers (see ``kind``).
    """

    kind: str
    actuator: str = ""
    values: dict[str, Any] = field(default_factory=dict)

    def describe(self) -> str:
        """What must be done on the machine, in one line."""
        v = self.values
        who = self.actuator
        if self.kind == "set_point":
            return f"set the machine's pressure regulator to {bar_g(v['psig']):.2f} bar(g)"
        if self.kind == "throttles":
            return (
                f"{who}: open the meter-out flow controls (Cv x {v['factor_a']:.2f} on the A "
                f"line, x {v['factor_b']:.2f} on the B line)"
            )
        if self.kind == "spring_return":
            bore = f", bore {v['bore_mm']:g} mm" if v.get("bore_mm") else ""
            return (
                f"{who}: single-acting cylinder with return spring ({v['preload_n']:.0f} N "
                f"preload, {v['rate_n_per_mm']:.2f} N/mm{bore}) on a 3/2 valve; PLC: hold "
                f"U_{who}_A to extend, release to retract; A-line flow control "
                f"x {v['throttle_factor_a']:.2f}"
            )
        if self.kind == "tube":
            bore = f", {v['inner_diameter_mm']:g} mm bore" if v.get("inner_diameter_mm") else ""
            return f"{who}: tubes from the valve {v['length_m']:g} m long{bore}"
        if self.kind == "valve":
            return f"{who}: valve of Cv {v['cv']:g} (about {v['cv'] * 1050:.0f} l/min ANR)"
        if self.kind == "line_pressure":
            what = "booster" if v.get("booster") else "pressure regulator"
            lines = {"a": "A line", "b": "B line"}.get(v["side"], "both lines")
            return f"{who}: own {what} at {bar_g(v['psig']):.2f} bar(g) on its {lines}"
        if self.kind == "air_off":
            return (
                "a shut-off (soft-start/dump) valve after the regulator, closed by the PLC "
                "at standstill"
            )
        if self.kind == "bore":
            return (
                f"{who}: cylinder of {v['bore_mm']:g} mm bore (flow controls opened to keep "
                "its speed)"
            )
        return f"{self.kind} {who} {v}"

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {
            "kind": self.kind,
            "actuator": self.actuator,
            "values": dict(self.values),
            "what": self.describe(),
        }

    def apply(self, raw: dict[str, Any]) -> None:
        """Edit a description's TOML data in place."""
        handler = _HANDLERS.get(self.kind)
        if handler is None:
            raise InputError(describe("change kind", self.kind, sorted(_HANDLERS)))
        handler(raw, self)


def apply_changes(machine: MachineDescription, changes: Sequence[Change]) -> MachineDescription:
    """``machine`` with ``changes`` made (a new, validated description).

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> m = apply_changes(load_machine("press-fit-cell"), [Change("set_point", "", {"psig": 60.0})])
    >>> m.supply.regulator_set_psig
    60.0
    """
    raw = copy.deepcopy(machine.raw)
    for change in changes:
        change.apply(raw)
    what = "; ".join(c.kind for c in changes) or "unchanged"
    return parse_description(raw, source=f"{machine.source} (what-if: {what})")


def standstill(machine: MachineDescription, seconds: float) -> MachineDescription:
    """``machine`` with a last step in which it stands still for ``seconds`` (air on)."""
    raw = copy.deepcopy(machine.raw)
    raw["step"] = [*raw["step"], {"name": "standstill (air on)", "dwell_s": float(seconds)}]
    return parse_description(raw, source=f"{machine.source} (standstill)")


def _actuator(raw: dict[str, Any], ident: str) -> dict[str, Any]:
    for table in raw["actuator"]:
        if table["id"] == ident:
            return table  # type: ignore[no-any-return]
    raise InputError(describe("actuator", ident, [t["id"] for t in raw["actuator"]]))


def _meter(table: dict[str, Any], side: str) -> float:
    return float(
        table.get(f"meter_out_cv_{side}", table.get("meter_out_cv", 0.0)) or MAX_THROTTLE_CV
    )


def _scale_throttles(table: dict[str, Any], factor_a: float, factor_b: float) -> None:
    cv_a = min(max(_meter(table, "a") * factor_a, MIN_CV), MAX_THROTTLE_CV)
    cv_b = min(max(_meter(table, "b") * factor_b, MIN_CV), MAX_THROTTLE_CV)
    table.pop("meter_out_cv", None)
    table["meter_out_cv_a"] = cv_a
    table["meter_out_cv_b"] = cv_b


def _set_point(raw: dict[str, Any], change: Change) -> None:
    supply = raw["supply"]
    vacuum = raw.get("vacuum")
    if isinstance(vacuum, dict) and "rated_psig" not in vacuum:
        # the ejector stays the part it is: rated at the pressure it was chosen for
        vacuum["rated_psig"] = float(supply["regulator_set_psig"])
    supply["regulator_set_psig"] = float(change.values["psig"])


def _throttles(raw: dict[str, Any], change: Change) -> None:
    table = _actuator(raw, change.actuator)
    _scale_throttles(table, float(change.values["factor_a"]), float(change.values["factor_b"]))


def _tube(raw: dict[str, Any], change: Change) -> None:
    table = _actuator(raw, change.actuator)
    table["tube_length_m"] = float(change.values["length_m"])
    if change.values.get("inner_diameter_mm"):
        table["tube_inner_diameter_mm"] = float(change.values["inner_diameter_mm"])


def _valve(raw: dict[str, Any], change: Change) -> None:
    table = _actuator(raw, change.actuator)
    # another valve: its order code no longer applies
    table["valve"] = {k: v for k, v in table["valve"].items() if k != "catalogue"}
    table["valve"]["cv"] = float(change.values["cv"])


def _line_pressure(raw: dict[str, Any], change: Change) -> None:
    table = _actuator(raw, change.actuator)
    side = change.values.get("side", "both")
    for key in ("line_pressure_psig", "line_pressure_psig_a", "line_pressure_psig_b"):
        table.pop(key, None)
    psig = float(change.values["psig"])
    if side == "both":
        table["line_pressure_psig"] = psig
    else:
        table[f"line_pressure_psig_{side}"] = psig
    table["booster"] = bool(change.values.get("booster", False))


def _resize(table: dict[str, Any], bore_mm: float) -> None:
    """A cylinder of another bore: areas, cushions, seals and flow controls follow it.

    Dead volumes (cushions, ports) scale with the piston area, seal friction with the
    bore (the seal's circumference), the meter-out flow controls with the area (a
    larger piston must exhaust more air per mm at the same speed); the rod, stroke,
    mass, valve and tube stay.
    """
    old = float(table["bore_mm"])
    area = (bore_mm / old) ** 2
    table["bore_mm"] = float(bore_mm)
    table.pop("catalogue", None)  # another cylinder: its order code no longer applies
    for key in ("dead_volume_a_cm3", "dead_volume_b_cm3"):
        table[key] = float(table[key]) * area
    for key in ("static_friction_n", "coulomb_friction_n", "viscous_friction_n_s_m"):
        table[key] = float(table[key]) * bore_mm / old
    _scale_throttles(table, area, area)


def _bore(raw: dict[str, Any], change: Change) -> None:
    _resize(_actuator(raw, change.actuator), float(change.values["bore_mm"]))


def _spring_return(raw: dict[str, Any], change: Change) -> None:
    """Single-acting with return spring on a 3/2 valve; the PLC program follows.

    Extending commands become ``set U_<id>_A`` held (the spring retracts the moment
    it is released), retracting ones ``reset U_<id>_A``; releases that only
    de-energised a bistable or closed-centre valve's solenoid are dropped; a step
    that waited for the end switch of a command keeps waiting for it.
    """
    ident = change.actuator
    table = _actuator(raw, ident)
    if table.get("initial", "retracted") != "retracted":
        raise InputError(
            describe(f"actuator {ident} initial", table.get("initial"), "'retracted'")
            + " (a return spring holds a single-acting cylinder retracted)"
        )
    if change.values.get("bore_mm"):
        _resize(table, float(change.values["bore_mm"]))
    was_single = table["valve"]["kind"] in SINGLE_SOLENOID_VALVES
    # another valve and another cylinder: their order codes no longer apply
    table["valve"] = {k: v for k, v in table["valve"].items() if k != "catalogue"}
    table["valve"]["kind"] = "3/2-monostable"
    table.pop("catalogue", None)
    table["spring_preload_n"] = float(change.values["preload_n"])
    table["spring_rate_n_per_mm"] = float(change.values["rate_n_per_mm"])
    cv_a = _meter(table, "a") * float(change.values["throttle_factor_a"])
    table.pop("meter_out_cv", None)
    table.pop("meter_out_cv_b", None)
    table["meter_out_cv_a"] = min(max(cv_a, MIN_CV), MAX_THROTTLE_CV)
    if not was_single:
        raw["step"] = [_single_solenoid_step(step, ident) for step in raw["step"]]


def _single_solenoid_step(step: dict[str, Any], ident: str) -> dict[str, Any]:
    """One PLC step rewritten for a single-solenoid valve on ``ident``."""
    sol_a, sol_b = f"U_{ident}_A", f"U_{ident}_B"
    actions = list(step.get("do", []))
    if not any(a.get("set") in (sol_a, sol_b) or a.get("reset") in (sol_a, sol_b) for a in actions):
        return step
    out = dict(step)
    if "wait" not in step:  # the waits the until-commands implied
        out["wait"] = [a["until"] for a in actions if "until" in a]
    new: list[dict[str, Any]] = []
    for action in actions:
        if action.get("set") == sol_a:
            new.append({"set": sol_a})
        elif action.get("set") == sol_b:
            new.append({"reset": sol_a})
        elif action.get("reset") in (sol_a, sol_b):
            continue  # released a solenoid of a valve that kept its position
        else:
            new.append(action)
    out["do"] = new
    if not new and not out.get("wait") and not out.get("wait_off") and not out.get("dwell_s"):
        out["dwell_s"] = 0.01  # a step that only released: keep it, a PLC scan long
    return out


def _none(raw: dict[str, Any], change: Change) -> None:
    """A change outside the running machine's model (the air switched off at standstill)."""


_HANDLERS = {
    "air_off": _none,
    "set_point": _set_point,
    "throttles": _throttles,
    "tube": _tube,
    "valve": _valve,
    "line_pressure": _line_pressure,
    "bore": _bore,
    "spring_return": _spring_return,
}


def next_size(ladder: Sequence[float], value: float, step: int) -> float | None:
    """The ladder's size ``step`` places from ``value`` (+1 larger, -1 smaller), or None.

    Examples
    --------
    >>> next_size(ISO_BORES_MM, 32.0, 1), next_size(ISO_BORES_MM, 33.0, 1)
    (40, 40)
    >>> next_size(VALVE_CVS, 0.21, -1)
    0.16
    """
    if step > 0:
        bigger = [v for v in ladder if v > value * (1 + 1e-9)]
        return bigger[step - 1] if len(bigger) >= step else None
    smaller = [v for v in ladder if v < value * (1 - 1e-9)]
    return smaller[step] if len(smaller) >= -step else None


def bar_g(psig: float) -> float:
    """Gauge pressure in bar from psi [bar(g)].

    Examples
    --------
    >>> round(bar_g(87.0), 3)
    5.998
    """
    return float(pa_to_bar_gauge(psig_to_pa(psig)))
