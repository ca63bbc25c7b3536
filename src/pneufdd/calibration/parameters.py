"""The parameters a twin-in-the-loop calibration fits, each with its prior.

A :class:`Parameter` changes a machine description's TOML table (a multiplier in log
space, or an offset in psi for the supply set point); :func:`machine_parameters` lists
the ones a plant's recordings can inform (section 1.2, objective 5), used by
:func:`pneufdd.calibration.calibrate.calibrate_machine`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pneufdd.calibration.valve import valve_cv_for_path
from pneufdd.errors import InputError, describe
from pneufdd.sim import MachineDescription

__all__ = ["Parameter", "actuator_table", "machine_parameters"]


@dataclass(frozen=True)
class Parameter:
    """One calibrated parameter: how it changes the description, and its prior.

    ``value`` is the multiplier's natural log (or the offset in psi for the supply set
    point); 0 is the description.
    """

    name: str
    prior_sigma: float
    apply: Callable[[dict[str, Any], float], None] = field(repr=False, compare=False)
    unit: str = "log factor"

    def describe_value(self, value: float) -> str:
        """The change as text: ``x 1.12`` or ``+1.5 psi``."""
        if self.unit == "psi":
            return f"{value:+.2f} psi"
        return f"x {math.exp(value):.3f}"


def _scale_keys(table: dict[str, Any], keys: Sequence[str], factor: float) -> None:
    for key in keys:
        if key in table:
            table[key] = float(table[key]) * factor


def actuator_table(raw: dict[str, Any], ident: str) -> dict[str, Any]:
    """The ``[[actuator]]`` table of ``ident`` in a description's raw TOML data."""
    for table in raw["actuator"]:
        if table["id"] == ident:
            return table  # type: ignore[no-any-return]
    raise InputError(describe("actuator", ident, [t["id"] for t in raw["actuator"]]))


def _volume(ident: str) -> Callable[[dict[str, Any], float], None]:
    def apply(raw: dict[str, Any], value: float) -> None:
        table = actuator_table(raw, ident)
        f = math.exp(value)
        _scale_keys(table, ("bore_mm", "rod_mm"), math.sqrt(f))
        _scale_keys(table, ("dead_volume_a_cm3", "dead_volume_b_cm3", "tube_length_m"), f)

    return apply


def _size(ident: str) -> Callable[[dict[str, Any], float], None]:
    """A drafted actuator's size: the air its lines hold, fed as a cylinder that size is.

    The supply air per stroke is the evidence (issue 10): it fixes the volume of the
    cylinder, its dead volumes and its tubes, not the valve or the tube bore that
    feed them. So the factor scales every volume of the air path: bore and rod by
    its square root, the dead volumes by the factor, and the tube's volume by the
    factor; the seal friction (proportional to the piston area, as the built-in
    descriptions estimate it: 0.040 N/mm^2) and the meter-out throttles by the
    factor too, so a throttled stroke keeps its speed (its exhaust flow is area x
    speed). The valve and the tube grow with a cylinder larger than the drafted one
    (they are sized to their cylinder: valve Cv x f, tube bore x sqrt f) but do not
    lose flow capacity with a smaller one: the valve stays (the smallest valves in
    use are not much smaller whatever the cylinder) and the tube gets shorter at
    about the same capacity (for a long tube ``Cv ~ d^2.5 / L^0.5``, the Crane
    formula of :func:`pneufdd.sim.compile.tube_cv`, and ``V ~ d^2 L``: bore
    x f^(1/7), length x f^(5/7)). Stroke and moving mass stay.

    Why not the valve and the tube bore with the cross-section both ways (stop 22):
    a leak draws its air through them, so their capacity sets how much a line leak
    blows and how far it pulls the line down. Scaled down with a small fitted
    cross-section (a 6 mm stroke gripper drafted as a 50 mm cylinder: factor 0.4)
    they choked a 60 SLPM leak to two thirds of its flow in the twin, and every line
    leak of such an actuator was sized a third too large.
    """
    valve_cv = _valve_cv(ident)

    def apply(raw: dict[str, Any], value: float) -> None:
        table = actuator_table(raw, ident)
        f = math.exp(value)
        _scale_keys(table, ("bore_mm", "rod_mm"), math.sqrt(f))
        _scale_keys(table, ("dead_volume_a_cm3", "dead_volume_b_cm3"), f)
        if f >= 1.0:  # a larger tube with a larger cylinder: volume and capacity grow
            _scale_keys(table, ("tube_inner_diameter_mm",), math.sqrt(f))
        else:  # a shorter, slightly narrower one: the volume shrinks, the capacity stays
            _scale_keys(table, ("tube_inner_diameter_mm",), f ** (1.0 / 7.0))
            _scale_keys(table, ("tube_length_m",), f ** (5.0 / 7.0))
        _scale_keys(table, ("static_friction_n", "coulomb_friction_n", "viscous_friction_n_s_m"), f)
        valve_cv(raw, math.log(max(f, 1.0)))
        # throttles present (a Cv of 50 or none is a free exhaust: left free)
        for key in ("meter_out_cv", "meter_out_cv_a", "meter_out_cv_b"):
            if key in table and float(table[key]) < 50.0:
                table[key] = min(float(table[key]) * f, 50.0)

    return apply


def _valve_cv(ident: str) -> Callable[[dict[str, Any], float], None]:
    def apply(raw: dict[str, Any], value: float) -> None:
        valve = actuator_table(raw, ident)["valve"]
        valve["cv"] = min(float(valve["cv"]) * math.exp(value), 50.0)

    return apply


