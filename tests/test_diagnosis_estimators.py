"""Detectors follow scikit-learn's estimator contract and meet their statistical targets."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from sklearn.utils.estimator_checks import parametrize_with_checks

from pneufdd.diagnosis.detection.band import BandDetector
from pneufdd.diagnosis.detection.statistic import (
    CycleDistanceDetector,
    recording_correlation,
    scaled_chi2_fit,
)


@parametrize_with_checks([BandDetector(), CycleDistanceDetector(n_folds=5)])
def test_sklearn_contract(estimator, check):
    check(estimator)


@pytest.mark.parametrize("eps", [2.0, 3.0])
def test_band_out_of_band_rate_matches_gaussian_tail(eps):
    # eq. 5.3: a leak-free Gaussian sample leaves mean +/- eps sigma with probability
    # 2 (1 - Phi(eps)): 4.55 % for eps = 2, 0.27 % for eps = 3.
    rng = np.random.default_rng(11)
    det = BandDetector(eps=eps).fit(rng.normal(3.0, 2.0, size=(2000, 400)))
    rate = float(np.mean(det.out_of_band(rng.normal(3.0, 2.0, size=(500, 400)))))
    expected = 2.0 * stats.norm.sf(eps)
    assert rate == pytest.approx(expected, rel=0.06)


def test_band_alarm_fraction_rule():
    rng = np.random.default_rng(2)
    det = BandDetector(eps=3.0, alarm_fraction=0.01).fit(rng.normal(size=(500, 1000)))
    shifted = rng.normal(size=(20, 1000))
    shifted[:, :50] += 10.0  # 5 % of every cycle far out of band
    assert det.predict(shifted).tolist() == [1] * 20
    assert np.all(det.score_samples(shifted) >= 0.05)
    assert det.predict(rng.normal(size=(50, 1000))).sum() == 0


def test_band_ignores_nan_padding():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(100, 20))
    X[:50, 15:] = np.nan  # short steps in half the cycles
    det = BandDetector().fit(X)
    assert np.all(np.isfinite(det.mean_))
    row = np.full((1, 20), np.nan)
    row[0, :5] = 0.0
    assert det.score_samples(row)[0] == 0.0


def test_scaled_chi2_fit_recovers_parameters():
    rng = np.random.default_rng(4)
    g, h = scaled_chi2_fit(0.5 * rng.chisquare(12.0, size=100_000))
    assert g == pytest.approx(0.5, rel=0.03)
    assert h == pytest.approx(12.0, rel=0.03)


def _fluctuating(rng, n, p, amplitude=5.0):
    direction = np.linspace(1.0, 2.0, p)
    return amplitude * rng.normal(size=(n, 1)) * direction + rng.normal(size=(n, p))


def test_cycle_distance_false_alarm_rate_near_target():
    rng = np.random.default_rng(5)
    det = CycleDistanceDetector(n_nuisance=1, false_alarm_rate=0.01).fit(
        _fluctuating(rng, 200, 120)
    )
    rate = float(np.mean(det.predict(_fluctuating(rng, 20_000, 120))))
    assert rate < 0.02
    assert abs(det.reference_false_alarm_rate_ - 0.01) < 0.03


def test_cycle_distance_ignores_supply_fluctuation_but_sees_step_pattern():
    rng = np.random.default_rng(6)
    p = 120
    det = CycleDistanceDetector(n_nuisance=1).fit(_fluctuating(rng, 200, p))
    direction = np.linspace(1.0, 2.0, p)
    # a run at the edge of the fluctuation seen in the reference (2.4 sigma of it):
    # in raw units 12 noise standard deviations, yet quiet
    big = 12.0 * direction + rng.normal(size=(10, p))
    assert not det.predict_run(big)
    naive = (big - det.mean_) / det.scale_
    assert np.mean(naive**2) > 4.0 * det.run_threshold(10)  # without the projection: alarm
    pattern = np.zeros(p)
    pattern[10:20] = 1.5  # a leak visible in 10 steps only
    assert det.predict_run(pattern + rng.normal(size=(10, p)))


def test_run_threshold_shrinks_with_run_length():
    rng = np.random.default_rng(7)
    det = CycleDistanceDetector().fit(rng.normal(size=(50, 30)))
    assert det.run_threshold(10) < det.run_threshold(1)
    assert det.run_threshold(1) == det.threshold_


@pytest.mark.parametrize("m", [1, 4, 9, 10])
def test_median_run_threshold_is_the_order_statistic_quantile(m):
    """Oracle: the (upper) median of m draws of g chi2(h), sampled 400,000 times."""
    rng = np.random.default_rng(11)
    det = CycleDistanceDetector(false_alarm_rate=0.01).fit(rng.normal(size=(60, 30)))
    g, h = det.chi2_scale_, det.chi2_dof_
    draws = np.sort(g * rng.chisquare(h, size=(400_000, m)), axis=1)[:, m // 2]
    assert det.run_threshold(m) == pytest.approx(np.quantile(draws, 0.99), rel=0.005)
    assert np.mean(draws > det.run_threshold(m)) == pytest.approx(0.01, abs=0.001)


@pytest.mark.parametrize("statistic", ["median", "mean"])
def test_run_p_value_inverts_the_run_threshold(statistic):
    """At false_alarm_rate = p-value of a run, the run threshold is that run's statistic."""
    rng = np.random.default_rng(12)
    det = CycleDistanceDetector(run_statistic=statistic).fit(rng.normal(size=(60, 30)))
    run = 1.1 * rng.normal(size=(10, 30))
    p = det.run_p_value(run)
    assert 1e-6 < p < 0.5
    det.false_alarm_rate = p
    assert det.run_threshold(10) == pytest.approx(det.run_score(det.score_samples(run)), rel=1e-6)


