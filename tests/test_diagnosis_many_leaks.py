"""Many leaks at once (issue 38): the set search, the remainder, totals and repair order."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

from pneufdd.diagnosis.cost import CostSettings, leak_totals, repair_cost, repair_order
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects, box_least_squares
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.findings import LeakFinding
from pneufdd.diagnosis.localisation.model_choice import choose_leak_count
from pneufdd.diagnosis.localisation.remainder import hidden_leak_bounds, size_spread
from pneufdd.diagnosis.localisation.search import LocalisationSettings, locate
from pneufdd.location import SUPPLY, Location

N_LOC = 10
N_FEAT = 120


def _linear_set(matrix: np.ndarray) -> SignatureSet:
    n_loc, n_feat = matrix.shape
    return SignatureSet(
        tuple(f"L{i}_A" for i in range(n_loc)),
        np.full((n_loc, 1), 10.0),
        10.0 * matrix[:, None, :],
        tuple(f"f{j}" for j in range(n_feat)),
        np.full(n_loc, 6e5),
    )


def _white(delta):
    return np.atleast_2d(delta) * 20.0


@pytest.fixture(scope="module")
def matrix() -> np.ndarray:
    # distinct, non-negative effects: each location moves its own block of features
    rng = np.random.default_rng(380)
    out = 0.2 * np.abs(rng.normal(size=(N_LOC, N_FEAT)))
    for i in range(N_LOC):
        out[i, 12 * i : 12 * i + 12] += 1.0
    return out


@given(
    st.lists(st.integers(0, N_LOC - 1), min_size=3, max_size=6, unique=True),
    st.lists(st.floats(0.5, 5.0), min_size=6, max_size=6),
)
@settings(max_examples=25, deadline=None)
def test_any_number_of_leaks_is_recovered_with_sizes(matrix, where, sizes):
    truth = dict(zip(where, sizes, strict=False))
    observed = sum(size * matrix[loc] for loc, size in truth.items())
    result = locate(observed, LeakEffectModel(_linear_set(matrix)), _white)
    found = {int(str(leak.location)[1:-2]): leak.mass_flow for leak in result.leaks}
    assert found.keys() == truth.keys()
    for loc, size in truth.items():
        assert found[loc] == pytest.approx(size, rel=1e-4)
    assert result.explained == pytest.approx(1.0, abs=1e-6)
    assert result.remainder is not None
    assert not result.remainder.more_leaks_possible


def test_max_leaks_limits_the_explanation_and_says_so(matrix):
    observed = 2.0 * matrix[1] + 3.0 * matrix[4] + 1.5 * matrix[7]
    model = LeakEffectModel(_linear_set(matrix))
    limited = locate(observed, model, _white, LocalisationSettings(max_leaks=2))
    assert len(limited.leaks) == 2
    remainder = limited.remainder
    assert remainder is not None
    assert remainder.more_leaks_possible
    assert "limit of 2" in remainder.reasons[0]
    # the third leak's location can hide at least its size
    bound = {str(h.location): h.mass_flow for h in remainder.hidden}
    assert bound["L7_A"] >= 1.5
    assert remainder.complete_confidence < 1e-6


def test_the_set_fit_matches_a_bounded_least_squares_oracle():
    # piecewise-linear effects of three leaks: the set fit from a start inside the
    # right segments is the oracle's best over those segment combinations
    rng = np.random.default_rng(381)
    n_loc, n_sizes, n_feat = 3, 3, 30
    sizes = np.cumsum(rng.uniform(0.5, 1.5, size=(n_loc, n_sizes)), axis=1)
    deltas = np.cumsum(np.abs(rng.normal(size=(n_loc, n_sizes, n_feat))), axis=1)
    model = WhitenedEffects(sizes, deltas, lambda d: np.atleast_2d(d), np.zeros(n_feat))
    truth = np.array([0.7 * sizes[0, 1], 1.2 * sizes[1, 0], 0.5 * (sizes[2, 1] + sizes[2, 2])])
    target = sum(model(i, truth[i]) for i in range(3)) + 0.01 * rng.normal(size=n_feat)
    model.target = target
    got, rss = model.fit_set((0, 1, 2), truth * 1.1)
    knots = np.concatenate([np.zeros((n_loc, 1)), sizes], axis=1)
    best = np.inf
    for segs in itertools.product(range(n_sizes), repeat=3):
        lo = np.array([knots[i, k] for i, k in enumerate(segs)])
        hi = np.array([knots[i, k + 1] if k < n_sizes - 1 else np.inf for i, k in enumerate(segs)])
        A = np.column_stack([model.slope[i, k] for i, k in enumerate(segs)])
        rhs = target - sum(model.intercept[i, k] for i, k in enumerate(segs))
        res = lsq_linear(A, rhs, bounds=(lo, hi))
        best = min(best, float(np.sum((A @ res.x - rhs) ** 2)))
    assert rss == pytest.approx(best, rel=1e-6, abs=1e-9)
    assert got == pytest.approx(truth, rel=0.05)


def test_box_least_squares_matches_scipy():
    rng = np.random.default_rng(382)
    for _ in range(300):
        k = int(rng.integers(1, 7))
        A = rng.normal(size=(int(rng.integers(k, 30)), k))
        if k > 2:
            A[:, 1] = A[:, 2] + 1e-7 * rng.normal(size=A.shape[0])  # near-collinear
        b = 3.0 * rng.normal(size=A.shape[0])
        lo = rng.uniform(-1.0, 0.5, size=k)
        hi = lo + rng.uniform(0.0, 2.0, size=k)
        x = box_least_squares(A, b, lo, hi, rng.uniform(lo, hi))
        y = lsq_linear(A, b, bounds=(lo, hi + 1e-15), method="bvls").x
        assert np.all(x >= lo - 1e-12)
        assert np.all(x <= hi + 1e-12)
        assert np.sum((A @ x - b) ** 2) <= np.sum((A @ y - b) ** 2) * (1 + 1e-9) + 1e-12


def test_forward_selection_stops_at_the_first_leak_not_taken():
    best = {
        0: ((), np.zeros(0), 1000.0),
        1: ((0,), np.ones(1), 600.0),
        2: ((0, 1), np.ones(2), 300.0),
        3: ((0, 1, 2), np.ones(3), 280.0),  # 7 %: not taken
        4: ((0, 1, 2, 3), np.ones(4), 10.0),  # never reached: three was not taken
    }
    assert choose_leak_count(best, 200, 6, 0.25) == 2


def test_hidden_leak_bounds_cover_a_leak_below_noise_95_percent_of_the_time():
    # a linear model, white noise, a true leak at location 0 too small to be chosen:
    # the one-sided 95 % bound holds it at least about 95 % of the time
    rng = np.random.default_rng(383)
    direction = np.zeros((2, 1, 40))
    direction[0, 0, :20] = 1.0
    direction[1, 0, 20:] = 1.0
    sizes = np.array([[1.0], [1.0]])
    covered = 0
    trials = 400
    for _ in range(trials):
        target = 0.3 * direction[0, 0] + rng.normal(size=40)
        model = WhitenedEffects(sizes, direction, lambda d: np.atleast_2d(d), target)
        bounds, _ = hidden_leak_bounds(model, target, None, (), 1.0)
        covered += int(bounds[0] >= 0.3)
    assert covered / trials >= 0.93


def test_size_spread_gives_the_sum_of_collinear_leaks_a_small_variance():
    J = np.array([[1.0, 1.0 + 1e-9], [2.0, 2.0], [0.5, 0.5]])
    F = size_spread(J, 1.0)
    each = np.sum(F**2, axis=1)
    total = float(np.sum((F.T @ np.ones(2)) ** 2))
    assert np.all(each > 1e6)  # the split between them is undetermined
    assert total == pytest.approx(1.0 / float(np.sum(J[:, 0] ** 2)), rel=1e-6)


def test_totals_interval_and_repair_order():
    settings = CostSettings()
    # the supply's fitting pays back sooner than the rod seal's expected repair
    supply = LeakFinding(SUPPLY, 1e-3, 1e-3, 1e-3, 500.0, 0.9, (SUPPLY,), "", repair_cost=40.0)
    rod = Location("DNC", "B")
    seal = LeakFinding(rod, 2e-3, 2e-3, 2e-3, 800.0, 0.9, (rod,), "", repair_cost=145.0)
    assert repair_order([seal, supply]) == (1, 0)
    assert repair_cost(rod, "linear", settings) == (
        145.0,
        "actuator seal, or its line's fitting or tube",
    )
    assert repair_cost(rod, "rotary", settings)[0] == 40.0
    assert repair_cost(Location("DGPL", "A"), "rodless", settings)[0] == 145.0

    # two leaks known to 0.5 g/s each, their sum to 0.1 g/s: the total's interval is
    # the sum's, and the cost interval follows eq. 1.1 linearly
    def variance(w):
        return 1e-8 if w[0] == w[1] else 0.25e-6 * sum(x * x for x in w)

    totals = leak_totals([1e-3, 2e-3], [1e-3, 1e-3], [1.0, 1.0], variance, settings)
    low, high = totals.mass_flow_interval
    assert (high - low) / 2 == pytest.approx(1.959964 * 1e-4, rel=1e-5)
    c_low, c_high = totals.annual_cost_interval
    assert c_low < totals.annual_cost < c_high
    assert (c_high - totals.annual_cost) / totals.annual_cost == pytest.approx(
        (totals.average_mass_flow_interval[1] - 2e-3) / 2e-3, rel=1e-9
    )


def _plants_reading_gains(matrix: np.ndarray, gains: np.ndarray) -> SignatureSet:
    """Linear signatures whose plausible plant ``k`` moves location ``l``'s features by
    ``1 + gains[k, l]`` times the signature (its deviation: ``gains[k, l]`` times it)."""
    base = _linear_set(matrix)
    deviations = gains[:, :, None, None] * base.deltas[None, :, :, :]
    return base.with_plant_deviations(deviations, base.sizes[0].copy())


def test_the_totals_variance_carries_the_plants_model_error(matrix):
    # three leaks, no noise in the observation: the fit's part is the linear
    # least-squares variance at unit residual scale; each plant reads leak l as
    # (1 + g_kl) a_l, so the model error's part is the mean square of sum_l g_kl a_l
    gains = np.random.default_rng(381).normal(0.0, 0.1, size=(12, N_LOC))
    truth = {1: 2.0, 4: 3.0, 7: 1.5}
    observed = sum(size * matrix[loc] for loc, size in truth.items())
    result = locate(observed, LeakEffectModel(_plants_reading_gains(matrix, gains)), _white)
    order = [int(str(leak.location)[1:-2]) for leak in result.leaks]
    assert sorted(order) == sorted(truth)
    J = 20.0 * matrix[order].T  # whitened Jacobian, columns in the leaks' order
    fit = float(np.sum(np.linalg.inv(J.T @ J)))
    sizes = np.array([truth[i] for i in order])
    model = float(np.mean((gains[:, order] @ sizes) ** 2))
    assert result.flow_variance(np.ones(3)) == pytest.approx(fit + model, rel=1e-6)
    # without plausible plants, the fit's part alone
    alone = locate(observed, LeakEffectModel(_linear_set(matrix)), _white)
    assert alone.flow_variance(np.ones(3)) == pytest.approx(fit, rel=1e-6)


def test_the_totals_interval_covers_a_plant_drawn_like_the_plausible_ones(matrix):
    # plants whose gains come from the plausible plants' distribution, noise on the
    # observation: the 95 % interval of the total covers the true total at about its
    # nominal rate with the model error, far less often without it
    rng = np.random.default_rng(382)
    signatures = _plants_reading_gains(matrix, rng.normal(0.0, 0.1, size=(40, N_LOC)))
    effects = LeakEffectModel(signatures)
    plain = LeakEffectModel(_linear_set(matrix))
    truth = {2: 2.0, 5: 3.0, 8: 1.5}
    covered = plainly = 0
    runs = 60
    for _ in range(runs):
        gain = rng.normal(0.0, 0.1, size=N_LOC)
        observed = sum((1.0 + gain[loc]) * size * matrix[loc] for loc, size in truth.items())
        observed = observed + rng.normal(0.0, 1.0 / 20.0, size=N_FEAT)
        result = locate(observed, effects, _white)
        assert len(result.leaks) == 3
        error = abs(sum(leak.mass_flow for leak in result.leaks) - 6.5)
        covered += error <= 1.959964 * np.sqrt(result.flow_variance(np.ones(3)))
        plain_half = 1.959964 * np.sqrt(locate(observed, plain, _white).flow_variance(np.ones(3)))
        plainly += error <= plain_half
    assert 0.85 * runs <= covered <= runs
    assert plainly <= 0.5 * runs


def test_a_supply_leak_is_tried_as_the_lines_of_the_third_best_actuator():
    # leaks on both lines of actuator C act together like a supply leak (an interaction
    # no signature holds); the additive signatures rank actuators A and B's lines
    # closer to the supply's effect, C's third: the swap finds C_A + C_B only because
    # three actuators are tried
    from pneufdd.diagnosis.localisation.check import SimulationCheckSettings, refine_all
    from pneufdd.diagnosis.localisation.simulated import supply_swaps

    names = ("supply", "A_A", "A_B", "B_A", "B_B", "C_A", "C_B", "D_A")
    rng = np.random.default_rng(383)
    supply = np.abs(rng.normal(size=40))
    effects = {0: supply, 7: np.abs(rng.normal(size=40))}
    for a, b, spread in ((1, 2, 0.05), (3, 4, 0.2)):
        effects[a] = 0.5 * supply + spread * np.abs(rng.normal(size=40))
        effects[b] = 0.5 * supply + spread * np.abs(rng.normal(size=40))
    effects[5], effects[6] = np.abs(rng.normal(size=40)), np.abs(rng.normal(size=40))
    together = supply - 0.5 * (effects[5] + effects[6])  # C_A + C_B at 1 each: 1.5 supply

    def sim(leaks):
        out = sum(size * effects[loc] for loc, size in leaks.items())
        if 5 in leaks and 6 in leaks:
            out = out + leaks[5] * leaks[6] * together
        return np.asarray(out, dtype=np.float64)

    target = sim({7: 2.0, 5: 1.0, 6: 1.0})
    matrix = np.stack([effects[i] for i in range(len(names))])
    signatures = _linear_set(matrix)
    signatures = SignatureSet(
        names,
        signatures.sizes,
        signatures.deltas,
        signatures.feature_names,
        signatures.nominal_pressure,
    )
    model = WhitenedEffects(
        signatures.sizes, signatures.deltas, lambda d: np.atleast_2d(d), target, 1.25
    )
    base = (0, 7)
    checked = refine_all({base: np.array([1.0, 2.0])}, target, sim, model.size_cap, 6)
    locations = signatures.locations
    check = SimulationCheckSettings(max_iterations=6)
    one = dict(checked)
    sized_one = supply_swaps(target, one, base, locations, model, sim, check, actuators=1)
    assert (5, 6, 7) not in sized_one
    sized = supply_swaps(target, checked, base, locations, model, sim, check)
    assert (5, 6, 7) in sized
    best = min(checked, key=lambda sub: checked[sub].rss)
    assert best == (5, 6, 7)
    assert checked[best].sizes == pytest.approx([1.0, 1.0, 2.0], rel=0.02)
