"""Faults in the twin (issue 34): each fault's physics, checked on a one-cylinder rig.

The rig is festo-dsd's DNC alone (no friction scatter, scan jitter or house-air
fluctuation), so every difference between two runs is the fault's. Each test asserts
a law (the orifice law across the seal, eq. 4.15 at breakaway, the ideal gas), an
invariant (mass balance, what a meter upstream of a leak sees) or an exact timing.
"""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from typing import Any

import numpy as np
import pytest

from pneufdd.errors import InputError
from pneufdd.physics.constants import P_ATM
from pneufdd.physics.faults import (
    pilot_delay_factor_kernel,
    seal_friction_temperature_factors,
    seal_leak_mass_flow,
)
from pneufdd.physics.friction import stick_slip_force_from_pressures
from pneufdd.physics.units import psig_to_pa, slpm_to_kg_s
from pneufdd.sim import MachineDescription, MachineStalledError, parse_description, run_simulation
from pneufdd.sim.compile import piston_areas
from pneufdd.sim.faults import Fault, FaultSchedule, parse_fault
from pneufdd.sim.nuisances import Nuisances, PayloadChange, TemperatureProfile

EXTEND = {"name": "extend", "do": [{"set": "U_DNC_A", "until": "S_DNC_B"}], "dwell_s": 1.0}
RETRACT = {"name": "retract", "do": [{"set": "U_DNC_B", "until": "S_DNC_A"}], "dwell_s": 1.0}


def dnc_rig(
    valve: str = "5/3-closed-centre", steps: list[dict[str, Any]] | None = None
) -> MachineDescription:
    """festo-dsd's DNC alone, without random scatter: extend, dwell, retract, dwell."""
    raw = tomllib.loads(
        (resources.files("pneufdd.sim") / "machines" / "festo-dsd.toml").read_text("utf-8")
    )
    raw["machine"].update(friction_scatter=0.0, scan_time_s=0.0)
    raw["supply"].update(house_drift_psi=0.0, compressor_band_psi=0.0)
    raw.pop("vacuum")
    dnc = raw["actuator"][0]
    dnc["initial"] = "retracted"
    if valve != dnc["valve"]["kind"]:  # another valve: its order code no longer applies
        dnc["valve"].pop("catalogue", None)
    dnc["valve"]["kind"] = valve
    raw["actuator"] = [dnc]
    raw["sensor"] = [
        s for s in raw["sensor"] if s["location"] in ("supply", "DNC_A", "DNC_B", "DNC")
    ]
    raw["step"] = steps or [EXTEND, RETRACT]
    return parse_description(raw, "DNC rig")


@pytest.fixture(scope="module")
def rig() -> MachineDescription:
    return dnc_rig()


@pytest.fixture(scope="module")
def healthy(rig: MachineDescription) -> Any:
    return run_simulation(rig, cycles=1, seed=0)


def _window(result: Any, start: float, end: float) -> slice:
    return slice(int(np.searchsorted(result.time, start)), int(np.searchsorted(result.time, end)))


def _breakaway(result: Any, rig: MachineDescription, direction: int) -> float:
    """Eq. 4.15 on the chamber pressures at the first breakaway of the DNC's stroke."""
    stroke = result.strokes_of("DNC", direction)[0]
    k = int(np.searchsorted(result.time, stroke.first_motion))
    area_a, area_b, _ = piston_areas(rig.actuators[0])
    pa, pb = result.outputs["p_DNC_A"][k], result.outputs["p_DNC_B"][k]
    return float(stick_slip_force_from_pressures(pa, pb, area_a, area_b)) * direction


