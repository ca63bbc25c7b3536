"""Leaks as orifices to atmosphere, and the GR-3/8B leak valve (sections 1.1, 3.2.5).

A leak is an orifice discharging to the atmosphere (:data:`P_ATM`). Its size is its
effective area ``Cd A`` [m^2], which can be given three ways (:func:`leak_area`):

* in turns of the Festo GR-3/8B flow-control valve the rig uses to make leaks
  (:func:`leak_valve_area`, the curve of Figs 3.13/3.14);
* as a hole diameter in mm, taken as a sharp-edged orifice with Cd = 0.61 (the
  Figure 1.2 note: "multiply by 0.61 for sharp [orifices]");
* as a nominal flow in SLPM (0 degC, 1013 mbar) at a stated absolute pressure.

The GR-3/8B curve
-----------------
Section 3.2.5 states that the valve passes at most about 1000 l/min at 20 turns and
that the dissertation stops at 6 turns because the flow meters top out at 200 SLPM;
Figs 3.13/3.14 show a monotone, convex start (little flow during the first turn,
steeper after). The area model is

.. math::

    (C_d A)(n) = A_{20} \\left(\\frac{n - n_0}{20 - n_0}\\right)^p \\ (n > n_0),
    \\qquad 0 \\ (n \\le n_0)

with a dead band n_0 = 0.3 turn (the needle's seal still closes the seat) and
p = 1.37. ``A_20`` is fixed by Festo's rating convention for flow-control valves,
the standard nominal flow: 1000 l/min (ANR) at 6 bar(g) upstream and 5 bar(g)
downstream, 20 degC, through the orifice law eq. 4.3: A_20 = 16.62 mm^2. n_0 and p
were chosen so that at 5 bar(g) to atmosphere 1 turn leaks 11.3 SLPM and 6 turns
200.0 SLPM, the span of the rig's experiments. At 20 turns and 5 bar(g) to
atmosphere the valve leaks 1094 SLPM. The curve is a design choice matched to
those anchors, not a fit to the (unavailable) plotted data.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, section 3.2.5, Figs 3.13/3.14, Figure 1.2.
.. [2] Festo, one-way flow control valves GR: standard nominal flow rate qnN,
   6 -> 5 bar, ISO 8778 reference (ANR).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from pneufdd.errors import InputError, describe
from pneufdd.physics._jit import (
    FloatOrArray,
    as_float_array,
    njit,
    require,
    scalar_or_array,
)
from pneufdd.physics.constants import P_ATM, T_ROOM
from pneufdd.physics.flow import orifice_mass_flow, orifice_mass_flow_kernel
from pneufdd.physics.units import slpm_to_kg_s

__all__ = [
    "LEAK_VALVE_DEAD_TURNS",
    "LEAK_VALVE_EXPONENT",
    "LEAK_VALVE_MAX_AREA",
    "LEAK_VALVE_MAX_TURNS",
    "SHARP_EDGE_CD",
    "equivalent_orifice_diameter",
    "leak_area",
    "leak_mass_flow",
    "leak_mass_flow_kernel",
    "leak_valve_area",
    "turns_for_area",
]

SHARP_EDGE_CD: float = 0.61
"""Discharge coefficient of a sharp-edged hole, Figure 1.2 note [-]."""

LEAK_VALVE_MAX_TURNS: float = 20.0
"""Full opening of the GR-3/8B adjustment screw, section 3.2.5 [turns]."""

LEAK_VALVE_DEAD_TURNS: float = 0.3
"""Turns before the GR-3/8B needle leaves its seat (design choice) [turns]."""

LEAK_VALVE_EXPONENT: float = 1.37
"""Exponent of the GR-3/8B area curve (design choice) [-]."""

LEAK_VALVE_MAX_AREA: float = 1.66191926293e-05
"""Effective area Cd*A of the GR-3/8B at 20 turns [m^2].

