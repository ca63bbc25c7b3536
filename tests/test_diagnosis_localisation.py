"""Non-negative decomposition into leak signatures (eqs. 5.23-5.24) and ambiguity groups."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from _diag_synth import synth_signatures
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.diagnosis.localisation.search import locate as locate_effects
from pneufdd.errors import InputError


def locate(observed, sig, whiten, **settings):
    """``locate`` on the signatures alone, settings as keywords."""
    return locate_effects(observed, LeakEffectModel(sig), whiten, LocalisationSettings(**settings))


def pair_coupling(sig, reference_size=None):
    return LeakEffectModel(sig).pair_coupling(reference_size)


def names(locations):
    return tuple(str(x) for x in locations)


def _linear_set(matrix: np.ndarray) -> SignatureSet:
    n_loc, n_feat = matrix.shape
    return SignatureSet(
        tuple(f"L{i}_A" for i in range(n_loc)),
        np.full((n_loc, 1), 10.0),  # linear: one simulated size well above the tests'
        10.0 * matrix[:, None, :],
        tuple(f"f{j}" for j in range(n_feat)),
        np.full(n_loc, 6e5),
    )


def _whiten(delta):
    return np.atleast_2d(delta) * 50.0


@given(
    st.integers(0, 5),
    st.integers(0, 5),
    st.floats(0.2, 5.0),
    st.floats(0.2, 5.0),
    st.integers(0, 2**31 - 1),
)
def test_nnls_recovers_known_nonnegative_mixture(i, j, a, b, seed):
    rng = np.random.default_rng(seed)
    matrix = np.abs(rng.normal(size=(6, 80)))
    sig = _linear_set(matrix)
    truth = {i: a} if i == j else {i: a, j: b}
    observed = sum(size * matrix[loc] for loc, size in truth.items())
    result = locate(observed, sig, _whiten, max_leaks=2)
    found = {sig.locations.index(leak.location): leak.mass_flow for leak in result.leaks}
    assert found.keys() == truth.keys()
    for loc, size in truth.items():
        assert found[loc] == pytest.approx(size, rel=1e-6)
    assert all(len(leak.ambiguity_group) == 1 for leak in result.leaks)
    assert result.explained == pytest.approx(1.0, abs=1e-9)


def test_collinear_signatures_form_one_ambiguity_group():
    rng = np.random.default_rng(1)
    matrix = np.abs(rng.normal(size=(4, 60)))
    matrix[3] = 2.0 * matrix[1]  # L3 looks exactly like a leak twice the size at L1
    sig = _linear_set(matrix)
    observed = 1.0 * matrix[1] + 0.01 * rng.normal(size=60)
    result = locate(observed, sig, _whiten, max_leaks=2)
    assert len(result.leaks) == 1
    leak = result.leaks[0]
    assert set(names(leak.ambiguity_group)) == {"L1_A", "L3_A"}
    sizes = dict(zip(names(leak.ambiguity_group), leak.group_mass_flows, strict=True))
    assert sizes["L1_A"] == pytest.approx(2.0 * sizes["L3_A"], rel=1e-3)
    assert leak.confidence > 0.9  # confident that the leak is in the group ...
    # ... but not in either member alone: the two fit equally well.


def test_distinct_signatures_are_not_grouped():
    rng = np.random.default_rng(2)
    matrix = np.abs(rng.normal(size=(4, 60)))
    sig = _linear_set(matrix)
    observed = 0.7 * matrix[2] + 0.001 * rng.normal(size=60)
    (leak,) = locate(observed, sig, _whiten).leaks
    assert names(leak.ambiguity_group) == ("L2_A",)
    assert leak.confidence > 0.95


def test_nonlinear_signatures_are_refined_to_the_right_size():
    sig = synth_signatures()
    # inside the simulated sizes (2e-4 ... 1.5e-3 kg/s): 2 %; extrapolated by 1/6: 5 %
    cases = [("supply", 4.2e-4, 0.02), ("X_B", 1.1e-3, 0.02), ("Y_A", 1.4e-3, 0.02)]
    cases.append(("X_A", 1.75e-3, 0.05))
    for loc, size, tol in cases:
        i = names(sig.locations).index(loc)
        # the true effect of the synthetic machine at this size (not the signature's
        # interpolation): rebuild it from a finer signature set
        fine = synth_signatures(sizes=(size,))
        observed = fine.deltas[i, 0]
        scale = np.maximum(np.abs(sig.deltas).max(axis=(0, 1)) * 1e-3, 1e-12)
        (leak,) = locate(observed, sig, lambda d, s=scale: np.atleast_2d(d) / s).leaks
        assert str(leak.location) == loc
        assert leak.mass_flow == pytest.approx(size, rel=tol)


def test_sizes_beyond_the_ladder_are_capped():
    sig = synth_signatures()  # largest simulated size 1.5e-3 kg/s
    observed = synth_signatures(sizes=(4e-3,)).deltas[1, 0]
    (leak,) = locate(
        observed, sig, lambda d: np.atleast_2d(d) * 1e3, max_leaks=1, max_extrapolation=1.25
    ).leaks
    assert str(leak.location) == "X_A"
    assert leak.mass_flow == pytest.approx(1.25 * 1.5e-3)


def test_locate_rejects_wrong_shape():
    sig = _linear_set(np.ones((2, 5)))
    with pytest.raises(InputError, match="shape of observed"):
        locate(np.ones(4), sig, _whiten)


def test_signature_select_and_validation():
    sig = synth_signatures()
    sub = sig.select(sig.feature_names[:12])
    assert sub.deltas.shape == (5, 3, 12)
    with pytest.raises(InputError, match="positive, increasing"):
        SignatureSet(
            ("X_A",), np.array([[2.0, 1.0]]), np.zeros((1, 2, 3)), ("x", "y", "z"), np.array([6e5])
        )


def test_vectorised_subset_fits_match_bounded_least_squares_oracle():
    # oracle: scipy.optimize.lsq_linear on every combination of signature segments
    import itertools

    from scipy.optimize import lsq_linear

    rng = np.random.default_rng(8)
    n_loc, n_sizes, n_feat = 4, 3, 25
    sizes = np.cumsum(rng.uniform(0.5, 1.5, size=(n_loc, n_sizes)), axis=1)
    deltas = np.cumsum(rng.normal(size=(n_loc, n_sizes, n_feat)), axis=1)
    sig = SignatureSet(
        tuple(f"L{i}_A" for i in range(n_loc)),
        sizes,
        deltas,
        tuple(f"f{j}" for j in range(n_feat)),
        np.full(n_loc, 6e5),
    )
    target = rng.normal(size=n_feat) * 3.0
    model = WhitenedEffects(sig.sizes, sig.deltas, lambda d: np.atleast_2d(d), target)
    knots = np.concatenate([np.zeros((n_loc, 1)), sizes], axis=1)
    values = np.concatenate([np.zeros((n_loc, 1, n_feat)), deltas], axis=1)

    def pieces(loc, k):
        slope = (values[loc, k + 1] - values[loc, k]) / (knots[loc, k + 1] - knots[loc, k])
        hi = knots[loc, k + 1] if k < n_sizes - 1 else np.inf
        return values[loc, k] - knots[loc, k] * slope, slope, knots[loc, k], hi

    for subset in [(0,), (2,), (0, 1), (1, 3), (2, 3)]:
        best = np.inf
        for segs in itertools.product(range(n_sizes), repeat=len(subset)):
            parts = [pieces(loc, k) for loc, k in zip(subset, segs, strict=True)]
            rhs = target - sum(p[0] for p in parts)
            A = np.column_stack([p[1] for p in parts])
            res = lsq_linear(A, rhs, bounds=([p[2] for p in parts], [p[3] for p in parts]))
            best = min(best, float(np.sum((A @ res.x - rhs) ** 2)))
        _, rss = model.fit(subset)
        assert rss == pytest.approx(best, rel=1e-6, abs=1e-9)


def test_supply_interaction_refines_pair_sizes():
    # effects of a line leak and a supply leak are not additive (the supply leak lowers
    # the pressure the line leak sees); with the bilinear term the sizes are recovered
    rng = np.random.default_rng(12)
    n_feat = 60
    base = np.abs(rng.normal(size=(3, n_feat)))
    inter = -0.3 * base[1] + 0.1 * rng.normal(size=n_feat)
    sizes = np.array([[0.5, 1.0, 2.0, 4.0]] * 3)
    deltas = sizes[:, :, None] * base[:, None, :]
    names = tuple(f"f{j}" for j in range(n_feat))
    plain = SignatureSet(("supply", "X_A", "X_B"), sizes, deltas, names, np.full(3, 6e5))
    coupled = SignatureSet(
        ("supply", "X_A", "X_B"),
        sizes,
        deltas,
        names,
        np.full(3, 6e5),
        np.vstack([np.zeros(n_feat), inter, np.zeros(n_feat)]),
        np.array([1.0, 1.0]),
    )
    a, b = 1.5, 2.5  # X_A and supply
    observed = a * base[1] + b * base[0] + a * b * inter
    found = _located(locate(observed, coupled, _whiten))
    assert found == pytest.approx({"X_A": a, "supply": b}, rel=1e-3)
    biased = _located(locate(observed, plain, _whiten))
    assert abs(biased["X_A"] / a - 1) > 0.05


def _located(result):
    return {str(leak.location): leak.mass_flow for leak in result.leaks}


def test_pair_coupling_extends_supply_interaction_to_line_pairs():
    # K_supply = 0, f_supply = 1; a line's share f is the ratio of its supply-flow
    # change to a supply leak's; coupling(l, m) = f_l K_m + f_m K_l is symmetric
    rng = np.random.default_rng(21)
    n_feat = 40
    base = np.abs(rng.normal(size=(3, n_feat)))
    base[1, :10] = 0.5 * base[0, :10]  # X_A draws half the supply flow of a supply leak
    base[2, :10] = 0.25 * base[0, :10]
    inter = rng.normal(size=(3, n_feat))
    inter[0] = 0.0
    sizes = np.array([[1.0, 2.0]] * 3)
    names = tuple(f"Q_In.mean@{j}" if j < 10 else f"P_In.mean@{j}" for j in range(n_feat))
    sig = SignatureSet(
        ("supply", "X_A", "Y_A"),
        sizes,
        sizes[:, :, None] * base[:, None, :],
        names,
        np.full(3, 6e5),
        inter,
        np.array([1.0, 1.0]),
    )
    coupling = pair_coupling(sig, reference_size=1.0)
    assert coupling is not None
    np.testing.assert_allclose(coupling(0, 1), inter[1])
    np.testing.assert_allclose(coupling(1, 0), inter[1])
    np.testing.assert_allclose(coupling(1, 2), 0.5 * inter[2] + 0.25 * inter[1])
    np.testing.assert_allclose(coupling(2, 1), coupling(1, 2))
    plain = SignatureSet(("supply", "X_A", "Y_A"), sizes, sig.deltas, names, np.full(3, 6e5))
    assert pair_coupling(plain) is None


def test_line_pair_with_interaction_is_recovered():
    # a perfect mixture of two line leaks plus their coupling term: exact sizes back
    rng = np.random.default_rng(22)
    n_feat = 60
    base = np.abs(rng.normal(size=(4, n_feat)))
    base[1, :12] = 0.6 * base[0, :12]
    base[2, :12] = 0.4 * base[0, :12]
    base[3, :12] = 0.5 * base[0, :12]
    inter = np.zeros((4, n_feat))
    inter[1:] = -0.3 * base[1:] + 0.1 * rng.normal(size=(3, n_feat))
    sizes = np.array([[0.5, 1.0, 2.0, 4.0]] * 4)
    names = tuple(f"Q_In.mean@{j}" if j < 12 else f"f{j}" for j in range(n_feat))
    locs = ("supply", "X_A", "Y_A", "Z_A")
    deltas = sizes[:, :, None] * base[:, None, :]
    sig = SignatureSet(locs, sizes, deltas, names, np.full(4, 6e5), inter, np.array([1.0, 1.0]))
    plain = SignatureSet(locs, sizes, deltas, names, np.full(4, 6e5))
    a, b = 1.5, 2.5  # X_A and Y_A
    term = pair_coupling(sig, reference_size=1.0)(1, 2)
    observed = a * base[1] + b * base[2] + a * b * term
    assert _located(locate(observed, sig, _whiten)) == pytest.approx({"X_A": a, "Y_A": b}, rel=1e-3)
    biased = _located(locate(observed, plain, _whiten))
    assert biased.keys() != {"X_A", "Y_A"} or abs(biased["X_A"] / a - 1) > 0.02


def _two_actuator_set(matrix):
    """Signatures of supply, X_A, X_B, Y_A, Y_B: one size (10) with effects ``matrix``."""
    return SignatureSet(
        ("supply", "X_A", "X_B", "Y_A", "Y_B"),
        np.full((5, 1), 10.0),
        10.0 * matrix[:, None, :],
        tuple(f"f{j}" for j in range(50)),
        np.full(5, 6e5),
    )


def _supply_equals_both_lines(seed=23):
    rng = np.random.default_rng(seed)
    matrix = np.abs(rng.normal(size=(5, 50)))
    matrix[0] = matrix[1] + matrix[2]  # supply leak = both lines of X: indistinguishable
    sig = _two_actuator_set(matrix)
    return matrix, sig


def test_indistinguishable_explanations_are_both_reported():
    matrix, sig = _supply_equals_both_lines()
    for observed in (2.0 * matrix[0], 2.0 * matrix[1] + 2.0 * matrix[2]):
        result = locate(observed, sig, _whiten)
        reported = [set(names(leak.ambiguity_group)) for leak in result.leaks] + [
            set(names(alt.locations)) for alt in result.alternatives
        ]
        # whichever the truth, it is inside what is reported, with its sizes
        assert {"supply"} in reported or any("supply" in r for r in reported)
        assert {"X_A", "X_B"} in reported
        alt = next(a for a in result.alternatives if set(names(a.locations)) == {"X_A", "X_B"})
        assert alt.mass_flows == pytest.approx((2.0, 2.0), rel=1e-6)
        assert alt.rss == pytest.approx(result.rss, abs=1e-6)


def test_distinct_single_leak_has_no_alternative():
    matrix, sig = _supply_equals_both_lines()
    result = locate(1.5 * matrix[3], sig, _whiten)
    assert [names(leak.ambiguity_group) for leak in result.leaks] == [("Y_A",)]
    assert result.alternatives == ()


def test_smaller_of_two_same_actuator_leaks_may_be_a_supply_leak():
    rng = np.random.default_rng(24)
    matrix = np.abs(rng.normal(size=(5, 50)))
    sig = _two_actuator_set(matrix)
    result = locate(3.0 * matrix[1] + 1.0 * matrix[2], sig, _whiten)
    groups = {str(leak.location): names(leak.ambiguity_group) for leak in result.leaks}
    assert groups == {"X_A": ("X_A",), "X_B": ("X_B", "supply")}
    other = locate(3.0 * matrix[1] + 1.0 * matrix[4], sig, _whiten)
    assert [names(leak.ambiguity_group) for leak in other.leaks] == [("X_A",), ("Y_B",)]


def test_both_lines_alternative_needs_sizes_below_the_cap():
    matrix, _ = _supply_equals_both_lines()
    ladder = np.array([[40.0], [10.0], [10.0], [10.0], [10.0]])  # caps 50 and 12.5
    sig = SignatureSet(
        ("supply", "X_A", "X_B", "Y_A", "Y_B"),
        ladder,
        ladder[:, :, None] * matrix[:, None, :],
        tuple(f"f{j}" for j in range(50)),
        np.full(5, 6e5),
    )
    # 8 per line: within the cap, X's two lines are offered as the alternative ...
    assert any(
        set(names(a.locations)) == {"X_A", "X_B"}
        for a in locate(8.0 * matrix[0], sig, _whiten).alternatives
    )
    # ... 30 per line is beyond it: they cannot make this supply leak
    beyond = locate(30.0 * matrix[0], sig, _whiten)
    assert [str(leak.location) for leak in beyond.leaks] == ["supply"]
    assert all(set(names(a.locations)) != {"X_A", "X_B"} for a in beyond.alternatives)


def test_both_lines_alternative_needs_a_comparable_residual():
    rng = np.random.default_rng(25)
    matrix = np.abs(rng.normal(size=(5, 50)))
    matrix[0] = matrix[1] + matrix[2] + 0.5 * np.abs(rng.normal(size=50))  # not quite
    sig = _two_actuator_set(matrix)
    observed = 2.0 * matrix[0] + 0.01 * rng.normal(size=50)

    def pairs(result):
        return [a for a in result.alternatives if len(a.locations) == 2]

    loose = locate(observed, sig, _whiten, both_lines_max_ratio=1e12)
    strict = locate(observed, sig, _whiten)
    assert [str(leak.location) for leak in strict.leaks] == ["supply"]
    alt = pairs(loose)[0]  # the best actuator first
    assert set(names(alt.locations)) == {"X_A", "X_B"}
    assert [a.rss for a in pairs(loose)] == sorted(a.rss for a in pairs(loose))
    assert alt.rss > 30.0 * loose.rss  # a far worse fit ...
    assert pairs(strict) == []  # ... is not offered by default


def test_every_actuator_whose_two_lines_fit_a_supply_leak_is_offered():
    # two actuators whose line pairs both make the supply leak's effect: the additive
    # residual cannot say which, so both pairs are listed, best first
    rng = np.random.default_rng(26)
    matrix = np.abs(rng.normal(size=(5, 50)))
    matrix[0] = matrix[1] + matrix[2]
    matrix[3] = matrix[1] + 0.02 * rng.normal(size=50)
    matrix[4] = matrix[2] + 0.02 * rng.normal(size=50)
    sig = _two_actuator_set(matrix)
    observed = 2.0 * matrix[0] + 0.05 * rng.normal(size=50)  # noise above the mismatch
    result = locate(observed, sig, _whiten)
    pairs = [set(names(a.locations)) for a in result.alternatives if len(a.locations) == 2]
    assert {"X_A", "X_B"} in pairs
    assert {"Y_A", "Y_B"} in pairs
    assert pairs.index({"X_A", "X_B"}) < pairs.index({"Y_A", "Y_B"})
    one = locate(observed, sig, _whiten, max_alternatives=1)
    assert [set(names(a.locations)) for a in one.alternatives if len(a.locations) == 2] == [
        {"X_A", "X_B"}
    ]