def test_piston_seal_leak_follows_the_orifice_law_and_the_supply_does_not_see_it(
    healthy: Any,
) -> None:
    rig = dnc_rig(steps=[{**EXTEND, "dwell_s": 2.0}])
    plain = run_simulation(rig, cycles=1, seed=0)
    leak = run_simulation(rig, cycles=1, seed=0, faults=["DNC=piston-leak:2slpm"])
    area = leak.recording.metadata["fault_timeline"][0]["effective_area_m2"]
    arrival = leak.strokes_of("DNC", +1)[0].end
    w = _window(leak, arrival + 0.1, arrival + 1.0)  # the 5/3 valve in its closed centre
    out = leak.outputs
    flow = out["mdot_piston_leak_DNC"][w]
    law = seal_leak_mass_flow(out["p_DNC_A"][w], out["p_DNC_B"][w], area, 293.15, 293.15)
    assert np.all(flow > 1e-5)  # chamber A (full) loses to chamber B (exhausted)
    np.testing.assert_allclose(flow, law, rtol=0.015)
    for side in "AB":  # nothing passes the closed valve: the line meters see nothing
        assert np.all(out[f"mdot_in_DNC_{side}"][w] == 0.0)
        assert np.all(out[f"mdot_exhaust_DNC_{side}"][w] == 0.0)
    assert np.all(np.diff(out["p_DNC_A"][w]) < 0)
    assert np.all(np.diff(out["p_DNC_B"][w]) > 0)
    # the supply line refills the manifold as without the leak
    extra = (
        out["mdot_supply_line"][w]
        - plain.outputs["mdot_supply_line"][
            _window(
                plain,
                plain.strokes_of("DNC", +1)[0].end + 0.1,
                plain.strokes_of("DNC", +1)[0].end + 1.0,
            )
        ][: flow.size]
    )
    assert np.abs(extra).max() < 0.05 * flow.min()
    # mass balance: regulator in = stored change + exhausted + leaked (to 1e-15 kg)
    balance = (
        out["mass_regulator"]
        - (out["stored_mass"] - out["stored_mass"][0])
        - out["mass_exhausted"]
        - out["mass_leaked"]
    )
    assert np.abs(balance - balance[0]).max() < 1e-15
    # the stroke itself: the leak lets chamber A's air into chamber B, slower
    assert leak.strokes_of("DNC", +1)[0].duration > plain.strokes_of("DNC", +1)[0].duration + 2e-3


def test_spool_leak_into_an_exhausted_line_flows_through_it_to_the_exhaust() -> None:
    rig = dnc_rig("5/2-bistable", steps=[{**EXTEND, "dwell_s": 5.0}])
    result = run_simulation(rig, cycles=1, seed=0, faults=["DNC_B=valve-leak-in:10slpm"])
    area = result.recording.metadata["fault_timeline"][0]["effective_area_m2"]
    out = result.outputs
    w = _window(result, result.time[-1] - 1.0, result.time[-1])  # steady
    into_b = out["mdot_in_DNC_B"][w]  # through the valve, so the line meter sees it
    # steady: what enters B from the supply leaves through the valve's exhaust, and
    # the supply line delivers it
    np.testing.assert_allclose(out["mdot_exhaust_DNC_B"][w], into_b, rtol=0.01)
    np.testing.assert_allclose(out["mdot_supply_line"][w], into_b, rtol=0.02)
    law = seal_leak_mass_flow(out["p_manifold"][w], out["p_DNC_B"][w], area, 293.15, 293.15)
    np.testing.assert_allclose(into_b, law, rtol=0.02)
    # the exhausted line keeps a back pressure the healthy valve would not
    assert out["p_DNC_B"][w].min() > P_ATM + 2000.0


def test_spool_leak_to_the_exhaust_is_upstream_of_the_line_meter() -> None:
    # a pressurised line leaking through the valve: the supply sees the leak, the line
    # meter (between valve and cylinder) sees no net flow; an external leak of the same
    # size on the line is downstream of the meter, which sees it
    rig = dnc_rig("5/2-bistable", steps=[{**EXTEND, "dwell_s": 5.0}])
    spool = run_simulation(rig, cycles=1, seed=0, faults=["DNC_A=valve-leak-out:10slpm"])
    external = run_simulation(rig, cycles=1, seed=0, leaks={"DNC_A": "10slpm"})
    for result, meter_sees in ((spool, False), (external, True)):
        out = result.outputs
        w = _window(result, result.time[-1] - 1.0, result.time[-1])  # steady
        supply = out["mdot_supply_line"][w]
        meter = out["mdot_in_DNC_A"][w] - out["mdot_exhaust_DNC_A"][w]
        # the line sits near the set point, where the leak is sized: 10 SLPM
        assert supply.mean() == pytest.approx(slpm_to_kg_s(10.0), rel=0.05)
        if meter_sees:
            np.testing.assert_allclose(meter, supply, rtol=0.05)
        else:
            assert np.abs(meter).max() < 0.01 * supply.mean()


