"""The lowest supply pressure that still does the job, found by bisection with the twin.

Section 6.2.1: a factory's pressure is often raised for one demanding cylinder, and
every 2 psi lower saves about 1 % of compressor energy (U.S. DOE). The job is the
present cycle: a set point is *feasible* when, in the twin (calibrated to the machine),

* every step keeps its duration within an allowance: ``tolerance`` x the present
  cycle time (default 2 %), plus, when production needs a longer cycle than the
  present one, that step's share of the difference;
* every force-holding step (``required_force_n`` in the description) still holds its
  required static force (eq. 4.13 at the step's end, return spring included);
* the machine does not stall.

Lower pressure makes strokes slower and forces smaller, so feasibility is monotone in
the set point and bisection finds the boundary. The step that fails first just below
it names the *limiting actuator*.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.energy.changes import Change, apply_changes
from pneufdd.energy.settings import EnergySettings
from pneufdd.energy.twin import TwinRun, run_twin, step_actuators
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import Leak

__all__ = [
    "FLOOR_FRACTION",
    "PressurePoint",
    "SetPointSearch",
    "Verdict",
    "allowances",
    "bisect_pressure",
    "candidate_limit_s",
    "judge",
    "lowest_set_point",
    "step_owner",
]

FLOOR_FRACTION = 0.25
"""The search goes down to this fraction of the present gauge set point [-]."""


@dataclass(frozen=True)
class Verdict:
    """Whether a candidate does the job, and where it fails worst.

    Attributes
    ----------
    feasible : bool
        Every step within its allowance, every required force held, no stall.
    step : int
        The worst step (index; -1 when none stands out).
    excess_s : float
        That step's duration over its allowance (negative: margin left) [s].
    force_short_n : float
        The largest shortfall of a required force (0 when all are held) [N].
    reason : str
        One line: why it fails, or its smallest margin.
    """

    feasible: bool
    step: int
    excess_s: float
    force_short_n: float
    reason: str


def candidate_limit_s(base: TwinRun) -> float:
    """Longest cycle a candidate is run for before it counts as stalled [s]."""
    return max(3.0 * base.cycle_time_s, 1.0)


def allowances(base: TwinRun, settings: EnergySettings) -> FloatArray:
    """How much longer each step may take than in ``base`` [s].

    ``tolerance`` x the present cycle time, plus each step's share of a longer needed
    cycle time (in proportion to its present duration).
    """
    durations = base.duration_s
    cycle = float(np.sum(durations))
    allowed = np.full(durations.shape, settings.tolerance * cycle)
    needed = settings.cycle_time_needed_s
    if needed is not None and needed > cycle:
        allowed = allowed + (needed - cycle) * durations / cycle
    return allowed


def step_owner(machine: MachineDescription, step: int, base: TwinRun | None = None) -> str:
    """The actuator (or vacuum) a step waits for; the one whose stroke is longest first."""
    st = machine.steps[step]
    if st.required_force_n > 0.0 and st.force_actuator:
        return st.force_actuator
    if base is not None:
        moving = step_actuators(base).get(step)
        if moving:
            return moving[0]
    waited = [w[2:].rsplit("_", 1)[0] if w.count("_") > 1 else w[2:] for w in st.wait]
    return waited[0] if waited else ""


def judge(
    run: TwinRun, base: TwinRun, allowed: FloatArray, cycle_limit_s: float | None = None
) -> Verdict:
    """A candidate's :class:`Verdict` against the present machine ``base``.

    ``cycle_limit_s``: the longest cycle production accepts (None: no bound but the
    steps').
    """
    if run.air is None:
        return Verdict(False, -1, float("inf"), 0.0, f"stalls ({run.stalled})")
    if cycle_limit_s is not None and run.cycle_time_s > cycle_limit_s:
        slowest = int(np.argmax(run.duration_s - base.duration_s))
        return Verdict(
            False, slowest, run.cycle_time_s - cycle_limit_s, 0.0,
            f"cycle {run.cycle_time_s:.3f} s, longer than the {cycle_limit_s:.3f} s needed",
        )  # fmt: skip
    excess = run.duration_s - base.duration_s - allowed
    k = int(np.argmax(excess))
    shortfalls = {
        step: run.machine.steps[step].required_force_n - force
        for step, force in run.forces_n.items()
    }
    short_step = max(shortfalls, key=lambda s: shortfalls[s]) if shortfalls else -1
    short = max(shortfalls.values(), default=0.0)
    if short > 0.0:
        name = run.machine.steps[short_step].force_actuator
        return Verdict(
            False, short_step, float(excess[short_step]), short,
            f"step {short_step + 1}: {name} holds {run.forces_n[short_step]:.0f} N of the "
            f"{run.machine.steps[short_step].required_force_n:.0f} N required",
        )  # fmt: skip
    if excess[k] > 0.0:
        return Verdict(
            False, k, float(excess[k]), 0.0,
            f"step {k + 1} takes {1e3 * (run.duration_s[k] - base.duration_s[k]):.0f} ms "
            f"longer (allowed {1e3 * allowed[k]:.0f} ms)",
        )  # fmt: skip
    return Verdict(
        True, k, float(excess[k]), 0.0, f"smallest margin {-1e3 * excess[k]:.0f} ms (step {k + 1})"
    )


@dataclass(frozen=True)
class PressurePoint:
    """One set point the search ran: what the twin says about it."""

    psig: float
    cycle_time_s: float
    supply_kg: float
    feasible: bool
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """JSON form (bar(g) as well)."""
        from pneufdd.energy.changes import bar_g

        return {
            "set_point_psig": self.psig,
            "set_point_bar_g": bar_g(self.psig),
            "cycle_time_s": self.cycle_time_s,
            "air_per_cycle_kg": self.supply_kg,
            "feasible": self.feasible,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class SetPointSearch:
    """The lowest feasible set point and what limits it.

    Attributes
    ----------
    now_psig, min_psig : float
        Present and lowest feasible set point [psig].
    base : TwinRun
        The present machine.
    best : TwinRun
        At the lowest feasible set point (with the search's fixed changes).
    limit : Verdict or None
        Why the next lower set point fails (None when the search reached its floor).
    limiting_actuator : str
        The actuator (or vacuum ejector) of the step that fails first; '' at the floor.
    curve : tuple of PressurePoint
        Every set point run, by pressure.
    changes : tuple of Change
        Fixed changes made at every candidate (a remedy's), the set point's excluded.
    feasible_now : bool
        Whether the machine with ``changes`` does the job at the present set point.
    """

    now_psig: float
    min_psig: float
    base: TwinRun
    best: TwinRun
    limit: Verdict | None
    limiting_actuator: str
    curve: tuple[PressurePoint, ...]
    changes: tuple[Change, ...] = field(default_factory=tuple)
    feasible_now: bool = True

    @property
    def floor_reached(self) -> bool:
        """The search's floor was feasible: the limit is lower still."""
        return self.limit is None


def _point(psig: float, run: TwinRun, verdict: Verdict) -> PressurePoint:
    return PressurePoint(psig, run.cycle_time_s, run.supply_kg, verdict.feasible, verdict.reason)


def lowest_set_point(
    machine: MachineDescription,
    leaks: Sequence[Leak] = (),
    settings: EnergySettings | None = None,
    changes: Sequence[Change] = (),
    base: TwinRun | None = None,
    grid: int = 0,
) -> SetPointSearch:
    """Bisect the regulator set point down to the lowest that still does the job.

    Parameters
    ----------
    machine : MachineDescription
        The machine (its calibrated twin).
    leaks : sequence of Leak
        Leaks kept in every run.
    settings : EnergySettings, optional
        Tolerance, cycles, seed, resolution.
    changes : sequence of Change
        Changes made at every candidate (a remedy: larger bore, own line pressure).
    base : TwinRun, optional
        The present machine's run (computed when not given).
    grid : int
        Extra evenly spaced set points to run for the pressure curve.

    Returns
    -------
    SetPointSearch

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> found = lowest_set_point(load_machine("press-fit-cell"))
    >>> found.now_psig, found.min_psig < found.now_psig, found.limiting_actuator
    (87.0, True, 'FEED')
    """
    fixed = list(changes)
    return bisect_pressure(
        machine,
        lambda psig: [*fixed, Change("set_point", "", {"psig": psig})],
        machine.supply.regulator_set_psig,
        leaks,
        settings,
        base,
        grid,
        fixed,
    )


def bisect_pressure(
    machine: MachineDescription,
    changes_at: Callable[[float], Sequence[Change]],
    high_psig: float,
    leaks: Sequence[Leak] = (),
    settings: EnergySettings | None = None,
    base: TwinRun | None = None,
    grid: int = 0,
    fixed: Sequence[Change] = (),
) -> SetPointSearch:
    """The lowest pressure ``p`` <= ``high_psig`` at which ``changes_at(p)`` does the job.

    The pressure is whatever ``changes_at`` sets with it: the regulator's set point, a
    group's own line pressure. The search runs down to :data:`FLOOR_FRACTION` of
    ``high_psig`` and stops when the bracket is ``settings.resolution_psi`` wide.
    """
    settings = settings or EnergySettings()
    if base is None:
        base = run_twin(machine, leaks, settings.cycles, settings.seed)
    if base.air is None:
        raise ValueError(f"the present machine stalls in the twin: {base.stalled}")
    allowed = allowances(base, settings)
    runs: dict[float, tuple[float, TwinRun, Verdict]] = {}

    def evaluate(psig: float) -> tuple[TwinRun, Verdict]:
        key = round(psig, 6)
        if key not in runs:
            candidate = apply_changes(machine, changes_at(psig))
            run = run_twin(
                candidate, leaks, settings.cycles, settings.seed, candidate_limit_s(base)
            )
            runs[key] = (psig, run, judge(run, base, allowed, settings.cycle_time_needed_s))
        return runs[key][1:]

    hi = high_psig
    hi_run, hi_verdict = evaluate(hi)
    floor = max(FLOOR_FRACTION * high_psig, 1.0)
    limit: Verdict | None = hi_verdict
    lo_run: TwinRun | None = hi_run
    if hi_verdict.feasible:
        lo = floor
        lo_run, limit = evaluate(lo)
        if limit.feasible:
            hi, hi_run, limit, lo_run = lo, lo_run, None, None
        else:
            while hi - lo > settings.resolution_psi:
                mid = 0.5 * (hi + lo)
                run, verdict = evaluate(mid)
                if verdict.feasible:
                    hi, hi_run = mid, run
                else:
                    lo, lo_run, limit = mid, run, verdict
        for psig in np.linspace(floor, high_psig, grid + 2)[1:-1] if grid else ():
            evaluate(float(psig))
    owner = ""
    if limit is not None and lo_run is not None:
        if limit.step >= 0:
            owner = step_owner(machine, limit.step, _slowest(lo_run, base))
        else:
            owner = _stalled_owner(machine, lo_run)
    curve = tuple(_point(p, r, v) for _, (p, r, v) in sorted(runs.items()))
    return SetPointSearch(
        now_psig=high_psig,
        min_psig=hi,
        base=base,
        best=hi_run,
        limit=limit,
        limiting_actuator=owner,
        curve=curve,
        changes=tuple(fixed),
        feasible_now=hi_verdict.feasible,
    )


def _slowest(run: TwinRun, base: TwinRun) -> TwinRun:
    """``run`` with its strokes ranked by how much slower than ``base`` they got."""
    grown = {key: s - base.stroke_s.get(key, s) for key, s in run.stroke_s.items()}
    return TwinRun(run.machine, run.air, run.forces_n, grown, run.stroke_direction, run.stalled)


def _stalled_owner(machine: MachineDescription, run: TwinRun | None) -> str:
    """The actuator a stalled run waited for (from the stall message)."""
    if run is None or not run.stalled:
        return ""
    for a in machine.actuators:
        if f"S_{a.id}_" in run.stalled:
            return a.id
    if machine.vacuum is not None and f"S_{machine.vacuum.id}" in run.stalled:
        return machine.vacuum.id
    return ""
