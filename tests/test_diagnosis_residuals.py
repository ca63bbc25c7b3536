"""The physics-residual detector: scikit-learn contract, eq. 4.21 and a leak on a plant."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.utils.estimator_checks import parametrize_with_checks

from pneufdd.diagnosis.detection.residuals import ResidualDetector, TwinReplay
from pneufdd.sim import as_exported, load_machine, simulate, vary_machine


@parametrize_with_checks([ResidualDetector()])
def test_sklearn_contract(estimator, check):
    check(estimator)


def test_false_alarm_rate_is_bounded_on_gaussian_residuals():
    rng = np.random.default_rng(21)
    det = ResidualDetector(false_alarm_rate=0.01, require_consistency=False)
    det.fit(rng.normal(size=(400, 20)))
    rate = float(np.mean(det.predict(rng.normal(size=(50_000, 20)))))
    # Bonferroni over 10 independent flow columns: at most 1 %, about 0.995 %
    assert 0.005 < rate <= 0.012


def test_eq_4_21_separates_a_leak_from_a_supply_pressure_rise():
    rng = np.random.default_rng(22)
    free = np.hstack([rng.normal(0, 1e-4, (300, 4)), rng.normal(0, 300, (300, 4))])
    det = ResidualDetector().fit(free)
    leak = free[:100] + np.array([8e-4] * 4 + [-2e3] * 4)
    push = free[:100] + np.array([8e-4] * 4 + [2e3] * 4)  # house air pushing: P and Q up
    assert det.predict(leak).tolist() == [1] * 100
    assert det.predict(push).tolist() == [0] * 100
    assert set(det.verdict(push)) == {"not a leak (pressure rose too)"}
    assert set(det.verdict(leak)) == {"leak (eq. 4.21 holds)"}


@pytest.mark.slow
def test_two_turn_extend_line_leak_on_a_plant():
    machine = load_machine("festo-dsd")
    replay = TwinReplay.of(machine, cycles=3, seed=5)
    plant = vary_machine(machine, 1.0, 7)
    free = [as_exported(simulate(plant, cycles=10, seed=s)) for s in (8, 9, 10)]
    det = ResidualDetector().fit(np.vstack([replay.residuals(r, machine) for r in free]))
    quiet = replay.residuals(as_exported(simulate(plant, cycles=10, seed=11)), machine)
    leak = as_exported(simulate(plant, cycles=10, leaks={"DNC_A": 2}, seed=12))
    rows = replay.residuals(leak, machine)
    assert det.predict(quiet).sum() == 0
    assert det.predict(rows).mean() >= 0.9
    # the twin's bias is the plant's model error: not zero on a plant at scale 1
    assert np.max(np.abs(det.bias_[: det.n_flow_columns_])) > 0
    # the leak's estimated flow is of the order of a 2-turn leak (~10-30 SLPM ~ 2-7e-4 kg/s)
    assert 1e-4 < float(np.median(det.leak_flow(rows))) < 2e-3