def test_throttle_change_sets_the_exhaust_path_by_the_series_rule(rig: MachineDescription) -> None:
    from pneufdd.sim.compile import compile_plant, tube_cv
    from pneufdd.sim.conditions import RunConditions
    from pneufdd.sim.layout import CP_CV_EXH, CP_CV_FILL

    plant = compile_plant(rig, [])
    healthy_exhaust = plant.cp[0, CP_CV_EXH]
    RunConditions(rig, plant, FaultSchedule(["DNC_A=throttle:-40%"]), None, 0).apply(0, 0.0, None)
    a = rig.actuators[0]
    tube = tube_cv(a.tube_length_m, a.tube_inner_diameter_mm)
    expected = 1 / math.sqrt(1 / a.valve.cv**2 + 1 / tube**2 + 1 / (0.6 * a.meter_out_cv_a) ** 2)
    assert plant.cp[0, CP_CV_EXH] == pytest.approx(expected, rel=1e-12)
    assert plant.cp[0, CP_CV_EXH] < healthy_exhaust
    assert plant.cp[1, CP_CV_EXH] == pytest.approx(healthy_exhaust)  # the other line
    assert plant.cp[0, CP_CV_FILL] == pytest.approx(plant.cp[1, CP_CV_FILL])  # check valve
    # or set to a Cv: 0.075 is the same throttle 40 % closed
    RunConditions(rig, plant, FaultSchedule(["DNC_A=throttle:0.075cv"]), None, 0).apply(
        0, 0.0, None
    )
    assert plant.cp[0, CP_CV_EXH] == pytest.approx(expected, rel=1e-12)


def test_throttle_slows_the_stroke_it_meters(rig: MachineDescription, healthy: Any) -> None:
    result = run_simulation(rig, cycles=1, seed=0, faults=["DNC_A=throttle:-50%"])
    # line A is exhausted while the DNC retracts; its extension is unchanged
    assert (
        result.strokes_of("DNC", -1)[0].duration > 1.3 * healthy.strokes_of("DNC", -1)[0].duration
    )
    assert result.strokes_of("DNC", +1)[0].duration == pytest.approx(
        healthy.strokes_of("DNC", +1)[0].duration, abs=1e-3
    )


@pytest.mark.parametrize(("fault", "factor", "added"), [("+50%", 1.5, 0.0), ("20N", 1.0, 20.0)])
def test_friction_fault_moves_the_breakaway_force_of_eq_4_15(
    rig: MachineDescription, healthy: Any, fault: str, factor: float, added: float
) -> None:
    result = run_simulation(rig, cycles=1, seed=0, faults=[f"DNC=friction:{fault}"])
    base = _breakaway(healthy, rig, +1)
    assert base == pytest.approx(150.0, rel=0.02)  # section 4.2.3
    assert _breakaway(result, rig, +1) == pytest.approx(150.0 * factor + added, rel=0.02)


def test_valve_delay_and_pilot_postpone_the_breakaway(
    rig: MachineDescription, healthy: Any
) -> None:
    first = healthy.strokes_of("DNC", +1)[0].first_motion
    delayed = run_simulation(rig, cycles=1, seed=0, faults=["DNC=valve-delay:50ms"])
    assert delayed.strokes_of("DNC", +1)[0].first_motion - first == pytest.approx(0.050, abs=0.002)
    # a pilot needing 4.6 bar: the 20 ms switching time times the law's factor at the
    # supply pressure then (the set point, the rig at rest)
    pilot = run_simulation(rig, cycles=1, seed=0, faults=["DNC=valve-pilot:4.6bar"])
    factor = pilot_delay_factor_kernel(psig_to_pa(72.0) - P_ATM, 3e5, 4.6e5)
    shift = pilot.strokes_of("DNC", +1)[0].first_motion - first
    assert shift == pytest.approx(0.020 * (factor - 1.0), abs=0.002)


def test_cushion_brakes_only_inside_its_length(rig: MachineDescription, healthy: Any) -> None:
    result = run_simulation(rig, cycles=1, seed=0, faults=["DNC_B=cushion:0.012cv"])
    x, x0 = result.outputs["x_DNC"], healthy.outputs["x_DNC"]
    zone = 0.2 - 0.020  # the DNC-32's 20 mm cushioning length
    entry = int(np.argmax(x0 >= zone))
    np.testing.assert_array_equal(x[: entry - 1], x0[: entry - 1])  # identical until the zone
    v = np.diff(x) / 1e-3
    v0 = np.diff(x0) / 1e-3
    inside = slice(entry + 30, entry + 40)
    assert v[inside].max() < 0.5 * v0[entry - 20 : entry].mean()
    assert (
        result.strokes_of("DNC", +1)[0].duration > 1.15 * healthy.strokes_of("DNC", +1)[0].duration
    )
    # the retraction starts from the cushioned chamber B's pressure, within 1 %
    assert result.strokes_of("DNC", -1)[0].duration == pytest.approx(
        healthy.strokes_of("DNC", -1)[0].duration, rel=0.01
    )


