"""Acceptance tests of the digital twin against the dissertation's measurements.

Each test names the section, table or equation whose number it checks. Simulations
are shared through module-scoped fixtures and kept to a few cycles.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pneufdd.physics.leaks import leak_mass_flow
from pneufdd.physics.units import kg_s_to_slpm, pa_to_psig
from pneufdd.sim import SimulationResult, run_simulation

MACHINE = "festo-dsd"
SEED = 11
DNC_BORE = 0.032
DNC_ROD = 0.012
A_A = math.pi * DNC_BORE**2 / 4
A_B = A_A - math.pi * DNC_ROD**2 / 4
SL_PER_KG = 1.0 / 1.294e-3  # standard litres per kg (section 3.4.1 basis)
DNC_RETRACT_STEP = 1  # 0-based index of step 2
DNC_EXTEND_STEP = 57  # 0-based index of step 58


def _window(res: SimulationResult, cycle: int, step: int) -> tuple[float, float]:
    """[step start, next step start): the same window in every cycle measured.

    The run's final step has no next step (its recording runs on into the idle
    machine, RUN_END_IDLE_S), so the figures use cycles that another cycle follows.
    """
    start = res.step_start[cycle, step]
    if step + 1 < res.step_start.shape[1]:
        return start, res.step_start[cycle, step + 1]
    assert cycle + 1 < res.step_start.shape[0], "the run's final step has no next step"
    return start, res.step_start[cycle + 1, 0]


def _integral_sl(res: SimulationResult, channel: str, a: float, b: float) -> float:
    t, q = res.recording.channel(channel)
    mask = (t >= a) & (t < b)
    return float(q[mask].sum() * 1e-3 * SL_PER_KG)


def _min_psig(res: SimulationResult, a: float, b: float) -> float:
    t, p = res.recording.channel("P_In")
    return float(pa_to_psig(p[(t >= a) & (t < b)].min()))


def _stroke_figures(res: SimulationResult, cycle: int) -> dict[str, float]:
    ea, eb = _window(res, cycle, DNC_EXTEND_STEP)
    ra, rb = _window(res, cycle, DNC_RETRACT_STEP)
    return {
        "extend_sl": _integral_sl(res, "Q_DNC_A", ea, eb),
        "retract_sl": _integral_sl(res, "Q_DNC_B", ra, rb),
        "extend_min_psig": _min_psig(res, ea, eb),
        "retract_min_psig": _min_psig(res, ra, rb),
    }


@pytest.fixture(scope="module")
def reference() -> SimulationResult:
    return run_simulation(MACHINE, cycles=4, seed=SEED)


@pytest.fixture(scope="module")
def dnc_a_sweep() -> dict[int, dict[str, float]]:
    out = {}
    for turns in (0, 2, 4, 5, 6):
        res = run_simulation(MACHINE, cycles=3, seed=SEED, leaks={"DNC_A": turns})
        out[turns] = _stroke_figures(res, 1)
    return out


@pytest.fixture(scope="module")
def dnc_b_sweep() -> dict[int, dict[str, float]]:
    out = {}
    for turns in (0, 2, 4, 5, 6):
        res = run_simulation(MACHINE, cycles=3, seed=SEED, leaks={"DNC_B": turns})
        out[turns] = _stroke_figures(res, 1)
    return out


def test_dnc_extend_stroke_time(reference: SimulationResult) -> None:
    """Section 3.2.4, eq. 3.1: 0.38 s at about 0.52 m/s; accept 0.30-0.46 s."""
    strokes = reference.strokes_of("DNC", +1)
    assert len(strokes) >= 2
    for s in strokes:
        assert 0.30 <= s.duration <= 0.46, s
        assert 0.40 <= 0.2 / s.duration <= 0.70  # mean speed [m/s]


def test_dnc_air_per_stroke(reference: SimulationResult) -> None:
    """Tables 4.2/4.3: 0.63 SL per stroke without leak; accept 0.5-0.8 SL (from the meters)."""
    for cycle in (1, 2):
        fig = _stroke_figures(reference, cycle)
        assert 0.5 <= fig["extend_sl"] <= 0.8, fig
        assert 0.5 <= fig["retract_sl"] <= 0.8, fig


def test_min_supply_pressure_during_dnc_strokes(reference: SimulationResult) -> None:
    """Table 4.2: minimum supply pressure 62.48 / 60.5 psig; accept 55-70 psig."""
    for cycle in (1, 2):
        fig = _stroke_figures(reference, cycle)
        assert 55.0 <= fig["extend_min_psig"] <= 70.0, fig
        assert 55.0 <= fig["retract_min_psig"] <= 70.0, fig


def test_dnc_a_leak_trend(dnc_a_sweep: dict[int, dict[str, float]]) -> None:
    """Table 4.2: extend consumption rises and minimum supply pressure falls with turns."""
    turns = sorted(dnc_a_sweep)
    flow = [dnc_a_sweep[n]["extend_sl"] for n in turns]
    pmin = [dnc_a_sweep[n]["extend_min_psig"] for n in turns]
    assert all(b > a for a, b in itertools.pairwise(flow)), flow
    assert all(b < a for a, b in itertools.pairwise(pmin)), pmin
    # the retract stroke (other line) uses less air with an extend-line leak (Table 4.2)
    assert dnc_a_sweep[6]["retract_sl"] < dnc_a_sweep[0]["retract_sl"]


def test_dnc_b_leak_trend(dnc_b_sweep: dict[int, dict[str, float]]) -> None:
    """Table 4.3: retract consumption rises and minimum supply pressure falls with turns."""
    turns = sorted(dnc_b_sweep)
    flow = [dnc_b_sweep[n]["retract_sl"] for n in turns]
    pmin = [dnc_b_sweep[n]["retract_min_psig"] for n in turns]
    assert all(b > a for a, b in itertools.pairwise(flow)), flow
    assert all(b < a for a, b in itertools.pairwise(pmin)), pmin
    assert dnc_b_sweep[6]["extend_sl"] < dnc_b_sweep[0]["extend_sl"]


def test_mass_balance_over_a_cycle(reference: SimulationResult) -> None:
    """Air in at the supply = change of stored air + exhausted + leaked (within 2 %)."""
    o = reference.outputs
    for cycle in range(3):
        a, b = _window(reference, cycle, 0)[0], _window(reference, cycle, 57)[1]
        i0 = int(np.searchsorted(reference.time, a))
        i1 = min(int(np.searchsorted(reference.time, b)), reference.time.size - 1)
        supplied = o["mass_regulator"][i1] - o["mass_regulator"][i0]
        stored = o["stored_mass"][i1] - o["stored_mass"][i0]
        out = sum(o[k][i1] - o[k][i0] for k in ("mass_exhausted", "mass_leaked", "mass_vacuum"))
        assert supplied > 0
        assert abs(supplied - (stored + out)) <= 0.02 * supplied


def test_stick_slip_force_recovered_by_eq_4_15(reference: SimulationResult) -> None:
    """Eq. 4.15 on the recorded DNC pressures at motion start gives F_sf = 150 N (+-15 %).

    Eq. 4.15 balances the pressure force against the static friction at the instant
    the piston first breaks away (``first_motion``), before any stick-slip creep.
    """
    _t, pa = reference.recording.channel("P_DNC_A")
    _, pb = reference.recording.channel("P_DNC_B")
    pa_g = pa - 101_325.0
    pb_g = pb - 101_325.0
    checked = 0
    for s in reference.strokes_of("DNC"):
        assert s.first_motion <= s.start < s.end
        i = round(s.first_motion * 1000.0)
        force = pa_g[i] * A_A - pb_g[i] * A_B
        if s.direction < 0:
            force = -force
        assert force == pytest.approx(150.0, rel=0.15), (s, force)
        checked += 1
    assert checked >= 4


def test_cycles_differ(reference: SimulationResult) -> None:
    """Supply fluctuation and friction scatter: leak-free cycles are not identical."""
    # stroke times on the 1 ms grid: not all the same
    times = {round(s.duration * 1000) for s in reference.strokes_of("DNC", +1)}
    assert len(times) >= 2
    durations = np.diff(reference.cycle_start)
    assert abs(durations[0] - durations[1]) >= 0.005
    assert 5.0 < durations[0] < 60.0
    # the house-air fluctuation moves each cycle's mean supply pressure by far more
    # than the sensor noise averaged over a cycle (measured spread: about 2 kPa)
    t, p_in = reference.recording.channel("P_In")
    edges = np.append(reference.cycle_start, t[-1])
    means = [np.mean(p_in[(t >= a) & (t < b)]) for a, b in itertools.pairwise(edges)]
    assert np.ptp(means) > 500.0


def test_switches_drive_sequence_and_return_home(reference: SimulationResult) -> None:
    """Every actuator ends each cycle where it started (periodic 58-step cycle)."""
    o = reference.outputs
    starts = [round(t * 1000) for t in reference.cycle_start]
    for a in reference.machine.actuators:
        x = o[f"x_{a.id}"]
        assert x[starts[1]] == pytest.approx(x[starts[2]], abs=1e-3), a.id
        assert x[starts[0]] == pytest.approx(x[starts[1]], abs=1e-3), a.id
    # every actuator moved in both directions within one cycle
    moved = {(s.actuator, s.direction) for s in reference.strokes if s.cycle == 1}
    for a in reference.machine.actuators:
        assert (a.id, 1) in moved, a.id
        assert (a.id, -1) in moved, a.id


@pytest.fixture(scope="module")
def supply_pair() -> tuple[SimulationResult, SimulationResult]:
    ref = run_simulation(MACHINE, cycles=2, seed=5)
    leak = run_simulation(MACHINE, cycles=2, seed=5, leaks={"supply": 3})
    return ref, leak


def test_supply_leak_constant_in_every_step(
    supply_pair: tuple[SimulationResult, SimulationResult],
) -> None:
    """Section 5.3.1.2: a supply leak adds a near-constant flow to Q_In in every step.

    * In every one of the 58 steps the leak's flow equals the orifice flow at the
      recorded supply pressure ``P_In`` within 5 %, and stays within 15 % of its
      cycle mean (the supply pressure dips during the DNC strokes).
    * Step-synchronised (lag removed, section 5.3.1.1), the typical (median) step's
      extra ``Q_In`` volume equals the leak's volume in that step within 5 %, and over
      the whole cycle within 10 % (the rest: less air per stroke at the lower supply
      pressure, and the 200 SLPM meter saturating in the DNC steps).
    """
    ref, leak = supply_pair
    area = leak.leaks[0].area_m2
    qr = ref.recording.channel("Q_In")[1]
    ql = leak.recording.channel("Q_In")[1]
    pl = leak.recording.channel("P_In")[1]
    flow = leak.outputs["mdot_leak_supply"]
    assert kg_s_to_slpm(leak.leaks[0].nominal_mass_flow_kg_s) > 40.0
    step_mean, ratios = [], []
    for step in range(58):
        ra, rb = (round(v * 1000) for v in _window(ref, 0, step))
        la, lb = (round(v * 1000) for v in _window(leak, 0, step))
        mean = flow[la:lb].mean()
        orifice = np.mean([leak_mass_flow(p, area) for p in pl[la:lb]])
        assert mean == pytest.approx(orifice, rel=0.05), step
        step_mean.append(mean)
        ratios.append((ql[la:lb].sum() - qr[ra:rb].sum()) / flow[la:lb].sum())
    step_mean_arr = np.array(step_mean)
    assert np.all(np.abs(step_mean_arr / step_mean_arr.mean() - 1.0) < 0.15)
    assert np.median(ratios) == pytest.approx(1.0, abs=0.05), np.round(ratios, 3)
    end_r = round(ref.step_start[1, 0] * 1000)
    end_l = round(leak.step_start[1, 0] * 1000)
    total = (ql[:end_l].sum() - qr[:end_r].sum()) / flow[:end_l].sum()
    assert total == pytest.approx(1.0, abs=0.10)


def test_accumulated_lag(supply_pair: tuple[SimulationResult, SimulationResult]) -> None:
    """Section 5.3.1.1: a leak delays every later step; the lag accumulates."""
    ref, leak = supply_pair
    lag = leak.step_start[0] - ref.step_start[0]
    assert lag[0] == 0.0
    assert lag[10] > 0.0
    assert lag[57] > lag[10]
    assert leak.step_start[1, 0] - ref.step_start[1, 0] > lag[57]


def test_dnc_b_leak_shows_in_steps_2_and_58() -> None:
    """Section 5.3.1.3: more inflow in step 2, less air in step 58, little elsewhere."""
    ref = run_simulation(MACHINE, cycles=3, seed=7)
    leak = run_simulation(MACHINE, cycles=3, seed=7, leaks={"DNC_B": 4})
    diffs = []
    for step in range(58):
        a, b = _window(ref, 1, step)
        c, d = _window(leak, 1, step)
        diffs.append(_integral_sl(leak, "Q_In", c, d) - _integral_sl(ref, "Q_In", a, b))
    diffs_arr = np.array(diffs)
    assert diffs_arr[1] == diffs_arr.max()
    assert diffs_arr[1] > 0.2
    assert diffs_arr[57] < -0.1
    # away from steps 1-5 and 58 (valve off delays and supply recovery) nothing shows
    assert np.all(np.abs(diffs_arr[5:57]) < 0.05), np.round(diffs_arr, 3)


def test_stroke_start_is_the_start_of_sustained_travel(reference: SimulationResult) -> None:
    """Section 3.3: t_s starts at the start-up of the acceleration, not at stick-slip creep.

    With F_cf > F_sf (section 4.2.3) the piston first creeps by micro-slips; the
    ground-truth start is the breakaway after which it travels 0.2 mm without
    sticking again (docs/twin.md).
    """
    t, x = reference.time, reference.outputs["x_DNC"]
    strokes = reference.strokes_of("DNC")
    assert len(strokes) == 8
    creeps = []
    for s in strokes:
        i0, i1 = np.searchsorted(t, [s.first_motion, s.start])
        home = x[i0 - 1]
        # creep before the start: micrometres, not the 1.2 mm the LVDT could resolve
        assert np.max(np.abs(x[i0 - 1 : i1 + 1] - home)) < 1e-4, s
        # after the start the piston keeps going: 0.2 mm within 20 ms, monotone
        ahead = s.direction * (x[i1 : i1 + 20] - home)
        assert ahead[-1] > 2e-4, s
        assert np.all(np.diff(ahead) >= -1e-12), s
        creeps.append(s.start - s.first_motion)
    # the dissertation's friction makes the retract creep for several ms
    assert max(creeps) > 0.003
