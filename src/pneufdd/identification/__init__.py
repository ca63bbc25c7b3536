"""Identification of the machine's parameters from measurements (dissertation chapter 4).

Pure functions, one file per component: the directional valve's Cv and xT with the
zero-flow correction (:mod:`.valve`, section 4.2.1, Figs. 4.7-4.9), a cylinder's
friction (:mod:`.friction`, eqs. 4.14-4.16) and the supply path (:mod:`.supply`,
Fig. 4.13, eqs. 4.19-4.21). The twin-in-the-loop calibration of a whole machine
description is :mod:`pneufdd.calibration`.

May import: :mod:`pneufdd.physics` and the shared helpers only.
"""

from __future__ import annotations

from pneufdd.identification.friction import (
    BreakawayFit,
    SlidingFrictionFit,
    fit_breakaway_friction,
    fit_sliding_friction,
)
from pneufdd.identification.supply import SupplyPathFit, fit_supply_path
from pneufdd.identification.valve import (
    ValveFit,
    fit_valve,
    nominal_flow_l_min,
    zero_flow_drop,
)

__all__ = [
    "BreakawayFit",
    "SlidingFrictionFit",
    "SupplyPathFit",
    "ValveFit",
    "fit_breakaway_friction",
    "fit_sliding_friction",
    "fit_supply_path",
    "fit_valve",
    "nominal_flow_l_min",
    "zero_flow_drop",
]
