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
from pneufdd.physics.units import kg_s_to_slpm, slpm_to_kg_s
from pneufdd.sim.description import Sensor
from pneufdd.sim.layout import SENSOR_FLOW, SENSOR_POSITION, SENSOR_PRESSURE
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


def _read_only(values: F64) -> F64:
    """A read-only view of ``values``: the reading's inputs as its compiled form is typed."""
    view = values.view()
    view.flags.writeable = False
    return view


def apply_sensor(
    sensor: Sensor, truth: F64, noise: np.random.Generator | F64, rate_hz: float
) -> F64:
    """Return what ``sensor`` records for the true signal ``truth`` (SI in, SI out).

    Parameters
    ----------
    sensor : Sensor
        The sensor description.
    truth : ndarray
        True signal: absolute pressure [Pa], signed mass flow towards the actuator or
        manifold [kg/s], or position [m].
    noise : numpy.random.Generator or ndarray
        Source of the noise (``truth.size`` standard normal draws are taken from it),
        or those draws themselves, one per sample [-].
    rate_hz : float
        Sample rate [Hz].

    Returns
    -------
    ndarray
        The recorded signal in SI units [Pa], [kg/s] or [m].

    Notes
    -----
    In the sensor's unit (bar(g), SLPM or mm) the reading is
    ``gain * truth + offset + noise * z``, clipped to the range and quantised to
    ``bits`` bits over it (round half to even), then converted back to SI. The
    arithmetic is one compiled pass (:func:`pneufdd.sim.kernel.sensor_reading_kernel`,
    prebuilt or numba's JIT) whose operations are those of the formulas in their order:
    the same values, bit for bit, as the NumPy expressions it replaced (a festo-dsd
    run's channels hold about 60,000 samples each; eight or more whole-array passes and
    their temporaries cost more than the arithmetic).
    """
    n = truth.size
    z = noise.standard_normal(n) if isinstance(noise, np.random.Generator) else noise
    if z.shape != (n,):
        raise InputError(describe(f"noise draws of sensor {sensor.channel!r}", z.shape, (n,)))
    reading = compiled_twin().sensor_reading
    if sensor.kind == "pressure":
        low, high = sensor.range_low, sensor.range_high
        kind = SENSOR_PRESSURE
        x = np.ascontiguousarray(truth, dtype=np.float64)
    elif sensor.kind == "flow":
        slpm = np.asarray(kg_s_to_slpm(truth), dtype=np.float64)
        if sensor.direction == "forward":
            slpm = np.maximum(slpm, 0.0)
        if sensor.time_constant_s > 0.0:
            a = float(np.exp(-1.0 / (rate_hz * sensor.time_constant_s)))
            slpm = first_order_recursion(slpm, 1.0 - a, a)
        low = sensor.range_low if sensor.direction == "forward" else -sensor.range_high
        high = sensor.range_high
        kind = SENSOR_FLOW
        x = np.ascontiguousarray(slpm, dtype=np.float64)
    else:
        low, high = sensor.range_low, sensor.range_high
        kind = SENSOR_POSITION
        x = np.ascontiguousarray(truth, dtype=np.float64)
    step = (high - low) / (2**sensor.bits - 1)
    q = reading(
        _read_only(x),
        _read_only(np.ascontiguousarray(z, dtype=np.float64)),
        kind,
        float(sensor.gain),
        float(sensor.offset),
        float(sensor.noise),
        float(low),
        float(high),
        float(step),
    )
    if kind == SENSOR_FLOW:
        return np.asarray(slpm_to_kg_s(q), dtype=np.float64)
    return np.asarray(q, dtype=np.float64)
