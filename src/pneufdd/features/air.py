"""Air consumption (eq. 4.17) and minimum supply pressure (Tables 4.2, 4.3).

.. math:: U = \\int Q\\,dt = \\sum Q\\,\\Delta t, \\qquad U_c = U / N      \\qquad (4.17)

Flows are integrated with the trapezoidal rule over a window, NaN gaps bridged by
linear interpolation when at least ``min_valid`` of the samples are finite. Results
are standard litres ``SL`` on the dissertation's basis (0 degC, 1013 mbar,
1.294 kg/m^3; section 3.4.1), the unit of Tables 4.2 and 4.3. Windows:

* a step: from its valve firing to the next step's start;
* a stroke: the step in which the actuator's solenoid fired (so the air that
  fills the chamber after the piston arrived, until the next step, is counted -
  that air is consumed by the stroke).
"""

from __future__ import annotations

import numpy as np

from pneufdd.features.context import CycleView
from pneufdd.features.motion import MOTIONS, exhaust_line, supply_line
from pneufdd.features.registry import Unavailable, register
from pneufdd.physics.constants import DISSERTATION_STANDARD

__all__ = ["consumed", "exhausted", "kg_to_sl", "min_supply_pressure"]


def kg_to_sl(mass: float) -> float:
    """Convert a mass of air to standard litres (0 degC, 1013 mbar, 1.294 kg/m^3).

    Parameters
    ----------
    mass : float
        Mass of air [kg].

    Returns
    -------
    float
        Volume at the dissertation's standard conditions [SL].

    Examples
    --------
    >>> round(kg_to_sl(0.6306 * 1.294e-3), 4)
    0.6306
    """
    return mass / (DISSERTATION_STANDARD.density * 1e-3)


def _integral(view: CycleView, name: str, t0: float, t1: float, sign: float) -> float:
    return kg_to_sl(view.integral(name, t0, t1, sign))


def consumed(view: CycleView, name: str, t0: float, t1: float) -> float:
    """Air into a line (positive flow) between ``t0`` and ``t1`` [SL] (eq. 4.17)."""
    if view.data.flow_direction(name) == "reverse":
        raise Unavailable(f"{name} measures reverse flow only: the supplied air is not measured")
    return _integral(view, name, t0, t1, 1.0)


def exhausted(view: CycleView, name: str, t0: float, t1: float) -> float:
    """Air out of a line (negative flow) between ``t0`` and ``t1`` [SL] (eq. 4.17)."""
    if view.data.flow_direction(name) == "forward":
        raise Unavailable(f"{name} measures forward flow only: the exhaust is not measured")
    return _integral(view, name, t0, t1, -1.0)


def min_supply_pressure(view: CycleView, act: str, motion: str) -> float:
    """Minimum ``P_In`` during the step of a stroke [Pa] (Tables 4.2/4.3)."""
    step = view.stroke(act, motion).step
    return float(np.nanmin(view.window("P_In", step.start_s, step.end_s)))


@register("air_SL", "step", "SL", "air", ("Q_In",))
def step_air(view: CycleView, number: int) -> float:
    """Air drawn from the supply (Q_In) during step N [SL] (eq. 4.17, Figs. 5.7-5.9)."""
    step = view.step(number)
    return consumed(view, "Q_In", step.start_s, step.end_s)


@register("air_cycle_SL", "cycle", "SL", "air", ("Q_In",))
def cycle_air(view: CycleView, _: object) -> float:
    """Air drawn from the supply (Q_In) over the whole cycle [SL] (eq. 4.17, U per cycle)."""
    return consumed(view, "Q_In", view.cycle.start_s, view.cycle.end_s)


def _register(motion: str) -> None:
    fill, ex = supply_line(motion), exhaust_line(motion)

    @register(
        f"air_{motion}_SL",
        "actuator",
        "SL",
        "air",
        (f"Q_{{act}}_{fill}",),
        description=f"Air consumed by the {motion} stroke, line {fill} [SL] (eq. 4.17, Table 4.2)",
    )
    def stroke_air(view: CycleView, act: str) -> float:
        step = view.stroke(act, motion).step
        return consumed(view, f"Q_{act}_{fill}", step.start_s, step.end_s)

    @register(
        f"air_exhaust_{motion}_SL",
        "actuator",
        "SL",
        "air",
        (f"Q_{{act}}_{ex}",),
        description=f"Air exhausted through line {ex} in the {motion} stroke [SL] (eq. 4.17).",
    )
    def stroke_exhaust(view: CycleView, act: str) -> float:
        step = view.stroke(act, motion).step
        return exhausted(view, f"Q_{act}_{ex}", step.start_s, step.end_s)

    @register(
        f"supply_air_{motion}_SL",
        "actuator",
        "SL",
        "air",
        ("Q_In",),
        description=f"Air from the supply (Q_In) in the {motion} step, all parallel motions [SL]",
    )
    def stroke_supply_air(view: CycleView, act: str) -> float:
        step = view.stroke(act, motion).step
        return consumed(view, "Q_In", step.start_s, step.end_s)

    @register(
        f"p_supply_min_{motion}_Pa",
        "actuator",
        "Pa",
        "air",
        ("P_In",),
        description=f"Minimum supply pressure P_In in the {motion} stroke's step [Pa] (Table 4.2)",
    )
    def stroke_min_supply(view: CycleView, act: str) -> float:
        return min_supply_pressure(view, act, motion)


for _m in MOTIONS:
    _register(_m)