def test_median_run_is_not_flagged_by_one_odd_cycle_but_a_shift_is():
    rng = np.random.default_rng(13)
    p = 40
    X = rng.normal(size=(80, p))
    median = CycleDistanceDetector(n_nuisance=0).fit(X)
    mean = CycleDistanceDetector(n_nuisance=0, run_statistic="mean").fit(X)
    run = rng.normal(size=(10, p))
    run[3] *= 4.0  # one odd cycle: 16 times the statistic of the others
    assert mean.predict_run(run)
    assert not median.predict_run(run)
    shifted = rng.normal(size=(10, p)) + 0.6  # every cycle moved (a leak)
    assert median.predict_run(shifted)
    assert mean.predict_run(shifted)


def test_run_statistic_is_checked():
    with pytest.raises(ValueError, match="run_statistic: received 'max'"):
        CycleDistanceDetector(run_statistic="max").fit(np.ones((5, 3)) + np.eye(5, 3))


def test_recording_level_shifts_need_leave_one_recording_out_cross_validation():
    # Cycles of one recording share its conditions (drift level, compressor phase):
    # each recording here is offset by its own random vector. Scored in turn, the
    # reference hides that; leaving whole recordings out measures what a new run meets.
    rng = np.random.default_rng(3)
    p, per = 30, 20

    def recordings(n):
        return [0.5 * rng.normal(size=p) + rng.normal(size=(per, p)) for _ in range(n)]

    X = np.vstack(recordings(5))
    groups = np.repeat(np.arange(5), per)
    in_turn = CycleDistanceDetector(n_nuisance=0, false_alarm_rate=0.01).fit(X)
    grouped = CycleDistanceDetector(n_nuisance=0, false_alarm_rate=0.01).fit(X, groups=groups)
    assert grouped.grouped_cv_
    assert not in_turn.grouped_cv_
    assert grouped.run_threshold(10) > in_turn.run_threshold(10)
    new_runs = [r[:10] for r in recordings(2000)]

    def flagged(det):
        return np.mean([det.predict_run(r) for r in new_runs])

    assert flagged(in_turn) > 0.05  # 13 % of new leak-free runs, designed for 1 %
    assert flagged(grouped) < 0.03  # 2 %


