"""Energy beyond leaks (issue 37): the twin's new parts, its bookkeeping, the set point search.

Values are checked against physics a reader can redo by hand: the air that fills a
tube is its volume times the change of density between exhaust and supply pressure
(ideal gas); a cylinder's static force is the gauge pressure times its piston area
(eq. 4.13); the categories of the bookkeeping add up to the air through the supply
meter (mass conservation of the kernel).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from pneufdd.energy.bookkeeping import twin_air
from pneufdd.energy.breakdown import reconcile
from pneufdd.energy.changes import Change, apply_changes
from pneufdd.energy.pressure import lowest_set_point
from pneufdd.energy.settings import EnergySettings
from pneufdd.energy.twin import mean_machine, run_twin
from pneufdd.errors import MachineError
from pneufdd.physics.constants import P_ATM, R_AIR
from pneufdd.physics.units import pa_to_psig, psig_to_pa
from pneufdd.sim import load_machine, parse_description, run_simulation


@pytest.fixture(scope="module")
def press():
    return load_machine("press-fit-cell")


def _raw(machine, edit):
    raw = copy.deepcopy(machine.raw)
    edit(raw)
    return parse_description(raw, source="test")


def _actuator(raw, ident):
    return next(a for a in raw["actuator"] if a["id"] == ident)


@pytest.fixture(scope="module")
def leaky_run(press):
    return run_simulation(press, cycles=3, seed=4, leaks={"supply": "15slpm", "FEED_A": "10slpm"})


def test_bookkeeping_adds_up_to_the_supply_meter(leaky_run):
    air = twin_air(leaky_run)
    per_cycle = air.per_cycle_kg
    total = sum(per_cycle.values())
    assert total == pytest.approx(air.supply_kg.sum(), rel=1e-9)
    # the supply leak is exactly the kernel's leak flow over the same windows
    start = leaky_run.step_start[1, 0]
    end = leaky_run.step_start[2, 0]
    i0, i1 = round(start / 1e-3), round(end / 1e-3)
    supply_leak = float(np.sum(leaky_run.outputs["mdot_leak_supply"][i0:i1]) * 1e-3)
    assert per_cycle["leak.supply"] == pytest.approx(supply_leak, rel=0.01)
    line_leak = float(np.sum(leaky_run.outputs["mdot_leak_FEED_A"][i0:i1]) * 1e-3)
    assert per_cycle["leak.FEED_A"] == pytest.approx(line_leak, rel=0.05)
    assert abs(per_cycle["storage"]) < 0.01 * total


def test_tube_air_is_its_volume_times_the_density_change(press):
    """CLAMP's B tube fills from the atmosphere to the set point once a cycle (ideal gas)."""
    result = run_simulation(press, cycles=3, seed=1)
    air = twin_air(result).per_cycle_kg
    clamp = press.actuators[press.actuator_ids.index("CLAMP")]
    tube = math.pi * (clamp.tube_inner_diameter_mm * 1e-3) ** 2 / 4 * clamp.tube_length_m
    dead = (clamp.dead_volume_a_cm3 + clamp.dead_volume_b_cm3) * 1e-6
    delta_rho = (psig_to_pa(press.supply.regulator_set_psig) - P_ATM) / (R_AIR * 293.15)
    # both lines fill once a cycle: 2 tube volumes, the dead volumes of both ends
    assert air["CLAMP.tube"] == pytest.approx(2 * tube * delta_rho, rel=0.05)
    assert air["CLAMP.dead volume"] == pytest.approx(dead * delta_rho, rel=0.05)


def test_description_refuses_bad_energy_keys(press):
    def spring_without_preload(raw):
        valve = _actuator(raw, "EJECT")["valve"]
        valve.pop("catalogue", None)  # another valve: the 5/2 valve's order code goes
        valve["kind"] = "3/2-monostable"

    with pytest.raises(MachineError, match="spring_preload_n"):
        _raw(press, spring_without_preload)

    def booster_without_pressure(raw):
        _actuator(raw, "EJECT")["booster"] = True

    with pytest.raises(MachineError, match="booster"):
        _raw(press, booster_without_pressure)

    def force_of_unknown(raw):
        raw["step"][2]["required_force_n"] = 900.0
        raw["step"][2]["force_actuator"] = "RAM"

    with pytest.raises(MachineError, match="force_actuator"):
        _raw(press, force_of_unknown)


