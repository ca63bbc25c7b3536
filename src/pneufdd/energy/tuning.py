"""The twin sets the meter-out flow controls a candidate needs to keep its step times.

A meter-out flow control (section 3.2.3, one-way: it throttles the exhaust only) sets
a stroke's speed; the pressure sets the force that drives it. At a lower pressure a
stroke slows down, and opening the flow control on the line it exhausts (B for an
extend, A for a retract) brings its speed back, until the valve and tube limit it.
:func:`fit_throttles` finds, for each line it may open, the smallest opening (a Cv
factor >= 1) at which the steps that line's strokes end keep their allowance: a
bisection in log factor for every line at once, each line judged by its own steps
(strokes of different actuators in one step are judged by the longest).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pneufdd.energy.changes import MAX_THROTTLE_CV, Change, apply_changes
from pneufdd.energy.pressure import Verdict, allowances, candidate_limit_s, judge
from pneufdd.energy.settings import EnergySettings
from pneufdd.energy.twin import TwinRun, run_twin
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import Leak

__all__ = ["ThrottleFit", "critical_lines", "fit_throttles", "throttle_changes"]

Line = tuple[str, str]  # (actuator, "a" | "b")

ROUNDS = 5
"""Bisection rounds in log factor (the bracket shrinks 32-fold) [-]."""


@dataclass(frozen=True)
class ThrottleFit:
    """The flow-control openings found and the run with them.

    Attributes
    ----------
    factors : dict of (str, str) to float
        Cv factor of each opened line's flow control, (actuator, "a"/"b") [-].
    run : TwinRun
        The candidate with those openings.
    verdict : Verdict
        Its verdict.
    """

    factors: dict[Line, float]
    run: TwinRun
    verdict: Verdict


def critical_lines(base: TwinRun, among: Sequence[Line] | None = None) -> dict[int, Line]:
    """For each step with a stroke: the line whose flow control sets its end.

    The actuator whose stroke in the step is longest (among the strokes on ``among``'s
    lines when given), and the line that stroke exhausts (B for an extend, A for a
    retract).
    """
    keep = None if among is None else set(among)
    found: dict[int, tuple[float, Line]] = {}
    for (step, ident), seconds in base.stroke_s.items():
        side = "b" if base.stroke_direction.get((step, ident), 1) > 0 else "a"
        if keep is not None and (ident, side) not in keep:
            continue
        if step not in found or seconds > found[step][0]:
            found[step] = (seconds, (ident, side))
    return {k: v[1] for k, v in found.items()}


def throttle_changes(factors: dict[Line, float]) -> list[Change]:
    """The changes that open the flow controls by ``factors`` (one per actuator)."""
    per: dict[str, dict[str, float]] = {}
    for (ident, side), f in factors.items():
        per.setdefault(ident, {"factor_a": 1.0, "factor_b": 1.0})[f"factor_{side}"] = f
    return [Change("throttles", ident, values) for ident, values in sorted(per.items())]


def _max_factor(machine: MachineDescription, line: Line) -> float:
    ident, side = line
    actuator = next(a for a in machine.actuators if a.id == ident)
    cv = actuator.meter_out_cv_a if side == "a" else actuator.meter_out_cv_b
    return max(MAX_THROTTLE_CV / cv, 1.0)


def fit_throttles(
    make: Callable[[dict[Line, float]], Sequence[Change]],
    machine: MachineDescription,
    base: TwinRun,
    lines: Sequence[Line],
    leaks: Sequence[Leak] = (),
    settings: EnergySettings | None = None,
) -> ThrottleFit:
    """Open the flow controls of ``lines`` as little as the step allowances permit.

    Parameters
    ----------
    make : callable
        ``make(factors)``: the candidate's changes with those flow-control factors.
    machine : MachineDescription
        The present machine (the changes apply to it).
    base : TwinRun
        The present machine's run (the step times to keep, the strokes' lines).
    lines : sequence of (str, str)
        The lines whose flow controls may open.
    leaks, settings
        As for :func:`pneufdd.energy.twin.run_twin`.

    Returns
    -------
    ThrottleFit
        Feasible when every step keeps its allowance with the openings found; the
        openings are then the smallest found to 1/32 of their log range.
    """
    settings = settings or EnergySettings()
    allowed = allowances(base, settings)
    owner = critical_lines(base, lines)
    wanted = set(lines)

    def run(factors: dict[Line, float]) -> tuple[TwinRun, Verdict, dict[Line, float]]:
        candidate = apply_changes(machine, make(factors))
        twin = run_twin(candidate, leaks, settings.cycles, settings.seed, candidate_limit_s(base))
        verdict = judge(twin, base, allowed, settings.cycle_time_needed_s)
        excess: dict[Line, float] = {}
        if twin.air is not None:
            over = twin.duration_s - base.duration_s - allowed
            for step, line in owner.items():
                if line in wanted:
                    excess[line] = max(excess.get(line, -math.inf), float(over[step]))
        else:
            excess = {line: math.inf for line in wanted}
        return twin, verdict, excess

    ones = {line: 1.0 for line in wanted}
    twin, verdict, excess = run(ones)
    needy = [line for line in wanted if excess.get(line, -1.0) > 0.0]
    if verdict.feasible or not needy:
        return ThrottleFit({}, twin, verdict)
    low = {line: 0.0 for line in needy}
    high = {line: math.log(_max_factor(machine, line)) for line in needy}
    top = {**ones, **{line: math.exp(high[line]) for line in needy}}
    twin_hi, verdict_hi, _ = run(top)
    if not verdict_hi.feasible:
        return ThrottleFit({k: v for k, v in top.items() if v != 1.0}, twin_hi, verdict_hi)
    best = (twin_hi, verdict_hi, dict(top))
    for _ in range(ROUNDS):
        mid = {line: 0.5 * (low[line] + high[line]) for line in needy}
        factors = {**ones, **{line: math.exp(mid[line]) for line in needy}}
        twin_mid, verdict_mid, excess_mid = run(factors)
        for line in needy:
            if excess_mid.get(line, -1.0) > 0.0:
                low[line] = mid[line]
            else:
                high[line] = mid[line]
        if verdict_mid.feasible:
            best = (twin_mid, verdict_mid, factors)
    final = {**ones, **{line: math.exp(high[line]) for line in needy}}
    if final != best[2]:
        twin_f, verdict_f, _ = run(final)
        if verdict_f.feasible:
            best = (twin_f, verdict_f, final)
    chosen = {k: float(v) for k, v in best[2].items() if not np.isclose(v, 1.0)}
    return ThrottleFit(chosen, best[0], best[1])
