"""Recording -> StepTable summaries and twin-computed signatures on festo-dsd."""

from __future__ import annotations

import numpy as np
import pytest

from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.twin import SIGNATURE_SEED, TwinLeakEffect, compute_signatures
from pneufdd.errors import InputError
from pneufdd.features.step_summaries import (
    build_step_table,
    machine_sequence,
    segment_cycles,
    sequence_from_records,
    sequence_to_records,
    trace_offsets,
)
from pneufdd.location import SUPPLY, Location
from pneufdd.physics.units import slpm_to_kg_s
from pneufdd.sim import MachineStalledError, load_machine, run_simulation, simulate

SEED = 32_000


@pytest.fixture(scope="module")
def recording():
    return simulate("festo-dsd", cycles=5, seed=SEED + 1)


def test_machine_sequence_segments_every_inner_cycle(recording):
    seq = machine_sequence(load_machine("festo-dsd"))
    assert all(spec.valves for spec in seq)
    assert sequence_from_records(sequence_to_records(seq)) == seq
    cycles, _used, rejected = segment_cycles(recording, seq)
    # 5 simulated cycles: at most the first (starts from rest) and the last (no
    # successor closes its last step) are partial, whatever the timing
    assert len(cycles) >= 3
    assert len(cycles) + len(rejected) == 5
    assert all(("mid-cycle" in r) or ("recording" in r) for r in rejected)
    assert all(len(c.steps) == len(seq) for c in cycles)


def test_step_summaries_equal_direct_slicing(recording):
    seq = machine_sequence(load_machine("festo-dsd"))
    cycles, _, _ = segment_cycles(recording, seq)
    offsets = trace_offsets(cycles, 100.0)
    table = build_step_table(recording, cycles, "festo-dsd", ["P_In", "Q_DNC_B"], offsets)
    for name, c in (("P_In", 0), ("Q_DNC_B", 1)):
        t, v = recording.channel(name)
        for i, j in [(0, 0), (1, 1), (2, 30)]:
            step = cycles[i].steps[j]
            sel = v[(t >= step.start_s - 1e-9) & (t < step.end_s - 1e-9)]
            assert table.summaries[i, j, c, 0] == pytest.approx(np.mean(sel), rel=1e-9)
            assert table.summaries[i, j, c, 1] == pytest.approx(np.min(sel))
            assert table.summaries[i, j, c, 2] == pytest.approx(np.max(sel))
            # the template starts at the step's own start (lag removal, 5.3.1.1): the
            # first 100 Hz block at or after the step's start
            block = int(np.ceil(step.start_s * 100.0 - 1e-9))
            expected = np.mean(v[block * 10 : block * 10 + 10])
            assert table.traces[i, c, offsets[j]] == pytest.approx(expected, rel=1e-9)
    assert np.allclose(table.durations, [[s.duration_s for s in c.steps] for c in cycles])


def test_cycle_air_and_pressure_from_the_step_table(recording):
    """The monitor's per-cycle supply air and pressure (StepTable.cycle_integral/_mean)."""
    seq = machine_sequence(load_machine("festo-dsd"))
    cycles, _, _ = segment_cycles(recording, seq)
    table = build_step_table(recording, cycles, "festo-dsd", ["P_In", "Q_In"])
    t, q = recording.channel("Q_In")
    for i, cycle in enumerate(cycles):
        # oracle: the rectangle rule over the raw samples of the cycle [kg]
        inside = (t >= cycle.start_s - 1e-9) & (t < cycle.steps[-1].end_s - 1e-9)
        direct = np.sum(q[inside]) * (t[1] - t[0])
        assert table.cycle_integral("Q_In")[i] == pytest.approx(direct, rel=1e-6)
    assert np.array_equal(table.cycle_mean("P_In"), table.summaries[:, :, 0, 0].mean(axis=1))
    assert table.cycle_mean("P_In").min() > 5e5  # a supply around 6 bar absolute [Pa]
    with pytest.raises(InputError, match="Q_DNC_A"):
        table.cycle_integral("Q_DNC_A")


SIG_SIZES_SLPM = (30.0, 55.0)


@pytest.fixture(scope="module")
def q_in_features():
    """festo-dsd's PLC sequence and the names of its Q_In step features."""
    rec = simulate("festo-dsd", cycles=3, seed=SEED + 2)
    seq = machine_sequence(load_machine("festo-dsd"))
    cycles, _, _ = segment_cycles(rec, seq)
    return seq, build_step_table(rec, cycles, "festo-dsd", ["Q_In"]).feature_names()


def _q_in_signatures(q_in_features, sizes_slpm, locations):
    """festo-dsd's Q_In leak signatures at ``sizes_slpm`` [SLPM], one simulated cycle."""
    seq, names = q_in_features
    return compute_signatures(
        load_machine("festo-dsd"),
        names,
        seq,
        cycles=1,
        channels=["Q_In"],
        sizes_slpm=sizes_slpm,
        locations=locations,
        workers=1,
    )


