"""The 13 features of Table 4.4, for any actuator with line sensors (DNC by default).

Table 4.4 of the dissertation, with the windows pneufdd uses (``docs/signals.md``):

==  =====================================================  ====================
 #  feature                                                window
==  =====================================================  ====================
 1  minimum supply pressure P_s                            both stroke steps
 2  minimum blind-side pressure P_a, extending             extend motion
 3  maximum blind-side pressure P_a, retracting            retract motion
 4  maximum rod-side pressure P_b, extending               extend motion
 5  minimum rod-side pressure P_b, retracting              retract motion
 6  air consumed through line A, extending                 extend step
 7  air exhausted through line B, extending                extend step
 8  air consumed through line B, retracting (*)            retract step
 9  air exhausted through line A, retracting (*)           retract step
10  maximum exhaust flow from chamber A, retracting        retract step
11  maximum exhaust flow from chamber B, extending         extend step
12  stroke time t_s, extending                             -
13  stroke time t_s, retracting                            -
==  =====================================================  ====================

(*) Table 4.4 prints "consumed flow in chamber A" and "exhaust flow in chamber B"
for the retracting stroke: while retracting, chamber A exhausts and chamber B fills,
so the letters are read as swapped (the retract-stroke consumption of Tables
4.2/4.3 is the B line's). "Motion" is from motion start to arrival (section 3.3);
"step" is from the valve firing to the next step's start. Table 4.5 gives the
direction each feature moves with extend-line, retract-line and supply leaks.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pneufdd.features.air import consumed, exhausted, min_supply_pressure
from pneufdd.features.context import CycleView
from pneufdd.features.motion import _times, max_exhaust
from pneufdd.features.registry import register

__all__ = ["TABLE_4_5", "TABLE_44_NAMES"]

TABLE_44_NAMES: tuple[str, ...] = (
    "t44_01_p_supply_min_Pa",
    "t44_02_p_a_min_extend_Pa",
    "t44_03_p_a_max_retract_Pa",
    "t44_04_p_b_max_extend_Pa",
    "t44_05_p_b_min_retract_Pa",
    "t44_06_air_a_extend_SL",
    "t44_07_exhaust_b_extend_SL",
    "t44_08_air_b_retract_SL",
    "t44_09_exhaust_a_retract_SL",
    "t44_10_exhaust_flow_max_a_retract_kg_s",
    "t44_11_exhaust_flow_max_b_extend_kg_s",
    "t44_12_t_s_extend_s",
    "t44_13_t_s_retract_s",
)
"""Stable names of the 13 features of Table 4.4, in the table's order."""

TABLE_4_5: dict[str, str] = {
    "extend": "---0++00++-+-",
    "retract": "-+0-------+-+",
    "both": "-0000+-00+0+0",
    "supply": "--0-0+0+0--++",
}
"""Table 4.5: the sign (+, -, 0) of each feature's change with a growing leak in the
extend line, the retract line, both lines, and the supply line."""


def _extreme(
    view: CycleView, act: str, motion: str, side: str, pick: Callable[..., float]
) -> float:
    s = _times(view, act, motion)
    return float(pick(view.window(f"P_{act}_{side}", s.t_start, s.t_end + 1e-9)))


@register(TABLE_44_NAMES[0], "actuator", "Pa", "table44", ("P_In",))
def f01(view: CycleView, act: str) -> float:
    """Table 4.4 #1: minimum supply pressure over both stroke steps [Pa]."""
    return min(min_supply_pressure(view, act, "extend"), min_supply_pressure(view, act, "retract"))


@register(TABLE_44_NAMES[1], "actuator", "Pa", "table44", ("P_{act}_A",))
def f02(view: CycleView, act: str) -> float:
    """Table 4.4 #2: minimum blind-side pressure during the extend motion [Pa]."""
    return _extreme(view, act, "extend", "A", np.nanmin)


@register(TABLE_44_NAMES[2], "actuator", "Pa", "table44", ("P_{act}_A",))
def f03(view: CycleView, act: str) -> float:
    """Table 4.4 #3: maximum blind-side pressure during the retract motion [Pa]."""
    return _extreme(view, act, "retract", "A", np.nanmax)


@register(TABLE_44_NAMES[3], "actuator", "Pa", "table44", ("P_{act}_B",))
def f04(view: CycleView, act: str) -> float:
    """Table 4.4 #4: maximum rod-side pressure during the extend motion [Pa]."""
    return _extreme(view, act, "extend", "B", np.nanmax)


@register(TABLE_44_NAMES[4], "actuator", "Pa", "table44", ("P_{act}_B",))
def f05(view: CycleView, act: str) -> float:
    """Table 4.4 #5: minimum rod-side pressure during the retract motion [Pa]."""
    return _extreme(view, act, "retract", "B", np.nanmin)


def _step(view: CycleView, act: str, motion: str) -> tuple[float, float]:
    step = view.stroke(act, motion).step
    return step.start_s, step.end_s


@register(TABLE_44_NAMES[5], "actuator", "SL", "table44", ("Q_{act}_A",))
def f06(view: CycleView, act: str) -> float:
    """Table 4.4 #6: air consumed through line A in the extend step [SL] (eq. 4.17)."""
    return consumed(view, f"Q_{act}_A", *_step(view, act, "extend"))


@register(TABLE_44_NAMES[6], "actuator", "SL", "table44", ("Q_{act}_B",))
def f07(view: CycleView, act: str) -> float:
    """Table 4.4 #7: air exhausted through line B in the extend step [SL] (eq. 4.17)."""
    return exhausted(view, f"Q_{act}_B", *_step(view, act, "extend"))


@register(TABLE_44_NAMES[7], "actuator", "SL", "table44", ("Q_{act}_B",))
def f08(view: CycleView, act: str) -> float:
    """Table 4.4 #8: air consumed through line B in the retract step [SL] (eq. 4.17)."""
    return consumed(view, f"Q_{act}_B", *_step(view, act, "retract"))


@register(TABLE_44_NAMES[8], "actuator", "SL", "table44", ("Q_{act}_A",))
def f09(view: CycleView, act: str) -> float:
    """Table 4.4 #9: air exhausted through line A in the retract step [SL] (eq. 4.17)."""
    return exhausted(view, f"Q_{act}_A", *_step(view, act, "retract"))


@register(TABLE_44_NAMES[9], "actuator", "kg/s", "table44", ("Q_{act}_A",))
def f10(view: CycleView, act: str) -> float:
    """Table 4.4 #10: maximum exhaust flow from chamber A in the retract step [kg/s]."""
    return max_exhaust(view, act, "retract")


@register(TABLE_44_NAMES[10], "actuator", "kg/s", "table44", ("Q_{act}_B",))
def f11(view: CycleView, act: str) -> float:
    """Table 4.4 #11: maximum exhaust flow from chamber B in the extend step [kg/s]."""
    return max_exhaust(view, act, "extend")


@register(TABLE_44_NAMES[11], "actuator", "s", "table44")
def f12(view: CycleView, act: str) -> float:
    """Table 4.4 #12: stroke time t_s of the extend stroke [s] (section 3.3)."""
    s = _times(view, act, "extend")
    return s.t_end - s.t_start


@register(TABLE_44_NAMES[12], "actuator", "s", "table44")
def f13(view: CycleView, act: str) -> float:
    """Table 4.4 #13: stroke time t_s of the retract stroke [s] (section 3.3)."""
    s = _times(view, act, "retract")
    return s.t_end - s.t_start