The area through which the orifice law eq. 4.3 passes 1000 l/min (ANR) from 6 bar(g)
to 5 bar(g) at 20 degC: ``l_min_anr_to_kg_s(1000) / orifice_mass_flow(P6, P5, 1.0)``.
Stored as a number so that importing pneufdd compiles nothing; the tests recompute it.
"""


def leak_valve_area(turns: npt.ArrayLike) -> FloatOrArray:
    """Effective orifice area of the GR-3/8B leak valve opened by a number of turns.

    .. math::

        (C_d A)(n) = A_{20}\\,\\max\\!\\left(0, \\frac{n - n_0}{20 - n_0}\\right)^{p}

    with A_20 = :data:`LEAK_VALVE_MAX_AREA` (1000 l/min ANR at 6 -> 5 bar(g)),
    n_0 = 0.3 turn and p = 1.37; see the module notes for the anchors.

    Parameters
    ----------
    turns : float or array_like
        Turns counter-clockwise from fully closed, 0 <= turns <= 20 [turns];
        fractional turns allowed.

    Returns
    -------
    float or ndarray
        Effective area Cd*A [m^2]; 0 for a closed valve.

    Raises
    ------
    InputError
        For negative turns or more than 20.

    Examples
    --------
    >>> from pneufdd.physics.units import bar_gauge_to_pa, kg_s_to_slpm
    >>> round(leak_valve_area(20.0) * 1e6, 2)
    16.62
    >>> [round(kg_s_to_slpm(leak_mass_flow(bar_gauge_to_pa(5.0), leak_valve_area(n))), 1)
    ...  for n in (1, 6)]
    [11.3, 200.0]
    """
    n = as_float_array(turns, "turns")
    require(n, (n >= 0.0) & (n <= LEAK_VALVE_MAX_TURNS), "turns", "0 to 20 turns")
    opening = np.clip(
        (n - LEAK_VALVE_DEAD_TURNS) / (LEAK_VALVE_MAX_TURNS - LEAK_VALVE_DEAD_TURNS), 0.0, 1.0
    )
    return scalar_or_array(LEAK_VALVE_MAX_AREA * opening**LEAK_VALVE_EXPONENT)


def turns_for_area(area: npt.ArrayLike) -> FloatOrArray:
    """Turns of the GR-3/8B that give an effective area, inverse of :func:`leak_valve_area`.

    .. math:: n = n_0 + (20 - n_0)\\,(C_d A / A_{20})^{1/p} \\quad (C_d A > 0)

    Parameters
    ----------
    area : float or array_like
        Effective area Cd*A, 0 <= area <= A_20 [m^2].

    Returns
    -------
    float or ndarray
        Turns from closed [turns]; 0 for zero area.

    Raises
    ------
    InputError
        For a negative area or one larger than the valve's full opening.

    Examples
    --------
    >>> round(turns_for_area(leak_valve_area(3.5)), 9)
    3.5
    """
    a = as_float_array(area, "area")
    require(
        a,
        (a >= 0.0) & (a <= LEAK_VALVE_MAX_AREA * (1.0 + 1e-12)),
        "area",
        f"effective area in [0, {LEAK_VALVE_MAX_AREA:.4g}] m^2 (0 to 20 turns)",
    )
    fraction = np.clip(a / LEAK_VALVE_MAX_AREA, 0.0, 1.0)
    turns = LEAK_VALVE_DEAD_TURNS + (LEAK_VALVE_MAX_TURNS - LEAK_VALVE_DEAD_TURNS) * fraction ** (
        1.0 / LEAK_VALVE_EXPONENT
    )
    return scalar_or_array(np.where(a > 0.0, turns, 0.0))


@njit
def leak_mass_flow_kernel(pressure: float, effective_area: float, T: float) -> float:
    """Leak mass flow to atmosphere; compiled kernel of :func:`leak_mass_flow`.

    Parameters
    ----------
    pressure : float
        Absolute pressure upstream of the leak [Pa].
    effective_area : float
        Effective area Cd*A [m^2].
    T : float
        Gas temperature [K].

    Returns
    -------
    float
        Mass flow out of the system [kg/s]; negative if ``pressure < P_ATM``.
    """
    return orifice_mass_flow_kernel(pressure, P_ATM, effective_area, 1.0, T)


def leak_mass_flow(
    pressure: npt.ArrayLike, effective_area: npt.ArrayLike, T: npt.ArrayLike = T_ROOM
) -> FloatOrArray:
    """Mass flow of a leak to the atmosphere: the orifice law eq. 4.3 with P2 = P_atm.

    .. math:: \\dot m = \\dot m_{orifice}(P, P_{atm}, C_d A, C_d = 1, T)

    Parameters
    ----------
    pressure : float or array_like
        Absolute pressure upstream of the leak [Pa].
    effective_area : float or array_like
        Effective area Cd*A [m^2].
    T : float or array_like
        Gas temperature [K].

    Returns
    -------
    float or ndarray
        Mass flow out of the system [kg/s]; negative (inflow) below atmosphere.

    Examples
    --------
    A 1 mm sharp-edged hole at 6 bar(g):

    >>> from pneufdd.physics.units import bar_gauge_to_pa, kg_s_to_slpm
    >>> round(kg_s_to_slpm(leak_mass_flow(bar_gauge_to_pa(6.0), leak_area(1.0, "mm"))), 1)
    36.8
    """
    return orifice_mass_flow(pressure, P_ATM, effective_area, 1.0, T)


_UNITS = ("turns", "mm", "SLPM")


def leak_area(
    value: npt.ArrayLike, unit: str, reference_pressure: float | None = None
) -> FloatOrArray:
    """Effective area of a leak given in turns, hole diameter or nominal flow.

    * ``"turns"``: GR-3/8B leak valve, :func:`leak_valve_area`;
    * ``"mm"``: sharp-edged hole of that diameter,
      :math:`C_d A = 0.61\\,\\pi d^2/4`;
    * ``"SLPM"``: the area that leaks that flow (0 degC, 1013 mbar basis) to the
      atmosphere at ``reference_pressure``,
      :math:`C_d A = \\dot m / \\dot m_{orifice}(P_{ref}, P_{atm}, 1, 1, 293.15)`.

    Parameters
    ----------
    value : float or array_like
        Leak size in ``unit`` [turns, mm or SLPM]; >= 0.
    unit : {"turns", "mm", "SLPM"}
        Unit of ``value``.
    reference_pressure : float, optional
        Absolute pressure at which the SLPM value holds, > 101325 Pa [Pa];
        required for ``"SLPM"`` and rejected otherwise.

    Returns
    -------
    float or ndarray
        Effective area Cd*A [m^2].

    Raises
    ------
    InputError
        For an unknown unit, a negative size, a missing or needless reference pressure.

    Examples
    --------
    >>> round(leak_area(1.0, "mm") * 1e6, 4)
    0.4791
    >>> from pneufdd.physics.units import bar_gauge_to_pa
    >>> round(leak_area(200.0, "SLPM", reference_pressure=bar_gauge_to_pa(5.0)) * 1e6, 3)
    3.039
    """
    if unit not in _UNITS:
        raise InputError(describe("parameter 'unit'", unit, _UNITS))
    if unit != "SLPM" and reference_pressure is not None:
        raise InputError(
            describe(
                f"parameter 'reference_pressure' with unit {unit!r}", reference_pressure, "None"
            )
        )
    if unit == "turns":
        return leak_valve_area(value)
    size = as_float_array(value, "value")
    require(size, size >= 0.0, "value", f"a leak size >= 0 {unit}")
    if unit == "mm":
        return scalar_or_array(SHARP_EDGE_CD * math.pi / 4.0 * (size * 1e-3) ** 2)
    if reference_pressure is None or not reference_pressure > P_ATM:
        raise InputError(
            describe(
                "parameter 'reference_pressure' for a leak in SLPM",
                reference_pressure,
                "an absolute pressure > 101325 Pa",
            )
        )
    per_area = leak_mass_flow(float(reference_pressure), 1.0)
    return scalar_or_array(slpm_to_kg_s(size) / per_area)


def equivalent_orifice_diameter(
    mass_flow: npt.ArrayLike, pressure: npt.ArrayLike, T: npt.ArrayLike = T_ROOM
) -> FloatOrArray:
    """Diameter of the sharp-edged hole (Cd = 0.61) that leaks a given mass flow.

    .. math:: d = \\sqrt{\\frac{4}{\\pi\\,0.61}\\,
              \\frac{\\dot m}{\\dot m_{orifice}(P, P_{atm}, 1, 1, T)}}

    Parameters
    ----------
    mass_flow : float or array_like
        Leak mass flow, >= 0 [kg/s].
    pressure : float or array_like
        Absolute pressure upstream of the leak, > 101325 Pa [Pa].
    T : float or array_like
        Gas temperature [K].

    Returns
    -------
    float or ndarray
        Equivalent hole diameter [m].

    Examples
    --------
    >>> from pneufdd.physics.units import bar_gauge_to_pa
    >>> p = bar_gauge_to_pa(6.0)
    >>> round(equivalent_orifice_diameter(leak_mass_flow(p, leak_area(1.0, "mm")), p) * 1e3, 9)
    1.0
    """
    m = as_float_array(mass_flow, "mass_flow")
    require(m, m >= 0.0, "mass_flow", "a leak mass flow >= 0 kg/s")
    p = as_float_array(pressure, "pressure")
    require(p, p > P_ATM, "pressure", "an absolute pressure > 101325 Pa")
    area = m / np.asarray(leak_mass_flow(p, 1.0, T))
    return scalar_or_array(np.sqrt(4.0 * area / (math.pi * SHARP_EDGE_CD)))