def test_switch_faults(rig: MachineDescription, healthy: Any) -> None:
    late = run_simulation(rig, cycles=1, seed=0, faults=["S_DNC_B=late:100ms"])
    step = np.diff(late.step_start[0]) - np.diff(healthy.step_start[0])
    assert step[0] == pytest.approx(0.100, abs=0.0015)  # the step waiting for S_DNC_B
    stuck = run_simulation(rig, cycles=1, seed=0, faults=["S_DNC_B=stuck-on"])
    assert stuck.outputs["x_DNC"].max() == 0.0  # the PLC released the solenoid at once
    assert stuck.recording.channel("S_DNC_B")[1].min() == 1
    with pytest.raises(MachineStalledError, match="S_DNC_B=stuck-off"):
        run_simulation(rig, cycles=1, seed=0, faults=["S_DNC_B=stuck-off"], max_cycle_s=5.0)
    with pytest.raises(MachineStalledError, match="S_DNC_B=missing-edge"):
        run_simulation(rig, cycles=1, seed=0, faults=["S_DNC_B=missing-edge:100%"], max_cycle_s=5.0)


def test_regulator_drift_moves_the_pressure_at_rest(rig: MachineDescription, healthy: Any) -> None:
    result = run_simulation(rig, cycles=1, seed=0, faults=["supply=regulator:-0.4bar"])
    for run, offset in ((healthy, 0.0), (result, -0.4e5)):
        rest = run.outputs["p_manifold"][_window(run, run.time[-1] - 0.2, run.time[-1])]
        assert rest.mean() == pytest.approx(psig_to_pa(72.0) + offset, abs=300.0)


def test_ambient_temperature_changes_friction_and_air_by_their_laws(
    rig: MachineDescription, healthy: Any
) -> None:
    warm = Nuisances(ambient=TemperatureProfile(((0.0, 35.0),)))
    result = run_simulation(rig, cycles=1, seed=0, nuisances=warm)
    coulomb, _ = seal_friction_temperature_factors(308.15, 293.15)
    assert _breakaway(result, rig, +1) == pytest.approx(150.0 * coulomb, rel=0.02)
    # the air a stroke takes: the same chambers at the same pressures hold T0/T of the mass
    air = [
        run.outputs["mass_supplied"][_window(run, 0.0, run.step_start[0, 1]).stop]
        for run in (healthy, result)
    ]
    assert air[1] / air[0] == pytest.approx(293.15 / 308.15, rel=0.01)
    row = result.recording.metadata["nuisance_timeline"][0]
    assert row["ambient_c"] == 35.0
    assert row["friction_factor"]["coulomb"] == coulomb


def _newton_mass(result: Any, rig: MachineDescription) -> float:
    """The moving mass eq. 4.13 gives over the middle of the extension: least squares of
    ``(F_p - F_cf - C_vf v) = M x''`` with the velocity and acceleration of x."""
    a = rig.actuators[0]
    area_a, area_b, rod = piston_areas(a)
    out = result.outputs
    stroke = result.strokes_of("DNC", +1)[0]
    w = _window(result, stroke.start + 0.05, stroke.end - 0.05)
    v = np.gradient(out["x_DNC"], 1e-3)
    acc = np.gradient(v, 1e-3)[w]
    force = out["p_DNC_A"] * area_a - out["p_DNC_B"] * area_b - P_ATM * rod
    net = (force - a.coulomb_friction_n - a.viscous_friction_n_s_m * v)[w]
    return float(np.sum(net * acc) / np.sum(acc**2))


