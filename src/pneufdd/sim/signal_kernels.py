"""The twin's compiled passes over whole signals: sensor lag, sensor reading, true rows.

Moved out of :mod:`pneufdd.sim.kernel` (which re-exports them, so the prebuilt twin
finds them there, :mod:`pneufdd.sim.prebuilt`) when the fault models of issue 34
grew the kernel's module; the code is unchanged.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.physics.constants import P_ATM
from pneufdd.sim import layout as lay

__all__ = ["first_order_recursion_kernel", "sensor_reading_kernel", "truth_rows_kernel"]


@njit(cache=True, nogil=True)
def first_order_recursion_kernel(x: FloatArray, gain: float, pole: float) -> FloatArray:
    """``y[k] = gain * x[k] + pole * y[k-1]``, ``y[-1] = 0``: the sensors' first-order lag
    and the house-pressure drift (:func:`pneufdd.sim.sensors.first_order_recursion`)."""
    y = np.empty_like(x)
    previous = 0.0
    for k in range(x.size):
        previous = gain * x[k] + pole * previous
        y[k] = previous
    return y


@njit(cache=True, nogil=True)
def sensor_reading_kernel(
    x: FloatArray,
    z: FloatArray,
    kind: int,
    gain: float,
    offset: float,
    noise: float,
    low: float,
    high: float,
    step: float,
) -> FloatArray:
    """What a sensor records for the true signal ``x`` (:func:`pneufdd.sim.sensors.apply_sensor`).

    In the sensor's unit, ``gain * x + offset + noise * z`` clipped to ``[low, high]``
    and rounded to the nearest multiple of ``step`` above ``low`` (ties to even), then
    back to SI. One pass over the samples, each operation in the order of
    ``apply_sensor``'s formulas, so the result is the same bit for bit as the NumPy
    expression it replaces (``tests/test_sim_sensors.py``).
    """
    y = np.empty_like(x)
    for k in range(x.size):
        if kind == lay.SENSOR_PRESSURE:
            v = x[k] - P_ATM
            v = v * gain
            v = v / 1e5
        elif kind == lay.SENSOR_FLOW:
            v = x[k] * gain
        else:
            v = x[k] * gain
            v = v * 1e3
        v = v + offset
        v = v + noise * z[k]
        v = min(max(v, low), high)
        v = v - low
        v = v / step
        v = np.rint(v)
        v = v * step
        v = v + low
        if kind == lay.SENSOR_PRESSURE:
            v = v * 1e5
            v = v + P_ATM
        elif kind == lay.SENSOR_POSITION:
            v = v * 1e-3
        y[k] = v
    return y


@njit(cache=True, nogil=True)
def truth_rows_kernel(
    p: FloatArray,
    x: FloatArray,
    fch: FloatArray,
    fexh: FloatArray,
    fr: FloatArray,
    source: IntArray,
    column: IntArray,
    store: FloatArray,
    first: int,
    n: int,
) -> None:
    """Copy the true signals of one cycle's ``n`` samples into ``store``.

    Row ``r`` of ``store`` (one recorded sensor) gets, from sample ``first`` on, the
    column ``column[r]`` of the kernel output that ``source[r]`` names
    (:data:`pneufdd.sim.layout.TRUTH_NODE_PRESSURE` ...): a pressure, a position, the
    supply line's flow or a chamber's net flow ``fch - fexh`` (the flow a meter on that
    line sees, towards the chamber). One compiled pass that releases the GIL, instead
    of a strided column copy (and a temporary for the flows) per sensor and cycle.
    """
    for r in range(source.size):
        c = column[r]
        kind = source[r]
        if kind == lay.TRUTH_NODE_PRESSURE:
            for k in range(n):
                store[r, first + k] = p[k, c]
        elif kind == lay.TRUTH_POSITION:
            for k in range(n):
                store[r, first + k] = x[k, c]
        elif kind == lay.TRUTH_CHAMBER_FLOW:
            for k in range(n):
                store[r, first + k] = fch[k, c] - fexh[k, c]
        else:
            for k in range(n):
                store[r, first + k] = fr[k, c]