def test_required_force_defaults_to_the_commanded_actuator(press):
    def force(raw):
        raw["step"][2]["required_force_n"] = 900.0

    step = _raw(press, force).steps[2]
    assert (step.force_actuator, step.force_direction) == ("PRESS", 1)


@pytest.fixture(scope="module")
def spring_eject(press):
    change = Change(
        "spring_return",
        "EJECT",
        {"preload_n": 20.0, "rate_n_per_mm": 0.2, "throttle_factor_a": 4.0},
    )
    return apply_changes(press, [change])


def test_single_acting_cylinder_draws_no_air_on_its_spring_side(press, spring_eject):
    result = run_simulation(spring_eject, cycles=2, seed=2)
    assert np.all(result.outputs["mdot_in_EJECT_B"] == 0.0)
    strokes = result.strokes_of("EJECT")
    assert {s.direction for s in strokes} == {1, -1}  # the spring brings it back
    # the B chamber stays at the atmosphere (vented through its breather)
    assert np.max(np.abs(result.outputs["p_EJECT_B"] - P_ATM)) < 0.2e5
    before = run_twin(press).actuator_air("EJECT")
    after = run_twin(spring_eject).actuator_air("EJECT")
    assert after < 0.7 * before  # one line instead of two (Fig. 6.1: about 50 % less)


def test_spring_return_rewrites_a_bistable_program():
    festo = load_machine("festo-dsd")
    change = Change(
        "spring_return", "HGD2", {"preload_n": 9.0, "rate_n_per_mm": 0.75, "throttle_factor_a": 1.0}
    )
    converted = apply_changes(festo, [change])
    assert "U_HGD2_B" not in converted.solenoids
    run = run_twin(converted)
    assert run.stalled == ""
    assert run.cycle_time_s == pytest.approx(run_twin(festo).cycle_time_s, rel=0.1)


def test_line_fed_by_its_own_regulator_and_by_a_booster(press):
    def zone(raw):
        _actuator(raw, "FEED")["line_pressure_psig"] = 50.0

    out = run_simulation(_raw(press, zone), cycles=2, seed=3).outputs
    for side in "AB":
        top = float(pa_to_psig(np.max(out[f"p_FEED_{side}"])))
        assert 49.0 < top <= 50.0 + 0.05  # non-relieving: never above its regulator

    def boost(raw):
        raw["supply"]["regulator_set_psig"] = 50.0
        _actuator(raw, "PRESS").update(line_pressure_psig=87.0, booster=True)

    out = run_simulation(_raw(press, boost), cycles=2, seed=3).outputs
    assert float(pa_to_psig(np.max(out["p_PRESS_B"]))) == pytest.approx(87.0, abs=0.1)
    assert float(pa_to_psig(np.max(out["p_manifold"]))) < 51.0


def test_ejector_rated_pressure_defaults_to_the_set_point():
    festo = load_machine("festo-dsd")

    def rated(raw):
        raw["vacuum"]["rated_psig"] = raw["supply"]["regulator_set_psig"]

    a = run_simulation(festo, cycles=1, seed=5).outputs["vacuum_level"]
    b = run_simulation(_raw(festo, rated), cycles=1, seed=5).outputs["vacuum_level"]
    assert np.array_equal(a, b)


@pytest.fixture(scope="module")
def search(press):
    return lowest_set_point(press, settings=EnergySettings())


def test_lowest_set_point_is_the_boundary_of_the_job(press, search):
    settings = EnergySettings()
    assert search.feasible_now
    assert search.min_psig < search.now_psig
    assert search.limiting_actuator in press.actuator_ids
    feasible = sorted(p.psig for p in search.curve if p.feasible)
    failing = sorted(p.psig for p in search.curve if not p.feasible)
    assert feasible[0] == search.min_psig
    assert failing[-1] < search.min_psig <= failing[-1] + settings.resolution_psi
    # every step of the chosen point within 2 % of the present cycle time
    allowed = settings.tolerance * search.base.cycle_time_s
    assert np.max(search.best.duration_s - search.base.duration_s) <= allowed
    # less pressure, less air
    assert search.best.supply_kg < search.base.supply_kg


