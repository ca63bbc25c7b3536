"""Where the twin's air goes: exact per-component bookkeeping of a simulation.

The twin's kernel already records, per 1 ms sample, the air each chamber draws from
the manifold through its valve (``mdot_in_<ACT>_<side>``), what it exhausts and what
leaks from it, the supply leak and the ejector (:class:`pneufdd.sim.SimulationResult`).
This module splits that air, after the run and without touching the kernel, into
what a plant engineer asks about:

* **stroke**: the air that fills an actuator's swept volume (the work it does);
* **dead volume** and **tube**: the air that pressurises the cylinder's inactive
  volumes (cushions, ports) and the tube from the valve, lost at every exhaust;
* **leak**: air that left through a leak (a line leak's air came in through its valve);
* **vacuum**: the ejector's nozzle air;
* **storage**: the change of the air stored in reservoir and manifold over the window
  (zero over whole cycles of a running machine, up to the house-air drift).

Per chamber :math:`c` the air in it is :math:`m_c = m_{c,0} + \\int (\\dot m_{in} -
\\dot m_{exh} - \\dot m_{leak})\\,dt` (the kernel conserves mass exactly, so the
integral of its recorded flows is its mass), its density :math:`\\rho_c = m_c / V_c`
with :math:`V_c = V_{dead} + A x` (eq. 4.11). A *fill* runs from a chamber's first
inflow after an exhaust to the next exhaust. During a fill the gas is one mixture, so
the part of it that pressurises the dead volume and tube is

.. math:: m_{dead} = V_{dead}\\,(\\rho_{end} - \\rho_{start})

(the volume that stays while the piston sweeps the rest), split between cylinder dead
volume and tube by their volumes; the chamber's leak over the fill's period is leak
air; the rest of the fill's inflow is stroke air. The shares are applied to every
sample of the fill's inflow, so steps get their part; over whole cycles the categories
sum to the supply air exactly (the test checks it to 1e-9 relative).

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, eq. 4.7-4.11 (chamber mass, volume), section 6.2.1 (where the air goes).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.sim import layout as lay
from pneufdd.sim.compile import compile_plant, initial_state
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.result import SimulationResult
from pneufdd.sim.simulate import RUN_END_IDLE_S

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["CATEGORIES", "TwinAir", "step_windows", "twin_air"]

CATEGORIES = ("stroke", "dead volume", "tube", "leak", "vacuum", "storage")
"""Kinds of air use; a component is ``<actuator>.<kind>``, ``leak.<location>``,
``vacuum`` or ``storage``."""


@dataclass(frozen=True)
class TwinAir:
    """The twin's air per step and component, averaged over the cycles measured.

    Attributes
    ----------
    components : tuple of str
        ``<ACT>.stroke``, ``<ACT>.dead volume``, ``<ACT>.tube``, ``leak.<location>``,
        ``vacuum``, ``storage``.
    air_kg : ndarray, shape (n_steps, n_components)
        Mean air per cycle of each component in each step [kg].
    supply_kg : ndarray, shape (n_steps,)
        Mean air through the supply line (the ``Q_In`` meter) per step [kg].
    duration_s : ndarray, shape (n_steps,)
        Mean step duration [s].
    cycles : int
        Cycles averaged.
    lines_kg : dict of str to float
        Air each line ``<ACT>_A``/``_B`` drew from the manifold per cycle (what a line
        flow meter between valve and cylinder sees) [kg].
    """

    components: tuple[str, ...]
    air_kg: FloatArray
    supply_kg: FloatArray
    duration_s: FloatArray
    cycles: int
    lines_kg: dict[str, float] = field(default_factory=dict)

    @property
    def cycle_time_s(self) -> float:
        """Mean cycle time [s]."""
        return float(np.sum(self.duration_s))

    @property
    def per_cycle_kg(self) -> dict[str, float]:
        """Air per cycle of each component [kg]."""
        total = self.air_kg.sum(axis=0)
        return {name: float(v) for name, v in zip(self.components, total, strict=True)}

    def actuator_kg(self, actuator: str) -> float:
        """An actuator's air per cycle, its leaks excluded (stroke + dead volume + tube) [kg]."""
        return sum(v for k, v in self.per_cycle_kg.items() if k.split(".")[0] == actuator)

    def to_pandas(self) -> pd.DataFrame:
        """Air per step (rows, 1-based) and component (columns) [kg]."""
        import pandas as pd

        frame = pd.DataFrame(self.air_kg, columns=list(self.components))
        frame.index = pd.RangeIndex(1, self.air_kg.shape[0] + 1, name="step")
        return frame


