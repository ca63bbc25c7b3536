"""Property tests of the sensor models (Table 3.2, section 3.4.1)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.signal import lfilter

from pneufdd.errors import InputError
from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.sim.description import Sensor
from pneufdd.sim.sensors import apply_sensor, first_order_recursion

FLOW = Sensor("Q", "flow", "supply", 0.0, 200.0, 0.4, 12, 0.015, "forward")
PRESSURE = Sensor("P", "pressure", "supply", 0.0, 10.0, 0.006, 12, 0.0, "forward")

flows = arrays(np.float64, st.integers(1, 300), elements=st.floats(-0.01, 0.01))
pressures = arrays(np.float64, st.integers(1, 300), elements=st.floats(5e4, 1.5e6))


@given(flows, st.integers(0, 2**32 - 1))
def test_forward_meter_reads_in_range_on_its_grid(truth: np.ndarray, seed: int) -> None:
    out = kg_s_to_slpm(apply_sensor(FLOW, truth, np.random.default_rng(seed), 1000.0))
    assert np.all(out >= 0.0)
    assert np.all(out <= 200.0 + 1e-9)
    codes = out / (200.0 / 4095)
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)


@given(pressures, st.integers(0, 2**32 - 1))
def test_pressure_sensor_clips_to_0_10_bar_gauge(truth: np.ndarray, seed: int) -> None:
    out = apply_sensor(PRESSURE, truth, np.random.default_rng(seed), 1000.0)
    gauge = (out - 101_325.0) / 1e5
    assert np.all(gauge >= -1e-9)
    assert np.all(gauge <= 10.0 + 1e-9)
    inside = ((truth - 101_325.0) / 1e5 > 0.1) & ((truth - 101_325.0) / 1e5 < 9.9)
    # noise 0.006 bar + half a 2.44 mbar step: 8 sigma bound
    assert np.all(np.abs(gauge[inside] - (truth[inside] - 101_325.0) / 1e5) < 0.05)


@given(
    arrays(np.float64, st.integers(1, 300), elements=st.floats(-1e6, 1e6)),
    st.floats(0.0, 2.0),
    st.floats(-0.999, 0.999),
)
def test_first_order_recursion_is_scipy_lfilter(x: np.ndarray, gain: float, pole: float) -> None:
    """The compiled sensor lag and drift recursion against scipy.signal.lfilter, bit for bit."""
    expected = lfilter([gain], [1.0, -pole], x)
    np.testing.assert_array_equal(first_order_recursion(x, gain, pole), expected)


def test_first_order_lag_settles_to_its_input_with_time_constant_tau() -> None:
    """A 15 ms lag sampled at 1 kHz reaches 1 - 1/e of a unit step after 15 samples."""
    pole = float(np.exp(-1.0 / (1000.0 * 0.015)))
    y = first_order_recursion(np.ones(200), 1.0 - pole, pole)
    np.testing.assert_allclose(y[14], 1.0 - np.exp(-1.0), rtol=1e-12)
    np.testing.assert_allclose(y[-1], 1.0, atol=1e-5)


def test_first_order_recursion_takes_one_dimension_only() -> None:
    with pytest.raises(InputError, match=r"\(2, 2\)"):
        first_order_recursion(np.ones((2, 2)), 0.5, 0.5)
