"""The built-in press-fit-cell and carton-sorter machines (docs/machines.md).

Each test checks a figure docs/machines.md states: structure, catalogue valve flow,
segmentation of the simulated cycle, cycle and stroke times, air per stroke against
the cylinder geometry, and leaks of 3, 30 and 150 SLPM at every location. The
simulations are shared through module-scoped fixtures and kept to 3-4 cycles.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pneufdd.physics.flow import isa_mass_flow
from pneufdd.physics.units import kg_s_to_l_min_anr, kg_s_to_slpm, pa_to_bar_gauge, psig_to_pa
from pneufdd.signals.segmentation import actuator_of, segment, sequence_from_machine
from pneufdd.sim import SimulationResult, builtin_machines, load_machine, run_simulation, simulate

MACHINES = ("press-fit-cell", "carton-sorter")
SEED = 1
LEAK_SEED = 5
SL_PER_KG = 1.0 / 1.294e-3  # standard litres (0 degC, 1013 mbar) per kg
P_ATM = 101_325.0
T_WALL = 293.15
R_AIR = 287.058

# Valve of each actuator: catalogue type and standard nominal flow qnN [l/min ANR,
# 6 -> 5 bar(g)]; 5/3 valves taken as 90 % of the same size's 5/2 value.
VALVES: dict[str, dict[str, tuple[str, float]]] = {
    "press-fit-cell": {
        "FEED": ("5/2-bistable", 560.0),  # VUVG-L14-B52
        "CLAMP": ("5/2-monostable", 220.0),  # VUVG-L10-M52
        "PRESS": ("5/3-closed-centre", 0.9 * 870.0),  # VUVG-L18-P53C
        "EJECT": ("5/2-monostable", 220.0),  # VUVG-L10-M52
    },
    "carton-sorter": {
        "STOP": ("5/2-monostable", 220.0),  # VUVG-L10-M52
        "HOLD": ("5/2-monostable", 220.0),  # VUVG-L10-M52
        "CENTRE": ("5/2-bistable", 560.0),  # VUVG-L14-B52
        "PUSH_L": ("5/2-monostable", 560.0),  # VUVG-L14-M52
        "PUSH_R": ("5/2-monostable", 560.0),  # VUVG-L14-M52
        "GATE": ("5/2-bistable", 220.0),  # VUVG-L10-B52
    },
}
REGULATOR_QNN = 1400.0  # MS4-LR-1/4: l/min at 6 bar(g) set, 1 bar droop

# docs/machines.md, seed 1: stroke time [s] of every (actuator, direction) and the
# leak-free cycle duration [s]; strokes per cycle.
STROKE_S: dict[str, dict[tuple[str, int], float]] = {
    "press-fit-cell": {
        ("FEED", 1): 0.290, ("FEED", -1): 0.395,
        ("CLAMP", 1): 0.066, ("CLAMP", -1): 0.121,
        ("PRESS", 1): 0.340, ("PRESS", -1): 0.275,
        ("EJECT", 1): 0.129, ("EJECT", -1): 0.185,
    },
    "carton-sorter": {
        ("STOP", 1): 0.102, ("STOP", -1): 0.168,
        ("HOLD", 1): 0.034, ("HOLD", -1): 0.078,
        ("CENTRE", 1): 0.116, ("CENTRE", -1): 0.161,
        ("PUSH_L", 1): 0.511, ("PUSH_L", -1): 0.667,
        ("PUSH_R", 1): 0.510, ("PUSH_R", -1): 0.667,
        ("GATE", 1): 0.215, ("GATE", -1): 0.333,
    },
}  # fmt: skip
STROKES_PER_CYCLE = {"HOLD": 2, "CENTRE": 2}  # the others: one extension, one retraction
CYCLE_S = {"press-fit-cell": 3.15, "carton-sorter": 6.18}
AIR_PER_CYCLE_SL = {"press-fit-cell": 4.73, "carton-sorter": 10.68}


@pytest.fixture(scope="module")
def runs() -> dict[str, SimulationResult]:
    return {name: run_simulation(name, cycles=4, seed=SEED) for name in MACHINES}


def test_builtin_machines_listed() -> None:
    assert builtin_machines() == ("carton-sorter", "festo-dsd", "press-fit-cell")


@pytest.mark.parametrize("name", MACHINES)
def test_structure_differs_from_festo_dsd(name: str) -> None:
    """6 bar(g) supply, no vacuum, mixed valves with monostables, parallel motions, timers."""
    m = load_machine(name)
    assert m.name == name
    assert m.supply.regulator_set_psig == 87.0
    assert 100.0 <= m.supply.house_psig <= 115.0
    assert m.vacuum is None
    assert {a.id: a.valve.kind for a in m.actuators} == {k: v[0] for k, v in VALVES[name].items()}
    kinds = {a.valve.kind for a in m.actuators}
    assert "5/2-monostable" in kinds
    assert len(kinds) >= 2
    monostable = [a.id for a in m.actuators if a.valve.kind == "5/2-monostable"]
    assert all(f"U_{i}_B" not in m.solenoids for i in monostable)
    moving = [{actuator_of(a.solenoid) for a in s.actions} for s in m.steps]
    assert max(len(ids) for ids in moving) >= 2  # parallel motions in one step
    assert sum(s.dwell_s > 0 for s in m.steps) >= 2  # timers
    assert all(s.actions for s in m.steps)  # every step starts with a valve event
    sensors = {s.channel for s in m.sensors}
    if name == "press-fit-cell":
        assert len(m.actuators) == 4
        assert sensors == {
            "P_In", "Q_In", "P_PRESS_A", "P_PRESS_B", "Q_PRESS_A", "Q_PRESS_B", "X_PRESS",
        }  # fmt: skip
    else:
        assert len(m.actuators) == 6
        assert sensors == {"P_In", "Q_In"}
        assert any(a.mode == "pulse" for s in m.steps for a in s.actions)  # impulse valve


@pytest.mark.parametrize("name", MACHINES)
def test_valve_cv_passes_the_catalogue_flow(name: str) -> None:
    """Cv = qnN / 1050: eq. 4.6 passes the catalogue qnN at 6 -> 5 bar(g), 20 degC (2 %)."""
    m = load_machine(name)
    p1, p2 = P_ATM + 6e5, P_ATM + 5e5
    for a in m.actuators:
        qn = VALVES[name][a.id][1]
        flow = kg_s_to_l_min_anr(isa_mass_flow(p1, p2, a.valve.cv, a.valve.xt, T_WALL))
        assert flow == pytest.approx(qn, rel=0.02), a.id
    s = m.supply
    flow = kg_s_to_l_min_anr(isa_mass_flow(p1, p2, s.regulator_cv, s.regulator_xt, T_WALL))
    assert flow == pytest.approx(REGULATOR_QNN, rel=0.02)


@pytest.mark.parametrize("name", MACHINES)
def test_cycle_segments_exactly_like_the_description(
    name: str, runs: dict[str, SimulationResult]
) -> None:
    """4 cycles, each with every step of the description, within one 100 Hz sample."""
    desc = load_machine(name)
    rec = simulate(name, cycles=4, seed=SEED)
    seg = segment(rec, sequence_from_machine(desc))
    assert [len(c.steps) for c in seg.cycles] == [len(desc.steps)] * 4
    assert not seg.rejected, [c.reason for c in seg.rejected]
    starts = np.array([[s.start_s for s in c.steps] for c in seg.complete])
    err = starts - runs[name].step_start
    assert err.min() >= -1e-9
    assert err.max() <= 0.0100001


@pytest.mark.parametrize("name", MACHINES)
def test_cycle_time(name: str, runs: dict[str, SimulationResult]) -> None:
    durations = np.diff(runs[name].cycle_start)
    assert durations == pytest.approx(CYCLE_S[name], rel=0.02)


@pytest.mark.parametrize("name", MACHINES)
def test_stroke_times_and_speeds(name: str, runs: dict[str, SimulationResult]) -> None:
    """Stroke times as docs/machines.md states (5 %); mean speeds 0.1-0.5 m/s."""
    res = runs[name]
    for a in res.machine.actuators:
        for direction in (1, -1):
            strokes = res.strokes_of(a.id, direction)
            assert len(strokes) == 4 * STROKES_PER_CYCLE.get(a.id, 1), (a.id, direction)
            for s in strokes:
                assert s.duration == pytest.approx(STROKE_S[name][a.id, direction], rel=0.05)
                assert 0.1 <= a.stroke_mm * 1e-3 / s.duration <= 0.5, (a.id, s)


def _geometric_sl(a: Any, side: str, supply_pa: float) -> float:
    """Free air to fill one line from atmosphere to the set point, isothermal [SL].

    Swept volume plus dead volume (cushion, ports, tube) at the supply pressure,
    minus the dead volume's air at atmosphere.
    """
    bore = math.pi * (a.bore_mm * 1e-3) ** 2 / 4
    area = bore if side == "A" else bore - math.pi * (a.rod_mm * 1e-3) ** 2 / 4
    tube = math.pi * (a.tube_inner_diameter_mm * 1e-3) ** 2 / 4 * a.tube_length_m
    dead = (a.dead_volume_a_cm3 if side == "A" else a.dead_volume_b_cm3) * 1e-6 + tube
    swept = area * a.stroke_mm * 1e-3
    return (supply_pa * (swept + dead) - P_ATM * dead) / (R_AIR * T_WALL) * SL_PER_KG


@pytest.mark.parametrize("name", MACHINES)
def test_air_per_stroke_matches_the_geometry(name: str, runs: dict[str, SimulationResult]) -> None:
    """Air into each line per stroke is 0.75-1.02 x the isothermal fill at the set point.

    Below 1: the chamber fills nearly adiabatically and the valve may switch before
    the air has cooled and topped up, and the other chamber has not always vented to
    atmosphere before it is refilled (short strokes). Above 1 only by the regulator's
    overshoot when house pressure is high. The machine's air per cycle (through the
    supply meter) is the figure docs/machines.md states (3 %).
    """
    res = runs[name]
    supply_pa = float(psig_to_pa(res.machine.supply.regulator_set_psig))
    t = res.time
    for a in res.machine.actuators:
        n = STROKES_PER_CYCLE.get(a.id, 1)
        for side in "AB":
            flow = res.outputs[f"mdot_in_{a.id}_{side}"]
            geometric = _geometric_sl(a, side, supply_pa)
            for c in (1, 2):
                mask = (t >= res.step_start[c, 0]) & (t < res.step_start[c + 1, 0])
                per_stroke = flow[mask].sum() * 1e-3 * SL_PER_KG / n
                assert 0.75 <= per_stroke / geometric <= 1.02, (a.id, side, per_stroke, geometric)
    supplied = res.outputs["mass_supplied"]
    for c in (1, 2):
        i0, i1 = (int(np.searchsorted(t, res.step_start[k, 0])) for k in (c, c + 1))
        sl = (supplied[i1] - supplied[i0]) * SL_PER_KG
        assert sl == pytest.approx(AIR_PER_CYCLE_SL[name], rel=0.03)


@pytest.mark.parametrize("name", MACHINES)
def test_supply_meter_range_fits(name: str, runs: dict[str, SimulationResult]) -> None:
    """Q_In stays below full scale, also with a 150 SLPM supply leak; P_In above 5 bar(g)."""
    meter = next(s for s in load_machine(name).sensors if s.channel == "Q_In")
    for res in (runs[name], run_simulation(name, 2, {"supply": "150slpm"}, SEED)):
        q = kg_s_to_slpm(res.recording.channel("Q_In")[1])
        assert q.max() < 0.9 * meter.range_high
        p = pa_to_bar_gauge(res.recording.channel("P_In")[1])
        assert p.min() > 5.0
        assert p.max() < 6.1


def _mean_q_in_slpm(res: SimulationResult) -> float:
    """Mean Q_In meter reading over the second of three cycles [SLPM]."""
    t, q = res.recording.channel("Q_In")
    mask = (t >= res.step_start[1, 0]) & (t < res.step_start[2, 0])
    return float(kg_s_to_slpm(q[mask].mean()))


@pytest.fixture(scope="module")
def leak_free() -> dict[str, float]:
    return {
        name: _mean_q_in_slpm(run_simulation(name, 3, seed=LEAK_SEED, keep_outputs=False))
        for name in MACHINES
    }


@pytest.mark.parametrize(
    ("name", "location"),
    [(name, loc) for name in MACHINES for loc in load_machine(name).leak_locations],
)
def test_leak_of_3_30_150_slpm_runs_and_shows(
    name: str, location: str, leak_free: dict[str, float]
) -> None:
    """Every location: 3 cycles run (no stall) and segment; mean Q_In rises with the leak.

    A supply leak blows all cycle: Q_In rises by 0.95-1.01 x its nominal flow (less:
    the supply pressure sags while actuators move). A line leak blows only while its
    line is pressurised: Q_In rises, by at most the nominal flow (5 %: a leak also
    changes the cycle time, and the meter's noise).
    """
    desc = load_machine(name)
    sequence = sequence_from_machine(desc)
    rise = []
    for size in (3.0, 30.0, 150.0):
        res = run_simulation(name, 3, {location: f"{size}slpm"}, LEAK_SEED, keep_outputs=False)
        seg = segment(res.recording, sequence)
        assert len(seg.complete) == 3
        assert not seg.rejected, [c.reason for c in seg.rejected]
        rise.append(_mean_q_in_slpm(res) - leak_free[name])
        if location == "supply":
            assert 0.95 <= rise[-1] / size <= 1.01, (size, rise[-1])
        else:
            assert rise[-1] <= 1.05 * size, (size, rise[-1])
    assert 0.0 < rise[0] < rise[1] < rise[2], rise


def test_example_machine_segments_like_its_description() -> None:
    """docs/examples/pick-place.toml (every actuator kind but `linear`, a 5/3
    closed-centre axis held by `until`, a pulsed bistable valve, an ejector) loads,
    runs and segments into every step of its description in every cycle."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "docs" / "examples" / "pick-place.toml"
    desc = load_machine(str(path))
    assert [a.id for a in desc.actuators] == ["X", "Z", "ROT", "GRIP"]
    rec = simulate(desc, cycles=3, seed=SEED)
    seg = segment(rec, sequence_from_machine(desc))
    assert [len(c.steps) for c in seg.complete] == [len(desc.steps)] * 3
    assert not seg.rejected, [c.reason for c in seg.rejected]