@pytest.fixture(scope="module")
def signatures(q_in_features):
    """Simulated signatures of a supply and a DNC_B leak at 30 and 55 SLPM (Q_In only)."""
    sig = _q_in_signatures(q_in_features, SIG_SIZES_SLPM, (SUPPLY, Location("DNC", "B")))
    return sig, len(q_in_features[0])


def test_supply_leak_signature_is_a_constant_flow_offset(signatures):
    # section 5.3.1.2: a supply leak adds about its flow to Q_In in every step
    sig, n = signatures
    q_mean = sig.deltas[0, 0, n : 2 * n]
    assert sig.sizes[0, 0] == pytest.approx(slpm_to_kg_s(30.0), rel=1e-6)
    assert np.median(q_mean) == pytest.approx(slpm_to_kg_s(30.0), rel=0.15)
    assert np.mean(q_mean > 0) > 0.9


def _true_mean_leak_flow(location, size_slpm, seed):
    """Leaked mass of one inner cycle / its duration, from the simulator's cumulative
    leaked mass (independent of the signatures' integration of the leak flow).

    Also returns the cycle's mean manifold pressure over the leak's nominal pressure.
    """
    sim = run_simulation("festo-dsd", cycles=3, leaks={location: f"{size_slpm}slpm"}, seed=seed)
    t0, t1 = sim.cycle_start[1], sim.cycle_start[2]
    m0, m1 = np.interp([t0, t1], sim.time, sim.outputs["mass_leaked"])
    inside = (sim.time >= t0) & (sim.time <= t1)
    pressure = np.trapezoid(sim.outputs["p_manifold"][inside], sim.time[inside]) / (t1 - t0)
    return (m1 - m0) / (t1 - t0), pressure / sim.leaks[0].nominal_pressure_pa


def test_supply_leak_loses_its_flow_all_cycle(signatures):
    sig, _ = signatures
    for k, slpm in enumerate(SIG_SIZES_SLPM):
        nominal = sig.sizes[0, k]
        assert sig.average_flow(0, nominal) == pytest.approx(sig.mean_flow[0, k], rel=1e-12)
        # another seed, integrated independently from the simulator's leak flow
        truth, pressure_ratio = _true_mean_leak_flow("supply", slpm, SEED + 10 + k)
        assert sig.mean_flow[0, k] == pytest.approx(truth, rel=0.02)
        # it blows all cycle, choked, from the manifold: its mean flow is the nominal
        # flow scaled by the mean manifold pressure, which the leak itself pulls a
        # little below the nominal supply pressure
        assert sig.mean_flow[0, k] == pytest.approx(nominal * pressure_ratio, rel=0.02)
        assert sig.mean_flow[0, k] <= nominal
    # a 30 SLPM supply leak loses within a few % of its nominal flow
    assert sig.mean_flow[0, 0] == pytest.approx(sig.sizes[0, 0], rel=0.06)


def test_rod_side_leak_loses_air_only_while_its_line_is_pressurised(signatures):
    # festo-dsd's DNC has a 5/3 closed-centre valve: a DNC_B leak blows while the rod
    # side is pressurised, then drains the isolated chamber and stops
    sig, _ = signatures
    k = SIG_SIZES_SLPM.index(55.0)
    nominal = sig.sizes[1, k]
    assert nominal == pytest.approx(slpm_to_kg_s(55.0), rel=1e-6)
    average = sig.average_flow(1, nominal)
    assert average < 0.2 * nominal
    truth, _ = _true_mean_leak_flow("DNC_B", 55.0, SEED + 20)
    assert average == pytest.approx(truth, rel=0.05)
    # a smaller leak drains its line more slowly: it loses a larger share of its flow
    assert sig.duty(1, sig.sizes[1, 0]) > sig.duty(1, nominal)


def test_rod_side_leak_next_to_a_supply_leak(signatures):
    # section 5.3.1.5's pair: the supply leak lowers the pressure the DNC_B leak blows
    # from; the mean flows with the bilinear interaction match the simulator's
    sig, _ = signatures
    line, supply = slpm_to_kg_s(55.0), slpm_to_kg_s(28.0)
    avg_line, avg_supply = sig.average_flows_with_supply(1, line, supply)
    sim = run_simulation(
        "festo-dsd", cycles=3, leaks={"DNC_B": "55slpm", "supply": "28slpm"}, seed=SEED + 30
    )
    t0, t1 = sim.cycle_start[1], sim.cycle_start[2]
    inside = (sim.time >= t0) & (sim.time <= t1)
    for loc, estimate in (("DNC_B", avg_line), ("supply", avg_supply)):
        lost = np.trapezoid(sim.outputs[f"mdot_leak_{loc}"][inside], sim.time[inside])
        assert estimate == pytest.approx(lost / (t1 - t0), rel=0.05)
    # alone, the DNC_B leak would lose more
    assert avg_line < sig.average_flow(1, line)