def _meter_out(ident: str, side: str) -> Callable[[dict[str, Any], float], None]:
    def apply(raw: dict[str, Any], value: float) -> None:
        table = actuator_table(raw, ident)
        key = f"meter_out_cv_{side.lower()}"
        old = float(table.get(key, table.get("meter_out_cv", 0.0)) or 50.0)
        table[key] = min(old * math.exp(value), 50.0)

    return apply


def _friction(ident: str) -> Callable[[dict[str, Any], float], None]:
    def apply(raw: dict[str, Any], value: float) -> None:
        table = actuator_table(raw, ident)
        _scale_keys(table, ("static_friction_n", "coulomb_friction_n"), math.exp(value))

    return apply


def _fill_path(ident: str, path_cv: float) -> Callable[[dict[str, Any], float], None]:
    """Set the valve so that, with the tube, the fill path has ``path_cv x e^value``."""

    def apply(raw: dict[str, Any], value: float) -> None:
        table = actuator_table(raw, ident)
        table["valve"]["cv"] = valve_cv_for_path(
            path_cv * math.exp(value),
            float(table["tube_length_m"]),
            float(table["tube_inner_diameter_mm"]),
        )

    return apply


def _set_point(raw: dict[str, Any], value: float) -> None:
    supply = raw["supply"]
    new = float(supply["regulator_set_psig"]) + value
    supply["regulator_set_psig"] = min(new, float(supply["house_psig"]) - 0.5, 145.0)


def _line_cv(raw: dict[str, Any], value: float) -> None:
    raw["supply"]["line_cv"] = min(float(raw["supply"]["line_cv"]) * math.exp(value), 50.0)


def _nozzle(raw: dict[str, Any], value: float) -> None:
    raw["vacuum"]["nozzle_diameter_mm"] = float(raw["vacuum"]["nozzle_diameter_mm"]) * math.exp(
        value
    )


def machine_parameters(
    machine: MachineDescription,
    line_channels: Sequence[str] = (),
    friction_known: Sequence[str] = (),
    paths: Mapping[str, float] | None = None,
) -> list[Parameter]:
    """The parameters the recordings can inform, with their priors.

    Prior standard deviations (log factors unless psi): twice the plant spreads of
    ``docs/plant-variation.md`` (a badly documented machine): volume 0.2 (dead
    volumes, tubes cut on site), valve Cv 0.3 (ISO 6358 tolerance x 2), throttle 0.8
    (needle valves set by hand), friction 0.5, line Cv 0.4, set point 5 psi, nozzle
    0.1. A drafted actuator (geometry assumed) gets a size (:func:`_size`) of prior
    1.0 and throttles of prior 1.0, and no valve parameter of its own: with its stroke
    and mass assumed, its step durations cannot tell a small valve from a tight
    throttle, and a valve fitted small to slow a drafted stroke chokes every leak on
    its lines in the twin (on a press-fit-cell plant: Cv 0.041 where the plant's
    valve had 0.46). Speed is set by the throttles, as on most machines.

    An actuator drafted with an order code (:attr:`~pneufdd.sim.description.Actuator.
    code_drafted`: its bore, rod and stroke the catalogue's; dead volumes, tube and
    throttles assumed) gets a volume of prior 0.3, throttles of prior 1.0, and a valve
    parameter of prior 0.3 only when its valve has a code too.

    Friction is fitted only for an actuator with a line pressure sensor whose
    friction was not identified from its strokes (``friction_known``,
    :mod:`pneufdd.calibration.friction`). Where the fill path (valve and tube in
    series) was identified from a line flow (``paths``: actuator id -> Cv,
    :mod:`pneufdd.calibration.valve`), the valve Cv is no parameter of its own: a
    last parameter ``{id}.fill_path_cv`` (prior 0.1 around the identified path: the
    flow sensor's span error, the assumed xT) sets the valve so that, in series with
    the tube the other parameters left, it gives that path.
    """
    params = [
        Parameter("supply.regulator_set_psig", 5.0, _set_point, "psi"),
        Parameter("supply.line_cv", 0.4, _line_cv),
    ]
    for a in machine.actuators:
        drafted = a.drafted
        assumed = drafted or a.code_drafted  # throttles set by hand, not described
        if drafted:  # its valve follows its size (_size)
            params.append(Parameter(f"{a.id}.volume", 1.0, _size(a.id)))
        else:
            # a code-drafted actuator: the code's bore, assumed dead volumes and tube
            params.append(
                Parameter(f"{a.id}.volume", 0.3 if a.code_drafted else 0.2, _volume(a.id))
            )
            # a code-drafted actuator's valve without a code of its own is sized to the
            # port (calibration.draft_codes) and not fitted to the durations (stop 23)
            valve_known = not a.code_drafted or bool(a.valve.catalogue)
            if a.id not in (paths or {}) and valve_known:
                params.append(Parameter(f"{a.id}.valve_cv", 0.3, _valve_cv(a.id)))
        for side, value in (("A", a.meter_out_cv_a), ("B", a.meter_out_cv_b)):
            if value < 50.0:  # a throttle on that line (none: free exhaust)
                params.append(
                    Parameter(
                        f"{a.id}.meter_out_cv_{side.lower()}",
                        1.0 if assumed else 0.8,
                        _meter_out(a.id, side),
                    )
                )
        if a.id not in friction_known and any(
            c in line_channels for c in (f"P_{a.id}_A", f"P_{a.id}_B")
        ):
            params.append(Parameter(f"{a.id}.friction", 0.5, _friction(a.id)))
    if machine.vacuum is not None:
        params.append(Parameter("vacuum.nozzle_diameter_mm", 0.1, _nozzle))
    # last: they read the tube the parameters above left
    for ident, path_cv in (paths or {}).items():
        params.append(Parameter(f"{ident}.fill_path_cv", 0.1, _fill_path(ident, path_cv)))
    return params
