"""Zero-phase LVDT filtering, velocity and acceleration (section 3.2.4, eq. 3.1)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from pneufdd.errors import InputError
from pneufdd.signals.filtering import fill_gaps, kinematics, lowpass

FS = 1000.0


def _stroke(noise: float = 2e-4, seed: int = 0):
    """A 200 mm DNC stroke of 0.38 s (eq. 3.1) with a smooth profile and LVDT noise."""
    t = np.arange(1500) / FS
    u = np.clip((t - 0.5) / 0.38, 0.0, 1.0)
    x = 0.2 * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
    rng = np.random.default_rng(seed)
    return t, x, x + noise * rng.standard_normal(t.size)


def test_eq_3_1_mean_speed_times_stroke_time_is_the_stroke() -> None:
    t, _x, noisy = _stroke()
    k = kinematics(noisy, FS, cutoff_hz=40.0)
    moving = (t >= 0.5) & (t <= 0.88)
    mean_speed = np.mean(k.velocity[moving])
    assert mean_speed == pytest.approx(0.2 / 0.38, rel=0.02)
    assert mean_speed * 0.38 == pytest.approx(0.200, rel=0.02)


def test_filtering_removes_noise_without_lag() -> None:
    _t, x, noisy = _stroke()
    k = kinematics(noisy, FS)
    assert np.sqrt(np.mean((k.position - x) ** 2)) < 2e-4 / 3
    v_true = np.gradient(x, 1 / FS)
    raw_v = np.gradient(noisy, 1 / FS)
    # Fig. 3.7 -> 3.8: the differentiated noise shrinks by more than 10x.
    assert np.std(raw_v - v_true) > 10 * np.std(k.velocity - v_true)
    # Zero phase: the filtered velocity fits the true one best without any shift.
    lags = np.arange(-20, 21)
    misfit = [np.sum((np.roll(k.velocity, lag) - v_true)[50:-50] ** 2) for lag in lags]
    assert lags[int(np.argmin(misfit))] == 0
    # Peer oracle: scipy's own zero-phase filter of the same design.
    sos = signal.butter(4, 40.0, output="sos", fs=FS)
    assert np.allclose(lowpass(noisy, FS, 40.0), signal.sosfiltfilt(sos, noisy))


def test_nan_gaps_are_bridged_and_kept_nan() -> None:
    _, _x, noisy = _stroke()
    gappy = noisy.copy()
    gappy[700:710] = np.nan
    y = lowpass(gappy, FS)
    assert np.all(np.isnan(y[700:710]))
    assert np.all(np.isfinite(y[:700]))
    assert np.max(np.abs(y[:690] - lowpass(noisy, FS)[:690])) < 1e-4
    filled, gaps = fill_gaps([np.nan, 1.0, np.nan, 3.0, np.nan])
    assert filled.tolist() == [1.0, 1.0, 2.0, 3.0, 3.0]
    assert gaps.tolist() == [True, False, True, False, True]


def test_filter_arguments_are_checked() -> None:
    with pytest.raises(InputError, match="cutoff_hz"):
        lowpass(np.zeros(100), FS, 600.0)
    with pytest.raises(InputError, match="signal length"):
        lowpass(np.zeros(10), FS, 40.0)
    with pytest.raises(InputError, match="order"):
        lowpass(np.zeros(100), FS, 40.0, order=0)
    with pytest.raises(InputError, match="fs"):
        lowpass(np.zeros(100), -1.0, 40.0)
