"""One twin run of a candidate machine, summarised for the energy questions.

Every what-if and every set point is judged by running the twin (the calibrated
description the reference keeps, or ``--machine``) for a few cycles with the same seed
(common random numbers: the house-air drift, friction scatter and PLC jitter are the
same in every candidate, so differences are the change's). The first cycle starts
from rest and is left out.

The twin runs the *mean machine* (:func:`mean_machine`): the description without its
per-cycle friction scatter. The questions are about the machine's mean behaviour (how
much slower is a step on average at a lower set point), and a few cycles with scatter
answer them with a sampling error: at the low pressures of the what-ifs friction is a
large part of the driving force, so 3 % of friction scatter moved a step of
press-fit-cell by 30 ms from cycle to cycle (1.6 bar(g), flow controls opened), and the
lowest set point of one plant by 4 psi (0.28 bar) from one seed to another.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.energy.bookkeeping import TwinAir, step_windows, twin_air
from pneufdd.physics.constants import P_ATM
from pneufdd.sim.compile import piston_areas
from pneufdd.sim.description import MachineDescription, parse_description
from pneufdd.sim.leaks import Leak
from pneufdd.sim.result import SimulationResult
from pneufdd.sim.simulate import MachineStalledError, run_simulation

__all__ = ["DEFAULT_CYCLES", "TwinRun", "mean_machine", "run_twin", "step_actuators"]

DEFAULT_CYCLES = 3
"""Twin cycles per candidate; the first (from rest) is left out [-]."""


@dataclass(frozen=True)
class TwinRun:
    """A candidate machine's cycle in the twin.

    Attributes
    ----------
    machine : MachineDescription
        The candidate.
    air : TwinAir or None
        Its air per step and component (None when it stalled).
    forces_n : dict of int to float
        For each force-holding step (index), the smallest static pneumatic force the
        actuator holds at the step's end, in the required direction [N].
    stroke_s : dict of (int, str) to float
        Mean stroke time of each actuator moving in each step (index, actuator) [s].
    stroke_direction : dict of (int, str) to int
        Its direction: +1 extend (exhausts the B line), -1 retract (exhausts A).
    stalled : str
        Why the machine stalled ('' when it did not).
    """

    machine: MachineDescription
    air: TwinAir | None
    forces_n: dict[int, float] = field(default_factory=dict)
    stroke_s: dict[tuple[int, str], float] = field(default_factory=dict)
    stroke_direction: dict[tuple[int, str], int] = field(default_factory=dict)
    stalled: str = ""

    @property
    def duration_s(self) -> FloatArray:
        """Mean step durations [s] (NaN when stalled)."""
        if self.air is None:
            return np.full(len(self.machine.steps), np.nan)
        return self.air.duration_s

    @property
    def cycle_time_s(self) -> float:
        """Mean cycle time [s] (NaN when stalled)."""
        return float("nan") if self.air is None else self.air.cycle_time_s

    def actuator_air(self, actuator: str) -> float:
        """An actuator's air per cycle, its leaks excluded [kg] (NaN when stalled)."""
        return float("nan") if self.air is None else self.air.actuator_kg(actuator)

    @property
    def supply_kg(self) -> float:
        """Supply air per cycle [kg] (NaN when stalled)."""
        return float("nan") if self.air is None else float(self.air.supply_kg.sum())


def mean_machine(machine: MachineDescription) -> MachineDescription:
    """``machine`` without its per-cycle friction scatter: the machine's mean behaviour.

    Everything else random stays (the PLC scan jitter, the house-air drift): common
    random numbers cancel them in a candidate's difference to the present machine,
    whereas the friction draws, the same in both, act differently at another pressure.

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> m = load_machine("press-fit-cell")
    >>> m.friction_scatter, mean_machine(m).friction_scatter, mean_machine(m).name == m.name
    (0.03, 0.0, True)
    """
    if machine.friction_scatter == 0.0:
        return machine
    raw = copy.deepcopy(machine.raw)
    raw.setdefault("machine", {})["friction_scatter"] = 0.0
    return parse_description(raw, source=machine.source)


