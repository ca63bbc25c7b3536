"""Standby: the air a stopped machine uses with the air on, and what a restart costs.

Section 6.2.1's procedure measures "consumption ... in running and standby mode". At
standstill a machine uses air only through its leaks (a supply leak blows all the
time, a line leak while its line holds pressure: behind a 5/2 valve the line it last
drove, behind a 5/3 closed-centre valve until the isolated chamber is empty) and any
ejector left on. The twin measures it by stopping the machine after a cycle, in the
state the cycle leaves it, for :data:`STANDSTILL_S`, and averaging the supply flow
over the last half of that time (the chambers have settled). Switching the air off
at standstill (a shut-off / soft-start valve after the regulator) saves that flow,
and costs one refill of the machine's volumes per restart.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pneufdd.energy.changes import standstill
from pneufdd.physics.constants import P_ATM, R_AIR
from pneufdd.physics.flow import isa_mass_flow
from pneufdd.physics.units import psig_to_pa
from pneufdd.sim import layout as lay
from pneufdd.sim.compile import compile_plant, series_cv
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import Leak
from pneufdd.sim.simulate import run_simulation

__all__ = ["STANDSTILL_S", "Standby", "twin_standby"]

STANDSTILL_S = 20.0
"""How long the twin stands still after a cycle; the flow is averaged over its second
half [s]."""


@dataclass(frozen=True)
class Standby:
    """A stopped machine's air.

    Attributes
    ----------
    flow_kg_s : float
        Supply flow at standstill with the air on (twin) [kg/s].
    refill_kg : float
        Air that pressurises the machine's volumes again after they were vented [kg].
    refill_s : float
        Rough time to refill them through the regulator and supply line [s].
    measured_flow_kg_s : float or None
        Mean ``Q_In`` over the recordings' idle stretches (None: there were none).
    measured_idle_s : float
        Length of those stretches [s].
    """

    flow_kg_s: float
    refill_kg: float
    refill_s: float
    measured_flow_kg_s: float | None = None
    measured_idle_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {
            "twin_flow_kg_s": self.flow_kg_s,
            "measured_flow_kg_s": self.measured_flow_kg_s,
            "measured_idle_s": self.measured_idle_s,
            "refill_kg": self.refill_kg,
            "refill_s": self.refill_s,
        }


def twin_standby(machine: MachineDescription, leaks: Sequence[Leak] = (), seed: int = 0) -> Standby:
    """The twin's standstill flow and refill air (no measured idle time).

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> m = load_machine("press-fit-cell")
    >>> leak_free = twin_standby(m)
    >>> leak_free.flow_kg_s < 1e-6, leak_free.refill_kg > 0  # air still cooling: < 1 mg/s
    (True, True)
    >>> twin_standby(m, [Leak("supply", 1.0, "mm")]).flow_kg_s > 1e-4
    True
    """
    stopped = standstill(machine, STANDSTILL_S)
    result = run_simulation(stopped, cycles=2, leaks=list(leaks), seed=seed)
    out = result.outputs
    start = float(result.step_start[-1, -1])
    i0 = round((start + STANDSTILL_S / 2) / lay.SAMPLE_DT)
    i1 = round((start + STANDSTILL_S) / lay.SAMPLE_DT)
    flow = float(np.mean(out["mdot_supply_line"][i0:i1]))
    plant = compile_plant(machine, [])
    volumes = [plant.sp[lay.SP_V_RES], plant.sp[lay.SP_V_MAN]]
    pressures = [out["p_reservoir"][i1 - 1], out["p_manifold"][i1 - 1]]
    for i, a in enumerate(machine.actuators):
        x = float(out[f"x_{a.id}"][i1 - 1])
        for side, travel in enumerate((x, a.stroke_mm * 1e-3 - x)):
            c = 2 * i + side
            volumes.append(plant.cp[c, lay.CP_DEAD] + plant.cp[c, lay.CP_AREA] * travel)
            pressures.append(out[f"p_{a.id}_{'AB'[side]}"][i1 - 1])
    t_wall = plant.t_wall
    refill = float(sum((p - P_ATM) * v for p, v in zip(pressures, volumes, strict=True)))
    refill /= R_AIR * t_wall
    s = machine.supply
    capacity = float(
        isa_mass_flow(
            psig_to_pa(s.house_psig),
            0.5 * (psig_to_pa(s.regulator_set_psig) + P_ATM),
            series_cv(s.regulator_cv, s.line_cv),
            min(s.regulator_xt, s.line_xt),
            t_wall,
        )
    )
    refill_s = refill / capacity if capacity > 0 else math.inf
    return Standby(max(flow, 0.0), max(refill, 0.0), refill_s)
