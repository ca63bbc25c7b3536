"""Property tests of the sensor models (Table 3.2, section 3.4.1)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.signal import lfilter

from pneufdd.errors import InputError
from pneufdd.physics.units import kg_s_to_slpm, slpm_to_kg_s
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


def _numpy_reading(sensor: Sensor, truth: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The sensor formulas as whole-array NumPy operations (the code the kernel replaced)."""

    def quantise(v: np.ndarray, low: float, high: float) -> np.ndarray:
        step = (high - low) / (2**sensor.bits - 1)
        return np.round((np.clip(v, low, high) - low) / step) * step + low

    if sensor.kind == "pressure":
        v = (truth - 101_325.0) * sensor.gain / 1e5 + sensor.offset + sensor.noise * z
        return quantise(v, sensor.range_low, sensor.range_high) * 1e5 + 101_325.0
    if sensor.kind == "position":
        v = truth * sensor.gain * 1e3 + sensor.offset + sensor.noise * z
        return quantise(v, sensor.range_low, sensor.range_high) * 1e-3
    slpm = np.asarray(kg_s_to_slpm(truth))
    if sensor.direction == "forward":
        slpm = np.maximum(slpm, 0.0)
    if sensor.time_constant_s > 0.0:
        a = float(np.exp(-1.0 / (1000.0 * sensor.time_constant_s)))
        slpm = lfilter([1.0 - a], [1.0, -a], slpm)
    low = sensor.range_low if sensor.direction == "forward" else -sensor.range_high
    v = slpm * sensor.gain + sensor.offset + sensor.noise * z
    return np.asarray(slpm_to_kg_s(quantise(v, low, sensor.range_high)))


@given(
    st.sampled_from(["pressure", "flow", "position"]),
    st.sampled_from(["forward", "bidirectional"]),
    st.floats(0.9, 1.1),
    st.floats(-0.2, 0.2),
    st.integers(0, 2**32 - 1),
)
def test_compiled_reading_is_the_numpy_formula_bit_for_bit(
    kind: str, direction: str, gain: float, offset: float, seed: int
) -> None:
    """One compiled pass gives what the formulas' whole-array NumPy expressions give."""
    rng = np.random.default_rng(seed)
    truth = {
        "pressure": rng.uniform(5e4, 1.3e6, 500),
        "flow": rng.uniform(-0.005, 0.005, 500),
        "position": rng.uniform(-0.01, 0.2, 500),
    }[kind]
    sensor = Sensor(
        "S", kind, "supply", 0.0, 200.0 if kind == "position" else 10.0, 0.05, 12,
        0.015 if kind == "flow" else 0.0, direction, gain, offset,
    )  # fmt: skip
    z = rng.standard_normal(truth.size)
    compiled = apply_sensor(sensor, truth, z, 1000.0)
    np.testing.assert_array_equal(compiled, _numpy_reading(sensor, truth, z))
    # a generator as the noise source draws the same normals
    drawn = apply_sensor(sensor, truth, np.random.default_rng(seed + 1), 1000.0)
    z_drawn = np.random.default_rng(seed + 1).standard_normal(truth.size)
    np.testing.assert_array_equal(drawn, _numpy_reading(sensor, truth, z_drawn))


def test_noise_draws_of_another_length_are_refused() -> None:
    with pytest.raises(InputError, match=r"noise draws of sensor 'P'.*\(3,\)"):
        apply_sensor(PRESSURE, np.full(4, 2e5), np.zeros(3), 1000.0)