def test_signature_ladder_ends_below_the_stall_limit(q_in_features):
    # a ladder size the machine cannot run with (a DNC_B leak of 3000 SLPM keeps the
    # DNC from retracting) is replaced by the largest size found to run below it, and
    # later sizes are searched below the smallest that stalled: increasing knots
    # instead of an error (issue 10, drafted machines with weak valves)
    with pytest.raises(MachineStalledError):
        simulate("festo-dsd", cycles=1, leaks={"DNC_B": "3000slpm"}, seed=SEED, max_cycle_s=30.0)
    sig = _q_in_signatures(q_in_features, (30.0, 3000.0, 4000.0), (Location("DNC", "B"),))
    knots = sig.sizes[0]
    assert knots[0] == pytest.approx(slpm_to_kg_s(30.0), rel=1e-6)
    assert np.all(np.diff(knots) > 0.0)
    assert knots[-1] < slpm_to_kg_s(3000.0)
    # the effect grows with the leak all the way up
    assert np.all(np.diff(sig.mean_flow[0]) > 0.0)


def test_a_plausible_plant_that_cannot_run_leak_free_is_left_out():
    # Found by a calibrated campaign: a plausible plant drawn around a calibrated
    # description stalled without any leak, and the whole reference build stopped.
    # Such a plant says nothing about leak effects: it is left out (None), not an error.
    import copy

    from pneufdd.diagnosis.effects.twin import _plant_effects
    from pneufdd.features.step_summaries import machine_sequence

    machine = load_machine("press-fit-cell")
    raw = copy.deepcopy(machine.raw)
    raw["supply"]["regulator_set_psig"] = 10.0  # too weak to return the feed
    weak = load_machine(raw)
    with pytest.raises(MachineStalledError):
        simulate(weak, cycles=1, seed=SEED)
    sequence = tuple(machine_sequence(machine) or ())
    job = (weak, (SUPPLY,), (1.0,), 1, SEED, sequence, ("P_In", "Q_In"), np.arange(4))
    assert _plant_effects(job) is None
    job = (machine, (SUPPLY,), (1.0,), 1, SEED, sequence, ("P_In", "Q_In"), np.arange(4))
    effects = _plant_effects(job)
    assert effects is not None
    assert effects.shape == (1, 1, 4)
    assert np.all(np.isfinite(effects))


def test_a_ladder_that_stalls_just_above_a_size_that_ran_is_rescaled(monkeypatch):
    # a machine that runs with a 100 SLPM supply leak and stalls at anything above
    # 100.05 SLPM: the search below 150 SLPM never finds a size that runs (a drafted
    # festo-dsd handling axis, seeds 430M, stalled at 122 SLPM after running at 120).
    # The twin cannot be made to stall that sharply on demand, so its feature
    # function stands in for it here; the ladder is then scaled to end at 100 SLPM
    import pneufdd.diagnosis.effects.twin as twin_effects

    def features(machine, leaks, cycles, seed, sequence, channels, leak_flows=True):
        (slpm,) = leaks.values()
        if slpm > 100.05:
            raise MachineStalledError(f"stalls at {slpm} SLPM")
        flow = slpm_to_kg_s(slpm)
        truth = [{"mass_flow_kg_s": flow, "at_pressure_pa": 7e5}]
        return np.array([slpm, -2.0 * slpm]), truth, ("f1", "f2"), {SUPPLY: 0.9 * flow}

    monkeypatch.setattr(twin_effects, "_mean_features", features)
    job = (load_machine("festo-dsd"), SUPPLY, (30.0, 100.0, 150.0), 1, 0, (), ())
    sizes, means, pressure, _, leaked, _ = twin_effects._location_ladder(job)
    assert sizes == pytest.approx(slpm_to_kg_s(np.array([20.0, 200.0 / 3.0, 100.0])))
    assert means[:, 0] == pytest.approx([20.0, 200.0 / 3.0, 100.0])
    assert leaked == pytest.approx(0.9 * sizes)
    assert pressure == 7e5

    def never(machine, leaks, cycles, seed, sequence, channels, leak_flows=True):
        raise MachineStalledError("stalls at any size")

    monkeypatch.setattr(twin_effects, "_mean_features", never)
    with pytest.raises(InputError, match=r"leak signature of machine .festo-dsd. at supply"):
        twin_effects._location_ladder(job)


def test_the_check_subtracts_the_signatures_own_leak_free_run(signatures, q_in_features):
    # the signatures keep their leak-free run; a check of the same cycles and seed takes
    # it instead of simulating it again, and gets exactly the changes it would compute
    sig, _ = signatures
    seq, names = q_in_features
    assert sig.baseline is not None
    assert sig.baseline_run == (1, SIGNATURE_SEED)
    machine = load_machine("festo-dsd")
    kept = LeakEffectModel.from_description(sig, machine, seq, ["Q_In"], cycles=1).simulator
    again = TwinLeakEffect(machine, names, seq, ["Q_In"], cycles=1)
    assert kept is not None
    leaks = {SUPPLY: float(slpm_to_kg_s(40.0)), Location("DNC", "B"): float(slpm_to_kg_s(20.0))}
    assert np.array_equal(kept(leaks), again(leaks))
    assert (kept.simulations, again.simulations) == (1, 2)
    # another number of cycles is another run: simulated, not taken
    other = LeakEffectModel.from_description(sig, machine, seq, ["Q_In"], cycles=2).simulator
    assert other is not None
    assert other(leaks) is not None
    assert other.simulations == 2