def test_run_threshold_counts_the_correlated_cycles_of_a_run():
    """Recordings offset as above, a campaign-like reference (4 recordings of 25
    cycles): the design rate is 1 %. Assuming a run's cycles independent, references
    flag new runs at 1.6 % on average (a quarter of them above 2 %); counting them as
    m / (1 + (m - 1) rho) independent cycles brings the average to or below the design
    (measured 0.50 % over 40 references of 600 runs, against 1.58 %)."""
    rng = np.random.default_rng(100)
    p = 30

    def recordings(n, per):
        return [0.5 * rng.normal(size=p) + rng.normal(size=(per, p)) for _ in range(n)]

    rates = []
    for _ in range(16):
        X = np.vstack(recordings(4, 25))
        groups = np.repeat(np.arange(4), 25)
        dets = [
            CycleDistanceDetector(n_nuisance=0, false_alarm_rate=0.01, run_correlation=c).fit(
                X, groups=groups
            )
            for c in (False, True)
        ]
        assert dets[0].recording_correlation_ == 0.0
        assert dets[1].run_threshold(10) >= dets[0].run_threshold(10)
        assert dets[1].run_threshold(1) == dets[0].run_threshold(1)
        runs = np.vstack(recordings(300, 10))
        scores = [d.score_samples(runs).reshape(300, 10) for d in dets]
        rates.append(
            [
                np.mean([d.run_score(r) > d.run_threshold(10) for r in sc])
                for d, sc in zip(dets, scores, strict=True)
            ]
        )
    independent, correlated = np.mean(rates, axis=0)
    assert independent > 0.012
    assert correlated <= 0.01


@pytest.mark.parametrize("statistic", ["median", "mean"])
def test_run_threshold_with_correlated_cycles_lies_between_the_run_and_cycle_rules(statistic):
    """rho = 0: the independent rule; rho = 1: a run is worth one cycle; in between the
    threshold rises with rho, and m / (1 + (m - 1) rho) cycles count."""
    rng = np.random.default_rng(21)
    det = CycleDistanceDetector(run_statistic=statistic, false_alarm_rate=0.01)
    det.fit(rng.normal(size=(60, 30)))
    base = det.run_threshold(10)
    det.recording_correlation_ = 0.2
    raised = det.run_threshold(10)
    assert det.effective_cycles(10) == pytest.approx(10 / 2.8)
    assert base < raised < det.run_threshold(1)
    det.recording_correlation_ = 0.5
    assert raised < det.run_threshold(10) < det.run_threshold(1)
    det.recording_correlation_ = 1.0
    assert det.run_threshold(10) == pytest.approx(det.run_threshold(1), rel=1e-9)


def test_recording_correlation_of_known_variance_components():
    """Oracle: between-recording variance 1, within 3 -> rho = 0.25 (many recordings)."""
    rng = np.random.default_rng(5)
    k, per = 2000, 8
    values = rng.normal(size=(k, 1)) + np.sqrt(3.0) * rng.normal(size=(k, per))
    groups = np.repeat(np.arange(k), per)
    assert recording_correlation(values.ravel(), groups) == pytest.approx(0.25, abs=0.02)
    unequal = np.concatenate([np.arange(k)[: k // 2].repeat(3), np.arange(k)[k // 2 :]])
    flat = values[:, :3].ravel()[: unequal.size]
    assert 0.0 <= recording_correlation(flat, unequal) <= 1.0


def test_groups_are_checked():
    with pytest.raises(ValueError, match=r"groups: received shape \(3,\)"):
        CycleDistanceDetector().fit(np.eye(5, 3) + 1.0, groups=[0, 1, 2])
