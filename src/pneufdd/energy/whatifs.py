"""The what-ifs of section 6.2.1, each modelled and priced by the twin.

* **Lower set point** (:func:`set_point_measure`): the lowest pressure that still does
  the job (:mod:`pneufdd.energy.pressure`).
* **Flow controls for the cycle time needed** (:func:`throttle_measure`): at a lower
  set point, the twin opens the meter-out flow controls of the strokes that slowed
  down and finds how far the pressure can then go.
* **Single-acting with spring return** (:func:`spring_measures`, Fig. 6.1): for
  actuators with a short stroke whose return needs little force.
* **Shorter tubes** and **smaller valves** (:func:`tube_measure`, :func:`valve_measure`):
  less dead volume filled and exhausted at every stroke.
* **A pressure zone** (:func:`zone_measure`): the limiting actuator keeps what it
  needs, the rest of the machine runs lower.
* **Remedies for the limiting actuator** (:func:`remedy_measures`): a larger bore, a
  booster on that actuator alone.
* **Air off at standstill** (:func:`air_off_measure`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from pneufdd.energy.changes import (
    ISO_BORES_MM,
    TUBE_BORES_MM,
    VALVE_CVS,
    Change,
    apply_changes,
    bar_g,
    next_size,
)
from pneufdd.energy.measures import Measure, price_measure
from pneufdd.energy.pressure import (
    SetPointSearch,
    allowances,
    bisect_pressure,
    candidate_limit_s,
    judge,
    lowest_set_point,
)
from pneufdd.energy.settings import EnergySettings, Money
from pneufdd.energy.standby import Standby
from pneufdd.energy.tuning import critical_lines, fit_throttles, throttle_changes
from pneufdd.energy.twin import TwinRun, run_twin
from pneufdd.physics.constants import P_ATM
from pneufdd.physics.units import kg_s_to_slpm, psig_to_pa
from pneufdd.sim.compile import piston_areas
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import Leak

__all__ = [
    "BOOSTER_DRIVE_RATIO",
    "SPRING_MAX_STROKE_MM",
    "air_off_measure",
    "remedy_measures",
    "set_point_measure",
    "spring_measures",
    "throttle_measure",
    "tube_measure",
    "valve_measure",
    "zone_measure",
]

SPRING_MAX_STROKE_MM = 50.0
"""Longest stroke offered as single-acting with return spring: catalogue spring-return
round cylinders stop at 25-50 mm (Fig. 6.1's "shorter stroke only") [mm]."""
SPRING_BREAKAWAY = 1.5
"""Return spring preload as a multiple of the seal's static friction [-]."""
SPRING_FLOOR = 0.05
"""... and at least this share of the piston force at the present set point [-]."""
SPRING_RISE = 0.5
"""The spring's force grows by this share of its preload over the stroke [-]."""
SPRING_STEPS = (1.0, 1.5, 2.25)
"""Preloads tried, as multiples of the first, before a larger bore is tried [-]."""
BOOSTER_RATIO = 2.0
"""Outlet to inlet absolute pressure of the booster (a 2:1 piston booster) [-]."""
BOOSTER_DRIVE_RATIO = 1.0
"""Drive air a 2:1 piston booster exhausts per unit of air it delivers [-]: its drive
chamber fills with the inlet air once per stroke while the compression chamber
delivers the air it drew in (docs/energy.md)."""


def set_point_measure(search: SetPointSearch, settings: EnergySettings) -> Measure:
    """The lowest set point as a measure (with the DOE compressor-side saving)."""
    change = Change("set_point", "", {"psig": search.min_psig})
    drop = search.now_psig - search.min_psig
    limit = search.limit.reason if search.limit is not None else "the search floor was feasible"
    return price_measure(
        "lower the set point", "set_point", [change], search.base, search.best, settings,
        header_drop_psi=drop,
        note=f"limited by {search.limiting_actuator or 'the search floor'}: {limit}",
    )  # fmt: skip


def _candidate(
    machine: MachineDescription,
    changes: Sequence[Change],
    leaks: Sequence[Leak],
    settings: EnergySettings,
    base: TwinRun,
) -> TwinRun:
    return run_twin(
        apply_changes(machine, changes), leaks, settings.cycles, settings.seed,
        candidate_limit_s(base),
    )  # fmt: skip


def throttle_measure(
    machine: MachineDescription,
    search: SetPointSearch,
    leaks: Sequence[Leak],
    settings: EnergySettings,
) -> Measure:
    """Flow controls opened where a lower pressure slows strokes; the set point lowered.

    Outer bisection on the set point below the plain search's minimum; at each one the
    twin opens the flow controls (:func:`pneufdd.energy.tuning.fit_throttles`).
    """
    base = search.base
    lines = sorted(set(critical_lines(base).values()))
    best: tuple[float, list[Change], TwinRun] | None = None
    hi = search.min_psig
    lo = max(0.25 * search.now_psig, 1.0)
    while hi - lo > settings.resolution_psi:
        mid = 0.5 * (hi + lo)

        def make(factors: dict[tuple[str, str], float], psig: float = mid) -> list[Change]:
            return [*throttle_changes(factors), Change("set_point", "", {"psig": psig})]

        fit = fit_throttles(make, machine, base, lines, leaks, settings)
        if fit.verdict.feasible:
            hi = mid
            best = (mid, make(fit.factors), fit.run)
        else:
            lo = mid
    if best is None:
        return price_measure(
            "flow controls set for the cycle time", "throttles", [], base, search.best, settings,
            note="opening the flow controls does not let the pressure go lower than the "
            "set point alone: the valves and tubes, not the flow controls, limit the strokes",
        )  # fmt: skip
    psig, changes, run = best
    return price_measure(
        "flow controls set for the cycle time", "throttles", changes, base, run, settings,
        header_drop_psi=search.now_psig - psig,
        note=f"the set point goes to {bar_g(psig):.2f} bar(g) instead of "
        f"{bar_g(search.min_psig):.2f} with the flow controls opened as listed",
    )  # fmt: skip


def _spring_change(
    machine: MachineDescription, ident: str, scale: float, bore: float | None, factor_a: float
) -> Change:
    actuator = next(a for a in machine.actuators if a.id == ident)
    area_a = piston_areas(actuator)[0] * ((bore / actuator.bore_mm) ** 2 if bore else 1.0)
    gauge = psig_to_pa(machine.supply.regulator_set_psig) - P_ATM
    friction = actuator.static_friction_n * ((bore / actuator.bore_mm) if bore else 1.0)
    preload = max(SPRING_BREAKAWAY * friction, SPRING_FLOOR * area_a * gauge) * scale
    rate = SPRING_RISE * preload / actuator.stroke_mm
    values: dict[str, object] = {
        "preload_n": round(preload, 1),
        "rate_n_per_mm": round(rate, 3),
        "throttle_factor_a": factor_a,
    }
    if bore:
        values["bore_mm"] = bore
    return Change("spring_return", ident, values)


def spring_candidates(machine: MachineDescription) -> list[str]:
    """Actuators that could be single-acting with a return spring (Fig. 6.1).

    A short stroke (:data:`SPRING_MAX_STROKE_MM`), resting retracted, not already
    single-acting, a piston cylinder (not rodless or rotary), and no required force
    on its return stroke (the spring's is small).
    """
    needs_return_force = {
        s.force_actuator for s in machine.steps if s.required_force_n > 0 and s.force_direction < 0
    }
    return [
        a.id
        for a in machine.actuators
        if a.stroke_mm <= SPRING_MAX_STROKE_MM
        and a.initial == "retracted"
        and a.valve.kind != "3/2-monostable"
        and a.kind in ("linear", "slide", "gripper")
        and a.id not in needs_return_force
    ]


def spring_measures(
    machine: MachineDescription, base: TwinRun, leaks: Sequence[Leak], settings: EnergySettings
) -> list[Measure]:
    """Each candidate actuator single-acting with a return spring, sized by the twin.

    The preload starts at :data:`SPRING_BREAKAWAY` x its static friction (at least
    :data:`SPRING_FLOOR` of its piston force); the twin opens its A-line flow control
    until the spring returns it within the allowance, and raises the preload (then the
    bore, one ISO size) when even an open flow control is too slow.
    """
    out = []
    for ident in spring_candidates(machine):
        actuator = next(a for a in machine.actuators if a.id == ident)
        bigger = next_size(ISO_BORES_MM, actuator.bore_mm, 1)
        attempts = [(s, None) for s in SPRING_STEPS] + ([(1.0, float(bigger))] if bigger else [])
        found = None
        for scale, bore in attempts:

            def make(
                factors: dict[tuple[str, str], float],
                who: str = ident,
                s: float = scale,
                b: float | None = bore,
            ) -> list[Change]:
                return [_spring_change(machine, who, s, b, factors.get((who, "a"), 1.0))]

            fit = fit_throttles(make, machine, base, [(ident, "a")], leaks, settings)
            found = (make(fit.factors), fit)
            if fit.verdict.feasible:
                break
        assert found is not None
        changes, fit = found
        out.append(
            price_measure(
                f"spring return: {ident}",
                "spring_return",
                changes,
                base,
                fit.run,
                settings,
                note="single-acting: a 3/2 valve instead of its "
                f"{actuator.valve.kind} valve, one line and one flow control less (Fig. 6.1); "
                "less return force, no mid-position hold, return time set by the spring",
            )
        )
    return out


def tube_measure(
    machine: MachineDescription, base: TwinRun, leaks: Sequence[Leak], settings: EnergySettings
) -> Measure:
    """Valves next to their cylinders: every tube longer than the target shortened."""
    changes = [
        Change("tube", a.id, {"length_m": settings.tube_length_m})
        for a in machine.actuators
        if a.tube_length_m > settings.tube_length_m * 1.01
    ]
    run = _candidate(machine, changes, leaks, settings, base) if changes else base
    return price_measure(
        "shorter tubes", "tubes", changes, base, run, settings,
        note=f"valves mounted next to their cylinders ({settings.tube_length_m:g} m of tube); "
        "the tube volume is filled and exhausted at every stroke",
    )  # fmt: skip


def valve_measure(
    machine: MachineDescription, base: TwinRun, leaks: Sequence[Leak], settings: EnergySettings
) -> Measure:
    """One valve size smaller, with its smaller tube, wherever the steps still keep time."""
    allowed = allowances(base, settings)
    kept: list[Change] = []
    for a in machine.actuators:
        cv = next_size(VALVE_CVS, a.valve.cv, -1)
        bore = next_size(TUBE_BORES_MM, a.tube_inner_diameter_mm, -1)
        if cv is None or bore is None:
            continue
        trial = [
            Change("valve", a.id, {"cv": float(cv)}),
            Change("tube", a.id, {"length_m": a.tube_length_m, "inner_diameter_mm": float(bore)}),
        ]
        run = _candidate(machine, [*kept, *trial], leaks, settings, base)
        if judge(run, base, allowed, settings.cycle_time_needed_s).feasible:
            kept += trial
    run = _candidate(machine, kept, leaks, settings, base) if kept else base
    return price_measure(
        "smaller valves and tubes", "valves", kept, base, run, settings,
        note="one valve size and one tube size smaller where the steps still keep their time "
        "(less tube volume per stroke); valves with flow to spare are often chosen by habit",
    )  # fmt: skip


def zone_measure(
    machine: MachineDescription,
    search: SetPointSearch,
    leaks: Sequence[Leak],
    settings: EnergySettings,
) -> Measure | None:
    """The limiting actuator keeps today's pressure; the rest in a lower pressure zone.

    The header (the machine's regulator) stays; every other actuator gets its own
    regulator (a pressure zone of the valve terminal) at one pressure, the lowest at
    which they still keep time (bisection). Together with the lower set point it is
    the zone the limiting actuator needs.
    """
    limiting = search.limiting_actuator
    group = [a.id for a in machine.actuators if a.id != limiting]
    if not limiting or search.limit is None or not group:
        return None

    def at(psig: float) -> list[Change]:
        return [Change("line_pressure", ident, {"psig": psig, "side": "both"}) for ident in group]

    zone = bisect_pressure(machine, at, search.now_psig, leaks, settings, search.base)
    changes = at(zone.min_psig)
    return price_measure(
        "pressure zone", "pressure_zone", changes, search.base, zone.best, settings,
        note=f"{limiting} keeps {bar_g(search.now_psig):.2f} bar(g); "
        f"{len(group)} other actuator(s) in a zone at {bar_g(zone.min_psig):.2f} bar(g) "
        f"(limited there by {zone.limiting_actuator or 'the search floor'})",
        remedy_for=limiting,
    )  # fmt: skip


def remedy_measures(
    machine: MachineDescription,
    search: SetPointSearch,
    leaks: Sequence[Leak],
    settings: EnergySettings,
) -> list[Measure]:
    """What lowers the set point past the limiting actuator: a larger bore, a booster."""
    limiting = search.limiting_actuator
    actuator = next((a for a in machine.actuators if a.id == limiting), None)
    if actuator is None or search.limit is None:
        return []
    out = []
    bigger = next_size(ISO_BORES_MM, actuator.bore_mm, 1)
    if bigger is not None:
        bore = Change("bore", limiting, {"bore_mm": float(bigger)})
        found = lowest_set_point(machine, leaks, settings, [bore], search.base)
        changes = [bore, Change("set_point", "", {"psig": found.min_psig})]
        verdict = "lowers" if found.min_psig < search.min_psig - 1e-9 else "does not lower"
        out.append(
            price_measure(
                f"larger bore: {limiting}",
                "larger_bore",
                changes,
                search.base,
                found.best,
                settings,
                header_drop_psi=search.now_psig - found.min_psig,
                note=f"{limiting} at {bigger:g} mm instead of {actuator.bore_mm:g} mm "
                f"{verdict} the set point: {bar_g(found.min_psig):.2f} bar(g) against "
                f"{bar_g(search.min_psig):.2f} (then limited by "
                f"{found.limiting_actuator or 'the search floor'}); more air per stroke of "
                f"{limiting}",
                remedy_for=limiting,
            )
        )
    boost = Change(
        "line_pressure", limiting, {"psig": search.now_psig, "side": "both", "booster": True}
    )
    floor = (psig_to_pa(search.now_psig) / BOOSTER_RATIO - P_ATM) / (psig_to_pa(1.0) - P_ATM)
    found = lowest_set_point(machine, leaks, settings, [boost], search.base)
    header = max(found.min_psig, floor)
    changes = [boost, Change("set_point", "", {"psig": header})]
    run = found.best
    if header > found.min_psig:
        run = _candidate(machine, changes, leaks, settings, search.base)
    drive = BOOSTER_DRIVE_RATIO * run.actuator_air(limiting) if run.air is not None else 0.0
    out.append(
        price_measure(
            f"booster: {limiting}",
            "booster",
            changes,
            search.base,
            run,
            settings,
            header_drop_psi=search.now_psig - header,
            extra_air_kg=drive,
            note=f"a 2:1 booster keeps {limiting} at {bar_g(search.now_psig):.2f} bar(g); "
            f"the rest runs at {bar_g(header):.2f} bar(g); the booster's drive air "
            f"({1e3 * drive:.2f} g a cycle) is counted; its point is a lower factory "
            "pressure (the compressor side)",
            remedy_for=limiting,
        )
    )
    return out


def air_off_measure(standby: Standby, settings: EnergySettings, base: TwinRun) -> Measure:
    """Switch the air off at standstill: the standby flow saved, minus the refills."""
    hours = settings.hours_standstill
    saved = settings.price(standby.flow_kg_s, hours)
    refill_year = standby.refill_kg * settings.restarts_per_year
    refill = settings.price(refill_year / (hours * 3600.0) if hours > 0 else 0.0, hours)
    net = Money(
        saved.mass_flow_kg_s - refill.mass_flow_kg_s,
        hours,
        saved.kwh - refill.kwh,
        saved.cost - refill.cost,
    )
    nan = math.nan
    return Measure(
        name="air off at standstill",
        kind="air_off",
        changes=(Change("air_off"),),
        feasible=True,
        reason=f"restart: about {standby.refill_s:.1f} s to refill "
        f"{1e3 * standby.refill_kg:.1f} g of air",
        air_before_kg=nan,
        air_after_kg=nan,
        cycle_before_s=base.cycle_time_s,
        cycle_after_s=base.cycle_time_s,
        step_change_s=tuple(0.0 for _ in base.duration_s),
        saving=net,
        note=f"a shut-off (soft-start/dump) valve after the regulator, closed by the PLC at "
        f"standstill: {hours:g} h a year at {float(kg_s_to_slpm(standby.flow_kg_s)):.2f} SLPM, "
        f"{settings.restarts_per_year:g} restarts a year",
        extra={"standby_flow_kg_s": standby.flow_kg_s, "refill_kg": standby.refill_kg},
    )