def test_payload_is_moving_mass_by_newtons_law(rig: MachineDescription, healthy: Any) -> None:
    heavy = Nuisances(payloads=(PayloadChange("DNC", 2.0),))
    result = run_simulation(rig, cycles=1, seed=0, nuisances=heavy)
    mass = rig.actuators[0].moving_mass_kg
    assert _newton_mass(healthy, rig) == pytest.approx(mass, rel=0.03)
    assert _newton_mass(result, rig) == pytest.approx(mass + 2.0, rel=0.03)
    assert _newton_mass(result, rig) - _newton_mass(healthy, rig) == pytest.approx(2.0, rel=0.01)
    assert result.recording.metadata["nuisance_timeline"][0]["payload_kg"] == {"DNC": 2.0}


def test_header_dips_reach_a_consuming_machine_below_the_set_point() -> None:
    # a non-relieving regulator and a 2 l reservoir hold the pressure of a machine at
    # rest; while air is drawn (a 30 SLPM supply leak) a dip of the house air below the
    # set point lowers the supply
    rig = dnc_rig(steps=[{**EXTEND, "dwell_s": 60.0}])
    dips = Nuisances(header_dips=parse_dips("depth=2bar,duration=3s,rate=90/h,seed=5"))
    plain = run_simulation(rig, cycles=1, seed=0, leaks={"supply": "30slpm"})
    result = run_simulation(rig, cycles=1, seed=0, leaks={"supply": "30slpm"}, nuisances=dips)
    events = result.recording.metadata["header_dips"]
    assert events
    assert all(e["depth_pa"] == 2e5 for e in events)
    assert all(e["duration_s"] == 3.0 for e in events)
    p, p0 = result.outputs["p_manifold"], plain.outputs["p_manifold"]
    quiet = np.ones(p.size, dtype=bool)
    quiet[: int(2.0 / 1e-3)] = False
    inside = 0
    for e in events:
        w = _window(result, e["start_s"], e["start_s"] + 3.0)
        # the dip and the refill after it; the house air's 0.1 s grid (linear between
        # its points) starts the drop up to 0.1 s early
        quiet[_window(result, e["start_s"] - 0.1, e["start_s"] + 15.0)] = False
        if e["start_s"] > 2.0 and e["start_s"] + 3.0 < result.time[-1]:
            assert (p0[w] - p[w]).max() > 0.1e5  # the supply sank by more than 0.1 bar
            inside += 1
    assert inside >= 1
    assert quiet.sum() > 5000
    np.testing.assert_allclose(p[quiet], p0[quiet], atol=50.0)  # the same away from the dips


def parse_dips(text: str) -> Any:
    from pneufdd.sim.nuisances import parse_header_dips

    return parse_header_dips(text)


def test_fault_life_and_truth(rig: MachineDescription) -> None:
    faults = FaultSchedule(
        [
            Fault("DNC", "friction", 20.0, "%", start_s=4.0, growth_per_s=1.0, repair_s=12.0),
            parse_fault("S_DNC_A=missing-edge:0%"),
        ]
    )
    result = run_simulation(rig, cycles=4, seed=3, faults=faults)
    meta = result.recording.metadata
    starts = meta["cycle_start_s"]
    rows = [r for r in meta["fault_timeline"] if r["kind"] == "friction"]
    expect = [(k, 20.0 + t - 4.0) for k, t in enumerate(starts) if 4.0 <= t < 12.0]
    assert [r["cycle"] for r in rows] == [k for k, _ in expect]
    assert [r["size"] for r in rows] == pytest.approx([size for _, size in expect])
    edges = [r for r in meta["fault_timeline"] if r["kind"] == "missing-edge"]
    assert len(edges) == 4
    assert not any(r["missed"] for r in edges)
    assert meta["fault_schedule"][0]["family"] == "friction"


def test_inactive_faults_and_empty_nuisances_leave_the_run_bit_identical() -> None:
    plain = run_simulation("festo-dsd", cycles=2, seed=7, keep_outputs=False)
    for extra in (
        {"faults": ["DNC=friction:+50%@1h", "S_DNC_B=missing-edge:0%"]},
        {"nuisances": Nuisances()},
        {"faults": []},
    ):
        other = run_simulation("festo-dsd", cycles=2, seed=7, keep_outputs=False, **extra)
        for name in plain.recording.channels:
            np.testing.assert_array_equal(other.recording.channel(name)[1],
                                          plain.recording.channel(name)[1])  # fmt: skip
        assert repr(other.strokes) == repr(plain.strokes)


