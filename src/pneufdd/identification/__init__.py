"""Identification of the machine's parameters from measurements (dissertation chapter 4).

Pure functions, one file per component: the directional valve's Cv and xT with the
zero-flow correction (:mod:`.valve`, section 4.2.1, Figs. 4.7-4.9), a cylinder's
friction (:mod:`.friction`, eqs. 4.14-4.16), the supply path (:mod:`.supply`,
Fig. 4.13, eqs. 4.19-4.21), a leak's equivalent orifice from a closed volume's
pressure decay (:mod:`.decay`, eqs. 4.3, 4.7-4.10) and a seal's friction against
pressure from a driven piston (:mod:`.seal_friction`). The twin-in-the-loop
calibration of a whole machine description is :mod:`pneufdd.calibration`.

May import: :mod:`pneufdd.physics` and the shared helpers only.
"""

from __future__ import annotations

from pneufdd.identification.decay import DecayFit, decay_start, fit_pressure_decay
from pneufdd.identification.friction import (
    BreakawayFit,
    SlidingFrictionFit,
    fit_breakaway_friction,
    fit_sliding_friction,
)
from pneufdd.identification.seal_friction import (
    SealFrictionFit,
    SealFrictionRun,
    breakaway_forces,
    fit_seal_friction,
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
    "DecayFit",
    "SealFrictionFit",
    "SealFrictionRun",
    "SlidingFrictionFit",
    "SupplyPathFit",
    "ValveFit",
    "breakaway_forces",
    "decay_start",
    "fit_breakaway_friction",
    "fit_pressure_decay",
    "fit_seal_friction",
    "fit_sliding_friction",
    "fit_supply_path",
    "fit_valve",
    "nominal_flow_l_min",
    "zero_flow_drop",
]