def step_windows(
    result: SimulationResult, skip_first: bool = True
) -> tuple[FloatArray, FloatArray]:
    """Start and end of every step [s], cycles x steps; the first cycle left out.

    The twin's first cycle starts from rest (``skip_first`` leaves it out when the run
    has more than one); the last step of the run ends where the idle tail begins.
    """
    starts = np.asarray(result.step_start, dtype=np.float64)
    last = float(result.time[-1]) + lay.SAMPLE_DT - RUN_END_IDLE_S
    ends = np.r_[starts.ravel()[1:], last].reshape(starts.shape)
    skip = 1 if skip_first and starts.shape[0] > 1 else 0
    return starts[skip:], ends[skip:]


def _chamber_volumes(machine: MachineDescription) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per chamber (2 i + side): piston area [m^2], cylinder dead volume, tube volume [m^3]."""
    plant = compile_plant(machine, [])
    area = plant.cp[:, lay.CP_AREA].copy()
    total_dead = plant.cp[:, lay.CP_DEAD].copy()
    tube = np.zeros_like(total_dead)
    for i, a in enumerate(machine.actuators):
        tube_vol = math.pi * (a.tube_inner_diameter_mm * 1e-3) ** 2 / 4 * a.tube_length_m
        tube[2 * i] = tube_vol
        if a.valve.kind != "3/2-monostable":  # a vented spring side has no tube
            tube[2 * i + 1] = tube_vol
    return area, total_dead - tube, tube


def _fill_shares(
    inflow: FloatArray,
    exhaust: FloatArray,
    leak: FloatArray,
    density: FloatArray,
    dead_total: float,
) -> tuple[FloatArray, FloatArray]:
    """Per sample: the dead-volume and leak parts of a chamber's inflow [kg/s].

    ``inflow``, ``exhaust``, ``leak`` are the chamber's mean flows per sample [kg/s],
    ``density`` its air density at each sample's start [kg/m^3] (one more entry: the
    end of the last sample) and ``dead_total`` its dead volume with the tube [m^3].
    """
    n = inflow.size
    dead = np.zeros(n)
    leaked = np.zeros(n)
    filling = inflow > 0.0
    exhausting = exhaust > 0.0
    if not filling.any():
        return dead, leaked
    # a fill starts at the first inflow after an exhaust (or the window's start)
    fill_idx = np.flatnonzero(filling)
    exhausts_before = np.cumsum(exhausting)[fill_idx]
    new = np.r_[True, exhausts_before[1:] != exhausts_before[:-1]]
    exhaust_idx = np.flatnonzero(exhausting)
    bounds = [*(int(k) for k in fill_idx[new]), n]
    for a, b in itertools.pairwise(bounds):
        # the fill ends where the next exhaust begins (or at the period's end)
        exh = exhaust_idx[(exhaust_idx >= a) & (exhaust_idx < b)]
        fill_end = int(exh[0]) if exh.size else b
        fill = filling[a:fill_end]
        total_in = float(np.sum(inflow[a:fill_end][fill])) * lay.SAMPLE_DT
        if total_in <= 0.0:
            continue
        rho_end = density[fill_end]
        m_dead = dead_total * max(rho_end - density[a], 0.0)
        m_leak = float(np.sum(leak[a:b])) * lay.SAMPLE_DT
        leak_share = min(m_leak / total_in, 1.0)
        dead_share = min(m_dead / total_in, 1.0 - leak_share)
        sel = np.arange(a, fill_end)[fill]
        dead[sel] = dead_share * inflow[sel]
        leaked[sel] = leak_share * inflow[sel]
    return dead, leaked


def _window_sum(values: FloatArray, start: FloatArray, end: FloatArray) -> FloatArray:
    """Sum of per-sample values x SAMPLE_DT over each [start, end) window [kg]."""
    csum = np.concatenate([[0.0], np.cumsum(values)]) * lay.SAMPLE_DT
    i0 = np.clip(np.round(start / lay.SAMPLE_DT).astype(np.int64), 0, values.size)
    i1 = np.clip(np.round(end / lay.SAMPLE_DT).astype(np.int64), 0, values.size)
    return np.asarray(csum[i1] - csum[i0])


def twin_air(result: SimulationResult, skip_first: bool = True) -> TwinAir:
    """Split a twin run's supply air into components, per step, mean over cycles.

    Parameters
    ----------
    result : SimulationResult
        A run with its internal states (``keep_outputs=True``).
    skip_first : bool
        Leave out the first cycle (started from rest) when there are more.

    Returns
    -------
    TwinAir

    Examples
    --------
    >>> from pneufdd.sim import run_simulation
    >>> air = twin_air(run_simulation("press-fit-cell", cycles=3, seed=1))
    >>> total = sum(air.per_cycle_kg.values())
    >>> bool(abs(total - air.supply_kg.sum()) < 1e-9 * total)
    True
    """
    out = result.outputs
    machine = result.machine
    start, end = step_windows(result, skip_first)
    area, cyl_dead, tube = _chamber_volumes(machine)
    plant = compile_plant(machine, result.leaks)
    mass0 = initial_state(machine, plant)["m"]
    names: list[str] = []
    series: list[FloatArray] = []
    lines: dict[str, float] = {}
    for i, a in enumerate(machine.actuators):
        parts = np.zeros((3, result.time.size))
        for side, label in enumerate("AB"):
            c = 2 * i + side
            inflow = np.asarray(out[f"mdot_in_{a.id}_{label}"], np.float64)
            drawn = _window_sum(inflow, start.ravel(), end.ravel())
            lines[f"{a.id}_{label}"] = float(np.sum(drawn) / start.shape[0])
            exhaust = np.asarray(out[f"mdot_exhaust_{a.id}_{label}"], np.float64)
            leak = np.asarray(out[f"mdot_leak_{a.id}_{label}"], np.float64)
            net = (inflow - exhaust - leak) * lay.SAMPLE_DT
            mass = mass0[2 + c] + np.concatenate([[0.0], np.cumsum(net)])
            x = np.asarray(out[f"x_{a.id}"], np.float64)
            travel = x if side == 0 else machine_stroke(a) - x
            vol = cyl_dead[c] + tube[c] + area[c] * np.r_[travel, travel[-1]]
            dead, leaked = _fill_shares(inflow, exhaust, leak, mass / vol, cyl_dead[c] + tube[c])
            volume_dead = cyl_dead[c] + tube[c]
            tube_part = tube[c] / volume_dead if volume_dead > 0 else 0.0
            parts[0] += inflow - dead - leaked
            parts[1] += dead * (1.0 - tube_part)
            parts[2] += dead * tube_part
            names_leak = f"leak.{a.id}_{label}"
            if np.any(leak > 0.0):
                names.append(names_leak)
                series.append(leaked)
        for kind, values in zip(("stroke", "dead volume", "tube"), parts, strict=True):
            names.append(f"{a.id}.{kind}")
            series.append(values)
    if np.any(out["mdot_leak_supply"] > 0.0):
        names.append("leak.supply")
        series.append(np.asarray(out["mdot_leak_supply"], np.float64))
    if machine.vacuum is not None:
        names.append("vacuum")
        series.append(np.asarray(out["mdot_vacuum"], np.float64))
    supply = np.asarray(out["mdot_supply_line"], np.float64)
    explained = np.sum(series, axis=0) if series else np.zeros_like(supply)
    names.append("storage")
    series.append(supply - explained)
    air = np.stack([_window_sum(s, start.ravel(), end.ravel()) for s in series], axis=1)
    n_steps = start.shape[1]
    air = air.reshape(start.shape[0], n_steps, -1).mean(axis=0)
    supply_kg = _window_sum(supply, start.ravel(), end.ravel()).reshape(start.shape).mean(axis=0)
    order = _order(names)
    return TwinAir(
        components=tuple(names[k] for k in order),
        air_kg=air[:, order],
        supply_kg=supply_kg,
        duration_s=(end - start).mean(axis=0),
        cycles=int(start.shape[0]),
        lines_kg=lines,
    )


def machine_stroke(actuator: Any) -> float:
    """An actuator's stroke [m]."""
    return float(actuator.stroke_mm) * 1e-3


def _order(names: list[str]) -> npt.NDArray[np.int64]:
    """Actuators in description order (stroke, dead volume, tube), then leaks, vacuum, storage."""
    rank = {"leak": 1, "vacuum": 2, "storage": 3}

    def key(k: int) -> tuple[int, int]:
        head = names[k].split(".")[0]
        return (rank.get(head, 0), k)

    return np.array(sorted(range(len(names)), key=key), dtype=np.int64)
