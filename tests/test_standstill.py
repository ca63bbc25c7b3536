"""The standstill leak test: plan, PLC program, the twin's run of it, and its analysis."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import InputError
from pneufdd.physics.units import psig_to_pa
from pneufdd.sim import load_machine, run_simulation, vary_machine
from pneufdd.standstill import plan_standstill
from pneufdd.standstill.analyse import held_states, measure_states
from pneufdd.standstill.estimate import estimate_leaks
from pneufdd.standstill.plan import StandstillPlan, measurement_rows
from pneufdd.standstill.program import state_table, structured_text, twin_description
from pneufdd.standstill.twin import simulate_standstill

SEED = 55_000  # this file's seeds (development seeds, not acceptance)


@pytest.fixture(scope="module")
def press():
    twin = load_machine("press-fit-cell")
    return twin, vary_machine(twin, scale=2.0, seed=SEED)


def test_plans_of_the_built_in_machines() -> None:
    expected = {  # states; what the states separate on their own
        "festo-dsd": (11, {"DNC_A", "DNC_B", "HMPL_V_A", "HMPL_V_B"}),
        "press-fit-cell": (6, {"PRESS_A", "PRESS_B"}),
        "carton-sorter": (7, set()),
    }
    for name, (states, separable) in expected.items():
        machine = load_machine(name)
        plan = plan_standstill(machine)
        assert plan.mode == "flow"
        assert len(plan.states) == states
        assert set(plan.separable) == separable
        assert all("supply" in s.pressurised for s in plan.states)
        m, _ = measurement_rows(plan)
        # every separable location's unit vector lies in the row space; no other does
        pinv = np.linalg.pinv(m)
        for k, loc in enumerate(plan.locations):
            unit = np.eye(len(plan.locations))[k]
            estimable = np.allclose(unit @ pinv @ m, unit, atol=1e-9)
            assert estimable == (loc in separable), (name, loc)
        # a 5/2 valve's two lines are never told apart as a pair (without line meters)
        for a in machine.actuators:
            if a.valve.kind != "5/3-closed-centre" and f"{a.id}_A" not in plan.line_flow_channels:
                assert (f"{a.id}_A", f"{a.id}_B") in plan.pairs_not_separable
        again = StandstillPlan.from_dict(json.loads(plan.to_json()))
        assert again == plan


def test_the_decay_plan_lists_each_state_volume(press) -> None:
    twin, _ = press
    plan = plan_standstill(twin, mode="decay")
    home, feed_out = plan.states[0], plan.states[1]
    feed = next(a for a in twin.actuators if a.id == "FEED")
    swept = np.pi / 4 * (feed.bore_mm * 1e-3) ** 2 * feed.stroke_mm * 1e-3
    annulus = np.pi / 4 * ((feed.bore_mm * 1e-3) ** 2 - (feed.rod_mm * 1e-3) ** 2)
    # FEED extended: line A holds the swept volume, line B (exhausted) is not connected
    delta = feed_out.connected_volume_m3 - home.connected_volume_m3
    assert delta == pytest.approx(swept - annulus * feed.stroke_mm * 1e-3, rel=1e-9)
    supply = (twin.supply.reservoir_volume_l + twin.supply.manifold_volume_l) * 1e-3
    assert plan.supply_volume_m3 == pytest.approx(supply)
    centre = plan.states[-1]
    assert "PRESS_A" not in centre.pressurised
    assert "PRESS_B" not in centre.pressurised
    raw = dict(load_machine("festo-dsd").raw)
    raw["sensor"] = [s for s in raw["sensor"] if s["channel"] != "Q_In"]
    no_meter = load_machine(raw)
    with pytest.raises(InputError, match="a supply flow meter"):
        plan_standstill(no_meter, mode="flow")
    assert plan_standstill(no_meter).mode == "decay"


def test_the_plc_program_and_table(press) -> None:
    twin, _ = press
    for mode in ("flow", "decay"):
        plan = plan_standstill(twin, mode=mode, settle_s=4.0, window_s=6.0)
        st = structured_text(plan)
        assert st.startswith("FUNCTION_BLOCK FB_StandstillLeakTest")
        assert st.rstrip().endswith("END_FUNCTION_BLOCK")
        for open_word, close_word in (("CASE", "END_CASE"), ("VAR(_INPUT|_OUTPUT)?", "END_VAR")):
            opens = len(re.findall(rf"^\s*{open_word}\b", st, flags=re.M))
            assert opens == len(re.findall(rf"^\s*{close_word}\b", st, flags=re.M)) >= 1
        assert "SETTLE_TIME : TIME := T#4000MS;" in st
        assert "WINDOW_TIME : TIME := T#6000MS;" in st
        for k, state in enumerate(plan.states, start=1):
            assert f"{k}: (* {state.name} *)" in st
        # the monostable CLAMP held on only where the state extends it
        assert st.count("U_CLAMP_A := TRUE;") == 1
        # PRESS (5/3): held on B at home, on A when extended, both off in the centre
        assert "U_PRESS_A := TRUE;" in st
        assert ("ShutOff := Measuring;" in st) == (mode == "decay")
        csv_text, md = state_table(plan)
        assert csv_text.count("\n") == len(plan.states) + 1
        assert "to the retracted end, then U_PRESS_A and U_PRESS_B off (centre)" in md


def test_a_closed_supply_loses_air_only_through_a_leak(press) -> None:
    twin, _ = press
    raw = twin_description(twin, plan_standstill(twin), state=0)  # home, held
    leaky, tight = (
        run_simulation(raw, cycles=2, leaks=leaks, seed=SEED, supply_open=(True, False))
        for leaks in ({"supply": "60slpm"}, {})
    )
    for run, falls in ((leaky, True), (tight, False)):
        t, p = run.recording.channel("P_In")
        closed = run.step_start[1, 0]
        before = p[(t > closed - 0.3) & (t < closed)].mean()
        after = p[(t > closed + 1.7) & (t < closed + 2.0)].mean()
        assert (before - after > 0.5e5) == falls
    with pytest.raises(InputError, match="supply_open"):
        run_simulation(raw, cycles=2, supply_open=(True,))


@pytest.mark.parametrize("mode", ["flow", "decay"])
def test_one_leak_found_and_sized_on_a_plant(press, mode: str) -> None:
    twin, plant = press
    plan = plan_standstill(twin, mode=mode)
    tolerance = 0.10 if mode == "flow" else 0.20  # the acceptance, on one plant
    for k, location in enumerate(("PRESS_B", "EJECT_A", "FEED_B")):
        recs = simulate_standstill(plant, plan, {location: "60slpm"}, seed=SEED + k)
        result = estimate_leaks(plan, measure_states(recs, plan))
        (leak,) = result.leaks
        assert leak.location == location
        assert leak.flow_slpm == pytest.approx(60.0, rel=tolerance)
        assert leak.std_slpm > 0.0
    free = estimate_leaks(plan, measure_states(simulate_standstill(plant, plan, {}), plan))
    assert not free.leak_found


def test_two_leaks_where_the_plan_separates_them(press) -> None:
    twin, plant = press
    plan = plan_standstill(twin)
    assert ("CLAMP_A", "PRESS_B") in plan.pairs_separable
    recs = simulate_standstill(plant, plan, {"CLAMP_A": "60slpm", "PRESS_B": "40slpm"}, SEED + 5)
    result = estimate_leaks(plan, measure_states(recs, plan))
    found = {leak.location: leak.flow_slpm for leak in result.leaks}
    assert set(found) == {"CLAMP_A", "PRESS_B"}
    assert found["CLAMP_A"] == pytest.approx(60.0, rel=0.10)
    assert found["PRESS_B"] == pytest.approx(40.0, rel=0.10)
    assert result.lines["PRESS_B"][0] == pytest.approx(40.0, rel=0.10)
    # a pair it cannot separate: both lines of FEED look like the supply and one line
    assert ("FEED_A", "FEED_B") in plan.pairs_not_separable
    recs = simulate_standstill(plant, plan, {"FEED_A": "60slpm", "FEED_B": "40slpm"}, SEED + 6)
    result = estimate_leaks(plan, measure_states(recs, plan))
    explained = [
        {x.location for x in result.leaks},
        *[set(a) for a in result.leaks[0].alternatives],
    ]
    assert {"FEED_A", "FEED_B"} in explained or any("supply" in e for e in explained)


def test_states_are_found_by_their_switches_and_solenoids(press) -> None:
    twin, plant = press
    plan = plan_standstill(twin)
    (rec,) = simulate_standstill(plant, plan, {}, seed=SEED)
    held = held_states(rec, plan)
    assert [k for k, _, _ in held] == list(range(len(plan.states)))
    for _, start, end in held:
        assert end - start >= plan.settle_s + 0.9 * plan.window_s


def test_standstill_cli(press, tmp_path: Path, capsys) -> None:
    twin, plant = press
    folder = tmp_path / "plan"
    assert main(["standstill", "plan", "--machine", "press-fit-cell"]) == 0  # prints, writes none
    table = capsys.readouterr().out
    assert table.startswith("| state | name | FEED | CLAMP | PRESS | EJECT |")
    assert table.count("\n") == 2 + 6
    assert main(["standstill", "plan", "--machine", "press-fit-cell", "--out", str(folder)]) == 0
    assert sorted(p.name for p in folder.iterdir()) == [
        "plan.json", "standstill.csv", "standstill.md", "standstill.st"
    ]  # fmt: skip
    assert "separated on their own: PRESS_A, PRESS_B" in capsys.readouterr().err
    # an existing plan is not replaced unasked
    assert main(["standstill", "plan", "--machine", "press-fit-cell", "--out", str(folder)]) == 2
    plan = plan_standstill(twin)
    runs = {}
    for name, leaks in (("free", {}), ("leak", {"EJECT_B": "60slpm"})):
        (rec,) = simulate_standstill(plant, plan, leaks, seed=SEED + 7)
        runs[name] = tmp_path / f"{name}.parquet"
        rec.write(runs[name])
    out = tmp_path / "result.json"
    code = main(
        ["standstill", "analyse", str(runs["leak"]), "--plan", str(folder), "--json", str(out)]
    )
    assert code == 1
    result = json.loads(out.read_text())
    assert result["leak_found"] is True
    assert [leak["location"] for leak in result["leaks"]] == ["EJECT_B"]
    assert "leak at EJECT_B" in capsys.readouterr().err
    assert main(["standstill", "analyse", str(runs["free"]), "--plan", str(folder)]) == 0
    assert main(["standstill", "analyse", str(runs["free"]), "--plan", str(tmp_path)]) == 2
    assert "plan.json" in capsys.readouterr().err


def test_sizes_refer_to_the_measured_supply_pressure(press) -> None:
    twin, plant = press
    plan = plan_standstill(twin)
    (rec,) = simulate_standstill(plant, plan, {"supply": "60slpm"}, seed=SEED + 8)
    result = estimate_leaks(plan, measure_states(rec and [rec], plan))
    # the plant's regulator, not the description's: within its droop and gauge error
    assert result.reference_pressure_pa == pytest.approx(
        psig_to_pa(plant.supply.regulator_set_psig), abs=0.25e5
    )