def test_required_force_bounds_the_set_point(press, search):
    """The ram must hold 1500 N: (p - p_atm) x its 63 mm piston area (eq. 4.13)."""

    def force(raw):
        raw["step"][2]["required_force_n"] = 1500.0

    machine = _raw(press, force)
    found = lowest_set_point(machine, settings=EnergySettings())
    ram = machine.actuators[machine.actuator_ids.index("PRESS")]
    area = math.pi * (ram.bore_mm * 1e-3) ** 2 / 4
    needed_psig = float(pa_to_psig(P_ATM + 1500.0 / area))
    assert found.limiting_actuator == "PRESS"
    assert found.best.forces_n[2] >= 1500.0
    # the chamber reaches the set point less the line's droop: just above the force's need
    assert needed_psig <= found.min_psig <= needed_psig + 2.0
    assert found.min_psig > search.min_psig


def test_reconcile_takes_line_meters_and_leaks_from_the_meters(press, leaky_run):
    """A line-metered actuator takes the meters' air; a leak's size follows the supply meter."""
    air = twin_air(leaky_run)
    press_cols = np.array([c.startswith("PRESS.") for c in air.components])
    leak_cols = np.array([c == "leak.supply" for c in air.components])
    truth = air.air_kg.copy()
    truth[:, press_cols] *= 1.1
    truth[:, leak_cols] *= 1.4
    lines = {line: 1.1 * air.lines_kg[line] for line in ("PRESS_A", "PRESS_B")}
    factors, scaled = reconcile(air, truth.sum(axis=1), lines)
    assert factors["PRESS"] == pytest.approx(1.1, rel=1e-9)  # the line meters' own figure
    assert factors["leak.supply"] == pytest.approx(1.4, abs=0.03)
    for other in ("FEED", "CLAMP", "EJECT"):
        assert factors[other] == pytest.approx(1.0, abs=0.03)
    assert scaled.sum() == pytest.approx(truth.sum(), rel=0.01)


def test_reconcile_does_not_hand_a_step_residual_to_the_actuator_that_owns_the_step(leaky_run):
    """Air the twin shapes differently (another fill's tail) in EJECT's steps stays shared.

    The meter cannot tell whose air a short step's surplus is; one factor per actuator
    gave it to the actuator that owns the step (festo-dsd's HGD2: +7.9 % -> +19.2 %).
    """
    air = twin_air(leaky_run)
    groups = np.array([c.split(".")[0] for c in air.components])
    eject = air.air_kg[:, groups == "EJECT"].sum(axis=1)
    owns = eject > 0.5 * air.air_kg.sum(axis=1)
    assert owns.any()
    measured = air.air_kg.sum(axis=1) + np.where(owns, 0.3 * eject, 0.0)
    factors, scaled = reconcile(air, measured)
    assert factors["EJECT"] == factors["FEED"] == factors["CLAMP"] == factors["PRESS"]
    assert factors["EJECT"] == pytest.approx(1.0, abs=0.03)
    surplus = float(np.sum(measured) - np.sum(air.air_kg))
    assert np.sum(scaled) - np.sum(air.air_kg) == pytest.approx(surplus, rel=0.5)


def test_mean_machine_steadies_the_set_point_search(press):
    """Without friction scatter the lowest set point hardly depends on the seed.

    With press-fit-cell's 3 % scatter, 2 measured cycles put it anywhere in 44.7-47.2
    psig over seeds 1-4; the mean machine within one bisection step (0.5 psi).
    """
    mean = mean_machine(press)
    assert mean.friction_scatter == 0.0
    assert press.friction_scatter > 0.0
    found = [lowest_set_point(mean, settings=EnergySettings(seed=s)).min_psig for s in (1, 2, 3, 4)]
    scattered = [
        lowest_set_point(press, settings=EnergySettings(seed=s)).min_psig for s in (1, 2, 3, 4)
    ]
    assert max(found) - min(found) <= 2 * EnergySettings().resolution_psi
    assert max(scattered) - min(scattered) > 2 * EnergySettings().resolution_psi