def step_actuators(run: TwinRun) -> dict[int, tuple[str, ...]]:
    """The actuators that stroke in each step, the one whose stroke is longest first."""
    found: dict[int, list[tuple[float, str]]] = {}
    for (step, ident), seconds in run.stroke_s.items():
        found.setdefault(step, []).append((seconds, ident))
    return {k: tuple(i for _, i in sorted(v, reverse=True)) for k, v in found.items()}


def _strokes(
    result: SimulationResult, start: FloatArray, end: FloatArray
) -> tuple[dict[tuple[int, str], float], dict[tuple[int, str], int]]:
    """Mean stroke time [s] and direction per (step, actuator) over the measured cycles."""
    flat_start = start.ravel()
    flat_end = end.ravel()
    n_steps = start.shape[1]
    times: dict[tuple[int, str], list[float]] = {}
    direction: dict[tuple[int, str], int] = {}
    for stroke in result.strokes:
        k = int(np.searchsorted(flat_start, stroke.first_motion, side="right")) - 1
        if k < 0 or stroke.first_motion >= flat_end[k]:
            continue
        key = (k % n_steps, stroke.actuator)
        times.setdefault(key, []).append(stroke.duration)
        direction[key] = stroke.direction
    return {key: float(np.mean(v)) for key, v in times.items()}, direction


def _forces(
    result: SimulationResult, machine: MachineDescription, end: FloatArray
) -> dict[int, float]:
    """Smallest static force at the end of each force-holding step [N] (eq. 4.13, spring)."""
    out = result.outputs
    forces: dict[int, float] = {}
    ids = machine.actuator_ids
    for k, step in enumerate(machine.steps):
        if step.required_force_n <= 0.0:
            continue
        actuator = machine.actuators[ids.index(step.force_actuator)]
        area_a, area_b, rod = piston_areas(actuator)
        idx = np.clip(np.round(end[:, k] / 1e-3).astype(np.int64) - 2, 0, result.time.size - 1)
        p_a = np.asarray(out[f"p_{actuator.id}_A"])[idx]
        p_b = np.asarray(out[f"p_{actuator.id}_B"])[idx]
        x = np.asarray(out[f"x_{actuator.id}"])[idx]
        net = p_a * area_a - p_b * area_b - P_ATM * rod
        net = net - (actuator.spring_preload_n + actuator.spring_rate_n_per_mm * x * 1e3)
        forces[k] = float(np.min(step.force_direction * net))
    return forces


def run_twin(
    machine: MachineDescription,
    leaks: Sequence[Leak] = (),
    cycles: int = DEFAULT_CYCLES,
    seed: int = 0,
    max_cycle_s: float = 120.0,
) -> TwinRun:
    """Run ``machine`` in the twin and summarise it (a stall is a result, not an error).

    Parameters
    ----------
    machine : MachineDescription
        The candidate.
    leaks : sequence of Leak
        Leaks to keep in it (the diagnosed ones, as holes: ``unit="mm"``).
    cycles : int
        Cycles to run; the first is left out.
    seed : int
        Seed (the same for every candidate).
    max_cycle_s : float
        A cycle longer than this is a stall [s] (a candidate several times slower than
        the present machine fails anyway; stopping it early saves the twin's time).

    Returns
    -------
    TwinRun

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> run = run_twin(load_machine("press-fit-cell"))
    >>> round(run.cycle_time_s, 2), run.stalled
    (3.14, '')
    """
    try:
        result = run_simulation(
            machine, cycles=cycles, leaks=list(leaks), seed=seed, max_cycle_s=max_cycle_s
        )
    except MachineStalledError as exc:
        return TwinRun(machine, None, stalled=str(exc))
    start, end = step_windows(result)
    times, direction = _strokes(result, start, end)
    return TwinRun(
        machine=machine,
        air=twin_air(result),
        forces_n=_forces(result, machine, end),
        stroke_s=times,
        stroke_direction=direction,
    )