@pytest.mark.parametrize(
    ("faults", "message"),
    [
        (["DNC=friction:+50ms"], "size of a friction fault"),
        (["DNC_C=throttle:-10%"], "location of a throttle fault"),
        (["DNC=throttle:-10%"], "location of a throttle fault"),
        (["S_DNC_Q=late:10ms"], "location of a late fault"),
        (["DNC_B=cushion:-20%"], "gives this actuator no cushioning"),
        (["DNC=wobble:3"], "fault kind"),
        (["DNC=friction:+10%", "DNC=friction:+20%"], "given twice"),
        (["DNC=friction:-200N"], "forces >= 0"),
        (["supply=regulator:-0.3bar@-5s"], "time of"),
        (["DNC_A=throttle:0cv"], "size of a throttle fault"),
    ],
)
def test_bad_faults_are_refused_before_any_run(
    rig: MachineDescription, faults: list[str], message: str
) -> None:
    with pytest.raises(InputError, match=message):
        run_simulation(rig, cycles=1, seed=0, faults=faults)


def test_a_kind_without_size_refuses_one() -> None:
    with pytest.raises(InputError, match="a kind without size"):
        Fault("S_DNC_B", "stuck-on", 3.0)


def test_mass_balance_with_every_internal_fault(rig: MachineDescription) -> None:
    faults = ["DNC=piston-leak:10slpm", "DNC_A=valve-leak-in:5slpm", "DNC_B=valve-leak-out:5slpm"]
    result = run_simulation(rig, cycles=2, seed=1, faults=faults)
    out = result.outputs
    balance = (
        out["mass_regulator"]
        - (out["stored_mass"] - out["stored_mass"][0])
        - out["mass_exhausted"]
        - out["mass_leaked"]
    )
    assert out["mass_regulator"][-1] > 1e-3  # about 1 g of air went in
    assert np.abs(balance - balance[0]).max() < 1e-15


def test_simulate_command_records_faults_and_nuisances(tmp_path: Any, capsys: Any) -> None:
    from pneufdd.cli.app import main
    from pneufdd.recording import Recording
    from pneufdd.sim.faults import FAULT_KINDS

    out = tmp_path / "run.parquet"
    argv = [
        "simulate", "--machine", "press-fit-cell", "--cycles", "2", "--seed", "4",
        "--fault", "PRESS_B=throttle:-30%@3s", "--fault-growth", "PRESS_B=throttle:-36%/h",
        "--fault", "S_FEED_B=late:20ms", "--ambient", "15C..35C/1h",
        "--payload", "PRESS=+1.5kg@2s", "--header-dips", "depth=0.5bar,duration=1s,rate=60/h",
        "--out", str(out),
    ]  # fmt: skip
    assert main(argv) == 0
    meta = Recording.read(out).metadata
    assert {f["kind"] for f in meta["fault_schedule"]} == {"throttle", "late"}
    throttle = [r for r in meta["fault_timeline"] if r["kind"] == "throttle"]
    start = meta["cycle_start_s"][1]
    assert [r["cycle"] for r in throttle] == [1]  # appears in the cycle starting after 3 s
    assert throttle[0]["size"] == pytest.approx(-30.0 - 0.01 * (start - 3.0))
    rows = meta["nuisance_timeline"]
    assert [r["ambient_c"] for r in rows] == pytest.approx([15.0, 15.0 + 20.0 * start / 3600])
    assert rows[1]["payload_kg"] == {"PRESS": 1.5}
    assert meta["nuisances"]["header_dips"]["rate_per_h"] == pytest.approx(60.0)
    assert main(["faults"]) == 0
    listing = capsys.readouterr().out
    assert all(kind in listing for kind in FAULT_KINDS)


def test_docs_list_every_fault_kind_and_their_example_runs() -> None:
    from pathlib import Path

    from pneufdd.sim.faults import FAULT_KINDS

    docs = (Path(__file__).resolve().parents[1] / "docs" / "faults.md").read_text("utf-8")
    for kind in FAULT_KINDS:
        assert f"| `{kind}` |" in docs  # its row of the catalogue table
    (example,) = docs.split("```python\n")[1:]
    code = example.split("```")[0].replace("cycles=20", "cycles=2")
    namespace: dict[str, Any] = {}
    exec(compile(code, "docs/faults.md", "exec"), namespace)
    assert namespace["rec"].metadata["fault_timeline"][0]["kind"] in FAULT_KINDS
