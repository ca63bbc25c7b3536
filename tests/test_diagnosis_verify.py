"""Explanations checked and sized by simulation when the signature model misfits."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.effects.twin import TwinLeakEffect
from pneufdd.diagnosis.localisation.check import (
    SimulationCheckSettings,
    refine_all,
    refine_by_simulation,
    verify_explanations,
)
from pneufdd.diagnosis.localisation.search import LocalisationSettings, locate
from pneufdd.errors import InputError
from pneufdd.features.step_summaries import build_step_table, machine_sequence, segment_cycles
from pneufdd.location import SUPPLY, Location
from pneufdd.physics.units import slpm_to_kg_s
from pneufdd.sim import load_machine, simulate

# --------------------------------------------------------------------------- synthetic


def _saturating(size: float, scale: float) -> float:
    """Effect that saturates with size, like a line pressure falling to atmosphere."""
    return scale * (1.0 - math.exp(-size / scale))


def _pair_simulator(base: np.ndarray, inter: np.ndarray):
    """'Simulator' of leaks at locations 0..n: saturating effects plus an interaction."""

    def sim(leaks):
        out = np.zeros(base.shape[1])
        for loc, size in leaks.items():
            out = out + _saturating(size, 3.0) * base[loc]
        if len(leaks) == 2:
            a, b = leaks.values()
            out = out + a * b * inter
        return out

    return sim


def _assert_same_fits(threaded, serial):
    """The same explanations in the same order, with the same sizes and residuals."""
    assert list(threaded) == list(serial)
    for sub, fit in serial.items():
        assert np.array_equal(threaded[sub].sizes, fit.sizes)
        assert threaded[sub].rss == fit.rss


@given(st.floats(0.3, 4.0), st.floats(0.3, 4.0), st.floats(0.4, 2.5))
def test_refine_recovers_sizes_of_a_nonlinear_interacting_pair(a, b, start_factor):
    rng = np.random.default_rng(3)
    base = np.abs(rng.normal(size=(2, 30)))
    sim = _pair_simulator(base, 0.2 * rng.normal(size=30))
    target = sim({0: a, 1: b})
    fit = refine_by_simulation(
        (0, 1),
        start_factor * np.array([a, b]),
        target,
        sim,
        np.array([10.0, 10.0]),
        max_iterations=30,
        tolerance=1e-9,
    )
    assert fit is not None
    assert fit.sizes == pytest.approx([a, b], rel=1e-3)
    assert fit.rss < 1e-6 * float(target @ target)


def test_refine_keeps_sizes_within_bounds():
    base = np.eye(3)[:2]
    sim = _pair_simulator(base, np.zeros(3))
    target = sim({0: 5.0, 1: 1.0})
    fit = refine_by_simulation((0, 1), np.array([1.0, 1.0]), target, sim, np.array([2.0, 9.0]))
    assert fit is not None
    assert fit.sizes[0] == pytest.approx(2.0)  # capped, never beyond
    assert fit.sizes[1] == pytest.approx(1.0, rel=1e-3)


def test_refine_gives_none_when_the_machine_never_runs():
    calls = []

    def stalls(leaks):
        calls.append(dict(leaks))
        return None

    assert refine_by_simulation((0,), np.array([1.0]), np.ones(3), stalls, np.array([5.0])) is None
    # tried at the start and twice smaller, then gives up
    assert [c[0] for c in calls] == pytest.approx([1.0, 0.7, 0.49])


def _additive_model_misses_an_interaction():
    """Leaks 0 and 2 interact in a direction no signature has: (base, simulator, the
    target of leaks 0: 3 and 2: 1, the additive model's fits of every subset)."""
    rng = np.random.default_rng(5)
    base = np.abs(rng.normal(size=(4, 40)))
    inter = rng.normal(size=40)

    def sim(leaks):
        out = sum(size * base[loc] for loc, size in leaks.items())
        if 0 in leaks and 2 in leaks:
            out = out + leaks[0] * leaks[2] * inter
        return np.asarray(out, dtype=np.float64)

    target = sim({0: 3.0, 2: 1.0})
    fits = {}
    for sub in [(0,), (1,), (2,), (3,), (0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]:
        sizes = np.clip(np.linalg.lstsq(base[list(sub)].T, target, rcond=None)[0], 0.0, None)
        r = target - base[list(sub)].T @ sizes
        fits[sub] = (sizes, float(r @ r))
    return base, sim, target, fits


def test_probed_second_leak_found_where_the_additive_model_fails():
    # the additive model cannot explain the pair; probing next to the first leak sees
    # the interaction
    _, sim, target, fits = _additive_model_misses_an_interaction()
    settings = SimulationCheckSettings(top_pairs=0, probe_size=1.0)
    out = verify_explanations(target, fits, 4, sim, np.full(4, 10.0), settings)
    best = min(out, key=lambda s: out[s].rss)
    assert best == (0, 2)
    assert out[best].sizes == pytest.approx([3.0, 1.0], rel=0.01)


def test_threads_size_every_explanation_as_one_thread_does():
    # the same explanations, sizes and residuals, in the same order, whatever the
    # number of threads: each is sized from the same start on its own
    rng = np.random.default_rng(11)
    base = np.abs(rng.normal(size=(6, 30)))
    sim = _pair_simulator(base, rng.normal(size=30))
    target = sim({1: 2.5, 4: 1.2})
    fits = {}
    for sub in [(i,) for i in range(6)] + [(i, j) for i in range(6) for j in range(i + 1, 6)]:
        sizes = np.clip(np.linalg.lstsq(base[list(sub)].T, target, rcond=None)[0], 0.0, None)
        r = target - base[list(sub)].T @ sizes
        fits[sub] = (sizes, float(r @ r))
    upper = np.full(6, 10.0)
    settings = SimulationCheckSettings(probe_size=1.0)
    serial = verify_explanations(target, fits, 6, sim, upper, settings)
    threaded = verify_explanations(target, fits, 6, sim, upper, settings, threads=3)
    assert len(serial) >= 5  # singles, partners and pairs were sized
    _assert_same_fits(threaded, serial)


def test_start_and_difference_steps_in_one_call_size_as_one_at_a_time():
    rng = np.random.default_rng(4)
    base = np.abs(rng.normal(size=(2, 20)))
    sim = _pair_simulator(base, 0.3 * rng.normal(size=20))
    target = sim({0: 1.7, 1: 0.6})
    batches = []

    def many(calls):
        batches.append(len(calls))
        return [sim(c) for c in calls]

    start, upper = np.array([1.0, 1.0]), np.array([9.0, 9.0])
    one = refine_by_simulation((0, 1), start, target, sim, upper)
    both = refine_by_simulation((0, 1), start, target, sim, upper, simulate_many=many)
    assert batches == [3]  # the start and one difference step per leak
    assert one is not None
    assert both is not None
    assert np.array_equal(both.sizes, one.sizes)
    assert both.rss == one.rss
    assert np.array_equal(both.jacobian, one.jacobian)


def test_a_stalled_start_is_shrunk_alike_with_steps_in_one_call():
    rng = np.random.default_rng(6)
    base = np.abs(rng.normal(size=(2, 20)))
    plain = _pair_simulator(base, 0.3 * rng.normal(size=20))

    def sim(leaks):  # the machine stalls when both leaks together exceed 3
        return None if sum(leaks.values()) > 3.0 else plain(leaks)

    target = plain({0: 1.2, 1: 0.8})
    batches = []

    def many(calls):
        batches.append([round(sum(c.values()), 6) for c in calls])
        return [sim(c) for c in calls]

    start, upper = np.array([2.0, 2.0]), np.array([9.0, 9.0])
    one = refine_by_simulation((0, 1), start, target, sim, upper)
    both = refine_by_simulation((0, 1), start, target, sim, upper, simulate_many=many)
    # 4.0 stalls, 2.8 runs: the start and its difference steps at each size tried
    assert [b[0] for b in batches] == [4.0, 2.8]
    assert one is not None
    assert both is not None
    assert np.array_equal(both.sizes, one.sizes)
    assert both.rss == one.rss


def test_no_more_simulations_run_at_once_than_threads():
    running, peak, lock = [0], [0], threading.Lock()
    rng = np.random.default_rng(2)
    base = np.abs(rng.normal(size=(5, 12)))
    plain = _pair_simulator(base, np.zeros(12))

    def sim(leaks):
        with lock:
            running[0] += 1
            peak[0] = max(peak[0], running[0])
        time.sleep(0.002)
        with lock:
            running[0] -= 1
        return plain(leaks)

    target = plain({1: 1.0, 3: 2.0})
    starts = {(i, j): np.array([1.0, 1.0]) for i in range(5) for j in range(i + 1, 5)}
    upper = np.full(5, 9.0)
    threaded = refine_all(starts, target, sim, upper, threads=2)
    serial = refine_all(starts, target, plain, upper, threads=1)
    assert peak[0] == 2
    assert list(threaded) == list(serial)
    for sub, fit in serial.items():
        assert np.array_equal(threaded[sub].sizes, fit.sizes)


def test_simulation_threads_must_be_a_positive_integer():
    sig = _synthetic_signatures(np.ones((2, 3)))
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="simulation threads"):
            LeakEffectModel(sig, threads=bad)  # type: ignore[arg-type]


def _synthetic_signatures(base: np.ndarray) -> SignatureSet:
    sizes = np.array([[0.5, 1.0, 2.0, 4.0, 8.0]] * base.shape[0])
    deltas = np.array([[_saturating(s, 3.0) * row for s in sizes[0]] for row in base])
    return SignatureSet(
        tuple(f"L{i}_A" for i in range(base.shape[0])),
        sizes,
        deltas,
        tuple(f"f{j}" for j in range(base.shape[1])),
        np.full(base.shape[0], 6e5),
    )


def _whiten(delta):
    return np.atleast_2d(delta) * 100.0


def _logged_effects(sig, sim):
    """Leak effects of ``sig`` simulated by ``sim`` (keyed by location index), and the
    list of the leaks it ran."""
    calls = []

    def simulator(leaks):
        by_index = {sig.locations.index(loc): size for loc, size in leaks.items()}
        calls.append(by_index)
        return sim(by_index)

    return calls, LeakEffectModel(sig, simulator)


def _found(result):
    return {str(leak.location): leak.mass_flow for leak in result.leaks}


def test_locate_simulates_only_when_the_signatures_misfit():
    rng = np.random.default_rng(8)
    base = np.abs(rng.normal(size=(5, 60)))
    sig = _synthetic_signatures(base)
    inter = 0.3 * rng.normal(size=60)  # a direction no single leak has
    sim = _pair_simulator(base, inter)
    calls, effects = _logged_effects(sig, sim)

    # one leak: the signatures explain it; nothing is simulated
    single = locate(sim({2: 1.7}), effects, _whiten)
    assert not calls
    assert not single.checked_by_simulation
    (leak,) = single.leaks
    assert leak.location == Location("L2", "A")
    assert leak.mass_flow == pytest.approx(1.7, rel=0.03)  # interpolated between 1 and 2
    # two interacting leaks: the signature model misfits; simulation finds them
    truth = sim({1: 2.5, 4: 1.2})
    plain = locate(truth, LeakEffectModel(sig), _whiten)
    assert plain.rss > 3.0 * plain.dof
    result = locate(truth, effects, _whiten)
    assert calls
    assert result.checked_by_simulation
    assert _found(result) == pytest.approx({"L1_A": 2.5, "L4_A": 1.2}, rel=0.01)
    assert result.rss < 1e-3 * plain.rss


# --------------------------------------------------------------------------- festo-dsd


@pytest.mark.slow
def test_two_large_leaks_on_festo_dsd_sized_by_simulation():
    """A 153 SLPM supply leak and a 71 SLPM gripper leak (5 and 3 turns).

    Their effects are far from additive: the supply leak draws the manifold down and
    the gripper line fills from it. The simulated leak effect, whitened like the
    diagnosis does, recovers both; the check asserts the simulated fit of the truth
    beats the signature model's best (noise-free: the observation is itself a
    simulation with another seed).
    """
    truth = {"supply": 5.0, "HGD2_A": 3.0}
    rec = simulate("festo-dsd", cycles=4, leaks=truth, seed=7_100_001)
    base = simulate("festo-dsd", cycles=4, seed=7_100_001)
    machine = load_machine("festo-dsd")
    sequence = machine_sequence(machine)
    assert sequence is not None
    channels = ("P_In", "Q_In")

    def mean_features(recording):
        cycles, _, _ = segment_cycles(recording, sequence, "test run")
        return build_step_table(recording, cycles, "festo-dsd", channels).features().mean(axis=0)

    observed = mean_features(rec) - mean_features(base)
    table = build_step_table(base, segment_cycles(base, sequence, "t")[0], "festo-dsd", channels)
    effect = TwinLeakEffect(machine, table.feature_names(), sequence, channels)
    flows = {leak["location"]: leak["mass_flow_kg_s"] for leak in rec.metadata["leaks"]}
    assert flows["supply"] == pytest.approx(float(slpm_to_kg_s(152.6)), rel=0.01)
    # whitening: durations by 3 ms, pressures by 500 Pa, flows by 1 SLPM
    scale = np.array(
        [
            3e-3 if n.startswith("duration") else 500.0 if n.startswith("P_") else 2.2e-5
            for n in table.feature_names()
        ]
    )

    def whiten(delta):
        return np.atleast_2d(delta) / scale

    y = whiten(observed)[0]
    names = [SUPPLY, Location("HGD2", "A")]

    def sim(leaks):
        change = effect({names[i]: size for i, size in leaks.items()})
        return None if change is None else whiten(change)[0]

    start = np.array([flows["supply"] * 1.1, flows["HGD2_A"] * 0.1])
    fit = refine_by_simulation((0, 1), start, y, sim, np.full(2, 8e-3))
    assert fit is not None
    assert fit.sizes == pytest.approx([flows["supply"], flows["HGD2_A"]], rel=0.1)
    single = refine_by_simulation((0,), start[:1], y, sim, np.full(1, 8e-3))
    assert single is not None
    assert fit.rss < 0.2 * single.rss
    assert effect.simulations < 20


@pytest.mark.slow
def test_diagnose_checks_two_large_leaks_by_simulation_end_to_end():
    """The engine on festo-dsd (supply-only sensors, signatures at four locations).

    5 turns on the supply and 3 on the gripper's extend line (153 + 71 SLPM): the
    signature fit misfits, the engine simulates the best explanations and reports
    both leaks within 10 % of the truth, and says so.
    """
    from pneufdd.diagnosis.effects.twin import compute_signatures
    from pneufdd.diagnosis.engine import diagnose
    from pneufdd.diagnosis.recordings import build_reference_from_recordings, run_table
    from pneufdd.features.step_summaries import sequence_from_records

    leak_free = simulate("festo-dsd", cycles=14, seed=7_200_001)
    model = build_reference_from_recordings(
        [leak_free], channels=("P_In", "Q_In"), with_signatures=False
    )
    signatures = compute_signatures(
        load_machine("festo-dsd"),
        model.feature_names,
        sequence_from_records(model.sequence),
        channels=model.channels,
        sizes_slpm=(15.0, 50.0, 120.0, 230.0),
        workers=1,
        locations=tuple(Location.parse(x) for x in ("supply", "DNC_B", "HGD2_A", "HGD2_B")),
    )
    model = model.with_signatures(signatures)
    run = simulate("festo-dsd", cycles=8, leaks={"supply": 5.0, "HGD2_A": 3.0}, seed=7_200_002)
    truth = {leak["location"]: leak["mass_flow_kg_s"] for leak in run.metadata["leaks"]}
    table = run_table(model, run)
    result = diagnose(model, table, threads=1)
    # two threads check the same explanations: the same diagnosis
    assert diagnose(model, table, threads=2).to_dict() == result.to_dict()
    with pytest.raises(InputError, match="threads"):
        diagnose(model, table, threads=0)
    assert result.detected
    assert result.localisation is not None
    assert result.localisation.checked_by_simulation
    assert any("digital twin" in note for note in result.notes)
    assert _found(result) == pytest.approx(truth, rel=0.1)
    plain = diagnose(model, table, localisation=LocalisationSettings(simulate_explanations=False))
    assert plain.localisation is not None
    assert not plain.localisation.checked_by_simulation
    assert result.localisation.rss < plain.localisation.rss


def test_one_leak_at_most_simulates_no_pairs():
    rng = np.random.default_rng(9)
    base = np.abs(rng.normal(size=(4, 50)))
    sig = _synthetic_signatures(base)
    sim = _pair_simulator(base, 0.3 * rng.normal(size=50))
    calls, effects = _logged_effects(sig, sim)

    result = locate(sim({0: 2.0, 3: 1.5}), effects, _whiten, LocalisationSettings(max_leaks=1))
    assert len(result.leaks) == 1
    assert calls  # the single-leak fit misfits: simulated
    assert all(len(c) == 1 for c in calls)  # only single leaks were simulated


# ------------------------------------------------------------ fewer simulations


def _counting(sim):
    runs = []

    def counted(leaks):
        runs.append(tuple(sorted(leaks)))
        return sim(leaks)

    return counted, runs


def _every_pair(seed, n_loc, n_features, truth, start):
    """A pair simulator, the target of ``truth``, every pair's ``start`` and the cap."""
    rng = np.random.default_rng(seed)
    base = np.abs(rng.normal(size=(n_loc, n_features)))
    plain = _pair_simulator(base, 0.25 * rng.normal(size=n_features))
    starts = {(i, j): np.array(start) for i in range(n_loc) for j in range(i + 1, n_loc)}
    return plain, plain(truth), starts, np.full(n_loc, 9.0)


def test_hopeless_explanations_stop_and_the_best_is_sized_as_without_stopping():
    plain, target, starts, upper = _every_pair(21, 6, 30, {1: 2.5, 4: 1.2}, [1.0, 1.0])
    sim_all, runs_all = _counting(plain)
    sim_kept, runs_kept = _counting(plain)
    every = refine_all(starts, target, sim_all, upper, max_iterations=3)
    kept = refine_all(starts, target, sim_kept, upper, max_iterations=3, keep_within=4.0)
    leader = min(every, key=lambda s: every[s].rss)
    assert leader == (1, 4)
    assert min(kept, key=lambda s: kept[s].rss) == leader
    # the leader took the same steps, so it has the same sizes and residual
    assert np.array_equal(kept[leader].sizes, every[leader].sizes)
    assert kept[leader].rss == every[leader].rss
    assert runs_kept.count(leader) == runs_all.count(leader)
    # every explanation still has a fit; the stopped ones no better than their own
    # fit without stopping, and all far from the leader
    assert list(kept) == list(every)
    for sub, fit in kept.items():
        assert fit.rss >= every[sub].rss
        if fit.rss != every[sub].rss:
            assert every[sub].rss > 2.0 * every[leader].rss
    assert len(runs_kept) < 0.7 * len(runs_all)


def test_stopping_does_not_depend_on_threads():
    plain, target, starts, upper = _every_pair(22, 5, 20, {0: 1.5, 3: 2.0}, [1.0, 1.5])
    serial = refine_all(starts, target, plain, upper, keep_within=3.0)
    threaded = refine_all(starts, target, plain, upper, threads=3, keep_within=3.0)
    _assert_same_fits(threaded, serial)


def test_a_leader_sized_before_stops_a_hopeless_batch_after_its_first_round():
    rng = np.random.default_rng(23)
    base = np.abs(rng.normal(size=(3, 20)))
    plain = _pair_simulator(base, np.zeros(20))
    target = plain({0: 2.0})
    sim, runs = _counting(plain)
    out = refine_all(
        {(1,): np.array([1.0]), (2,): np.array([1.0])},
        target,
        sim,
        np.full(3, 9.0),
        keep_within=4.0,
        leader=1e-9,
    )
    assert set(out) == {(1,), (2,)}
    assert len(runs) == 4  # each: its start and one difference step, nothing more


def test_starts_judged_by_slopes_skip_hopeless_difference_steps_and_find_the_pair():
    # the additive "signature model" misses the interaction of leaks 0 and 2; its
    # slopes judge each start, and only explanations still in the running have their
    # difference steps simulated
    base, plain, target, fits = _additive_model_misses_an_interaction()

    def slopes(sub, sizes):
        return base[list(sub)].T

    upper = np.full(4, 10.0)
    found, sized = {}, {}
    for judged in (False, True):
        sim, runs = _counting(plain)
        out = verify_explanations(
            target,
            fits,
            4,
            sim,
            upper,
            SimulationCheckSettings(probe_size=1.0, keep_within=4.0),
            slopes=slopes if judged else None,
        )
        best = min(out, key=lambda s: out[s].rss)
        assert best == (0, 2)
        assert out[best].sizes == pytest.approx([3.0, 1.0], rel=0.01)
        found[judged], sized[judged] = len(runs), out[best]
    assert found[True] < found[False]
    # the best explanation took the same steps either way
    assert np.array_equal(sized[True].sizes, sized[False].sizes)
    assert sized[True].rss == sized[False].rss


def test_keep_within_between_zero_and_one_is_refused():
    with pytest.raises(InputError, match="keep_within"):
        LocalisationSettings(keep_within=0.5)
    assert LocalisationSettings(keep_within=0.0).keep_within == 0.0


def test_references_saved_before_size_every_explanation_to_the_end():
    old = LocalisationSettings.from_dict({"max_leaks": 2})
    assert old.keep_within == 0.0
    new = LocalisationSettings()
    assert LocalisationSettings.from_dict(new.to_dict()) == new


@pytest.mark.parametrize(
    "bad",
    [
        {"top_singles": -1},
        {"partners": 1.5},
        {"probed_locations": True},
        {"max_iterations": -2},
        {"probe_size": 0.0},
        {"probe_size": math.nan},
        {"min_pair_flow": -1e-5},
        {"keep_within": 0.5},
        {"keep_within": math.nan},
    ],
)
def test_check_settings_refuse_what_cannot_be_checked(bad):
    (name,) = bad
    with pytest.raises(InputError, match=f"check setting {name}"):
        SimulationCheckSettings(**bad)
