"""Sensor models: what the DAQ of the rig records (Table 3.2, sections 3.2.4 and 3.4.1).

* Pressure: SDE1-D10, 0-10 bar(g), white noise, clipped to range, 12-bit quantised
  over the range (NI 6025E, 0-10 V input), stored as absolute pressure [Pa].
* Flow: SFE1-LF-F200 thermal mass-flow meter, 0-200 SLPM, first-order response,
  measures ONE direction only (``forward`` = towards the actuator or the manifold;
  reverse flow reads zero), saturates at full scale, noise, 12-bit; stored in kg/s via
  the dissertation basis (1.294 kg/m^3). ``bidirectional`` is an idealised research
  meter, not a real SFE1.
* Position: LVDT on the DNC rod with noticeable noise (Fig. 3.6).

Every sensor reads ``gain * truth + offset`` in its unit before noise and quantisation
(a calibration error: ``gain`` 1 and ``offset`` 0 for an ideal sensor; the plants of
:mod:`pneufdd.sim.variation` draw them within the sensors' stated accuracy).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pneufdd.errors import InputError, describe
from pneufdd.physics.constants import P_ATM
from pneufdd.physics.units import kg_s_to_slpm, slpm_to_kg_s
from pneufdd.sim.description import Sensor
from pneufdd.sim.prebuilt import compiled_twin

__all__ = ["SENSOR_SI_UNIT", "apply_sensor", "first_order_recursion"]

F64 = npt.NDArray[np.float64]
SENSOR_SI_UNIT = {"pressure": "Pa", "flow": "kg/s", "position": "m"}


def first_order_recursion(x: F64, gain: float, pole: float) -> F64:
    """First-order recursive filter ``y[k] = gain * x[k] + pole * y[k-1]``, ``y[-1] = 0``.

    The sensor's first-order lag (``gain = 1 - pole``, ``pole = exp(-dt / tau)``, the
    exact discretisation of ``tau dy/dt + y = x`` for a piecewise-constant input) and
    the house-pressure drift's AR(1) process (``gain = 1``) are both this recursion.
    It is compiled like the rest of the twin
    (:func:`pneufdd.sim.kernel.first_order_recursion_kernel`, prebuilt or numba's JIT,
    :mod:`pneufdd.sim.prebuilt`): the same result as
    ``scipy.signal.lfilter([gain], [1, -pole], x)`` (the tests use it as the oracle),
    without importing :mod:`scipy.signal`, which costs about 0.5 s at the start of
    every ``pneufdd simulate``.

    Parameters
    ----------
    x : ndarray
        Input samples, one dimension [any unit].
    gain : float
        Input gain [-].
    pole : float
        Pole of the recursion, ``|pole| < 1`` for a stable filter [-].

    Returns
    -------
    ndarray
        Filtered samples [unit of ``x``].

    Raises
    ------
    InputError
        If ``x`` has more or fewer than one dimension.

    Examples
    --------
    >>> first_order_recursion(np.array([1.0, 1.0, 1.0]), 0.5, 0.5).tolist()
    [0.5, 0.75, 0.875]
    """
    samples = np.ascontiguousarray(x, dtype=np.float64)
    if samples.ndim != 1:
        raise InputError(describe("samples of the recursion (shape)", samples.shape, "(n,)"))
    recursion = compiled_twin().first_order_recursion
    return np.asarray(recursion(samples, float(gain), float(pole)))


def _quantise(values: F64, low: float, high: float, bits: int) -> F64:
    """``values`` clipped to ``[low, high]`` and rounded to ``bits`` bits (in place)."""
    step = (high - low) / (2**bits - 1)
    # low + round((clip(values) - low) / step) * step, each operation in place
    np.clip(values, low, high, out=values)
    values -= low
    values /= step
    np.round(values, out=values)
    values *= step
    values += low
    return values


def apply_sensor(sensor: Sensor, truth: F64, rng: np.random.Generator, rate_hz: float) -> F64:
    """Return what ``sensor`` records for the true signal ``truth`` (SI in, SI out).

    Parameters
    ----------
    sensor : Sensor
        The sensor description.
    truth : ndarray
        True signal: absolute pressure [Pa], signed mass flow towards the actuator or
        manifold [kg/s], or position [m].
    rng : numpy.random.Generator
        Source of the noise.
    rate_hz : float
        Sample rate [Hz].

    Returns
    -------
    ndarray
        The recorded signal in SI units [Pa], [kg/s] or [m].

    Notes
    -----
    Each step works in place on one array (a festo-dsd run's channels hold about
    60,000 samples each; temporaries cost more than the arithmetic); the operations
    and their order are those of the formulas in the comments, so the values are the
    same bit for bit.
    """
    n = truth.size
    if sensor.kind == "pressure":
        # gain * (truth - P_ATM) / 1e5 + offset + noise * z  [bar(g)]
        bar_g = np.subtract(truth, P_ATM, dtype=np.float64)
        bar_g *= sensor.gain
        bar_g /= 1e5
        bar_g += sensor.offset
        bar_g += sensor.noise * rng.standard_normal(n)
        q = _quantise(bar_g, sensor.range_low, sensor.range_high, sensor.bits)
        q *= 1e5
        q += P_ATM
        return q
    if sensor.kind == "flow":
        slpm = np.asarray(kg_s_to_slpm(truth), dtype=np.float64)
        if sensor.direction == "forward":
            slpm = np.maximum(slpm, 0.0)
        if sensor.time_constant_s > 0.0:
            a = float(np.exp(-1.0 / (rate_hz * sensor.time_constant_s)))
            slpm = first_order_recursion(slpm, 1.0 - a, a)
        # gain * slpm + offset + noise * z  [SLPM]
        reading = np.multiply(slpm, sensor.gain, dtype=np.float64)
        reading += sensor.offset
        reading += sensor.noise * rng.standard_normal(n)
        low = sensor.range_low if sensor.direction == "forward" else -sensor.range_high
        q = _quantise(reading, low, sensor.range_high, sensor.bits)
        return np.asarray(slpm_to_kg_s(q), dtype=np.float64)
    # gain * truth * 1e3 + offset + noise * z  [mm]
    mm = np.multiply(truth, sensor.gain, dtype=np.float64)
    mm *= 1e3
    mm += sensor.offset
    mm += sensor.noise * rng.standard_normal(n)
    q = _quantise(mm, sensor.range_low, sensor.range_high, sensor.bits)
    q *= 1e-3
    return q
