"""Piston friction and the piston force balance (dissertation section 4.2.3).

Eq. 4.14 models friction as stick-slip (static) ``Fsf`` at rest and Coulomb plus
viscous ``Fcf + Cvf v`` in motion. Written literally, it switches on ``v == 0``,
which a time integrator never hits exactly: the force chatters between +Fcf and -Fcf.
:func:`friction_force` uses the Karnopp form instead: inside a small velocity band
``|v| < v_stick`` the piston is treated as stuck and friction balances the driving
force up to the breakaway force ``Fsf``; outside the band eq. 4.14's sliding law
applies.

Sign convention (the dissertation's): ``F_f`` is the force *subtracted* from the
driving force, eq. 4.13/4.16, so it is positive when it resists motion towards +x
(extension). The mechanical power friction delivers to the piston is
``-F_f v``; it is never positive while sliding.

Force balance. Eq. 4.13 prints ``P_a - P_b - F_f = (M_L + M_P) x''`` without the
areas. A real cylinder with absolute chamber pressures obeys

.. math::

    P_a A_a - P_b A_b - P_{atm} A_{rod} - F_f = (M_L + M_P)\\ddot x

where ``A_rod = A_a - A_b`` is the rod cross-section on which the atmosphere pushes
(eq. 4.15/4.16 use gauge pressures, which hides that term). :func:`piston_force`
computes the left side without friction.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, eq. 4.13-4.16; Fsf = 150 N, Fcf = 158.6 N,
   Cvf = 17.88 N s/m for the Festo DNC 32.
.. [2] Karnopp, D., Computer simulation of stick-slip friction in mechanical
   dynamic systems, J. Dyn. Sys. Meas. Control 107 (1985) 100-103.
"""

from __future__ import annotations

import numpy.typing as npt

from pneufdd.physics._jit import (
    FloatOrArray,
    as_float_array,
    elementwise,
    njit,
    njit_inline,
    require,
    scalar_or_array,
)
from pneufdd.physics.constants import P_ATM

__all__ = [
    "CVF_DNC",
    "FCF_DNC",
    "FSF_DNC",
    "V_STICK",
    "friction_force",
    "friction_force_kernel",
    "piston_force",
    "piston_force_kernel",
    "piston_net_force_kernel",
    "stick_slip_force_from_pressures",
]

FSF_DNC: float = 150.0
"""Stick-slip (breakaway) friction of the DNC 32, section 4.2.3 [N]."""

FCF_DNC: float = 158.6
"""Coulomb friction of the DNC 32, section 4.2.3 [N]."""

CVF_DNC: float = 17.88
"""Viscous friction coefficient of the DNC 32, section 4.2.3 [N s/m]."""

V_STICK: float = 1e-3
"""Default half-width of the Karnopp stick band [m/s]."""


@njit
def friction_force_kernel(
    velocity: float,
    driving_force: float,
    Fsf: float,
    Fcf: float,
    Cvf: float,
    v_stick: float,
) -> float:
    """Karnopp friction force of eq. 4.14; compiled kernel of :func:`friction_force`.

    Parameters
    ----------
    velocity : float
        Piston velocity [m/s].
    driving_force : float
        Net non-friction force on the piston, e.g. :func:`piston_force` [N].
    Fsf, Fcf : float
        Breakaway and Coulomb friction [N].
    Cvf : float
        Viscous coefficient [N s/m].
    v_stick : float
        Half-width of the stick band [m/s].

    Returns
    -------
    float
        Friction force F_f, subtracted from the driving force [N].
    """
    if abs(velocity) < v_stick:
        if driving_force > Fsf:
            return Fsf
        if driving_force < -Fsf:
            return -Fsf
        return driving_force
    if velocity > 0.0:
        return Fcf + Cvf * velocity
    return -Fcf + Cvf * velocity


_friction_ufunc = elementwise(friction_force_kernel, 6)


def friction_force(
    velocity: npt.ArrayLike,
    driving_force: npt.ArrayLike,
    Fsf: npt.ArrayLike = FSF_DNC,
    Fcf: npt.ArrayLike = FCF_DNC,
    Cvf: npt.ArrayLike = CVF_DNC,
    v_stick: npt.ArrayLike = V_STICK,
) -> FloatOrArray:
    """Piston friction, eq. 4.14 in Karnopp form.

    .. math::

        F_f = \\begin{cases}
            \\operatorname{clip}(F_d, -F_{sf}, F_{sf}), & |\\dot x| < v_{stick}
                \\ \\text{(stick)} \\\\
            \\operatorname{sign}(\\dot x) F_{cf} + C_{vf}\\dot x, & |\\dot x| \\ge v_{stick}
                \\ \\text{(slip)}
        \\end{cases}

    In stick, friction cancels the driving force F_d until it exceeds the breakaway
    force Fsf; the net force ``F_d - F_f`` is then ``F_d - sign(F_d) Fsf``. While
    ``|F_d| <= Fsf`` inside the band the net force is zero, so the velocity stays
    constant there; the integrator should set it to zero on entering the band
    (standard Karnopp practice), otherwise a residual |v| < v_stick drifts the
    piston and friction can then do positive work on it. Note that the published DNC
    values have Fcf = 158.6 N > Fsf = 150 N, unusual (breakaway is normally the
    larger); they are kept as published.

    Parameters
    ----------
    velocity : float or array_like
        Piston velocity x' [m/s].
    driving_force : float or array_like
        Net non-friction force on piston and load, e.g. :func:`piston_force` [N].
    Fsf : float or array_like
        Stick-slip (breakaway) friction, >= 0 [N]; default 150 N (section 4.2.3).
    Fcf : float or array_like
        Coulomb friction, >= 0 [N]; default 158.6 N.
    Cvf : float or array_like
        Viscous friction coefficient, >= 0 [N s/m]; default 17.88 N s/m.
    v_stick : float or array_like
        Half-width of the stick band, > 0 [m/s]; default 1 mm/s.

    Returns
    -------
    float or ndarray
        Friction force F_f, subtracted from the driving force [N].

    Examples
    --------
    >>> friction_force(0.0, 100.0), friction_force(0.0, 400.0)
    (100.0, 150.0)
    >>> round(friction_force(0.25, 400.0), 2)
    163.07
    """
    v = as_float_array(velocity, "velocity")
    f = as_float_array(driving_force, "driving_force")
    params = []
    for name, value in (("Fsf", Fsf), ("Fcf", Fcf), ("Cvf", Cvf)):
        array = as_float_array(value, name)
        require(array, array >= 0.0, name, "a value >= 0")
        params.append(array)
    band = as_float_array(v_stick, "v_stick")
    require(band, band > 0.0, "v_stick", "a velocity > 0 m/s")
    return scalar_or_array(_friction_ufunc(v, f, *params, band))


@njit
def piston_force_kernel(Pa: float, Pb: float, Aa: float, Ab: float) -> float:
    """Net pneumatic force on the piston; compiled kernel of :func:`piston_force`.

    Parameters
    ----------
    Pa, Pb : float
        Absolute pressures in chambers A and B [Pa].
    Aa, Ab : float
        Piston areas on sides A and B [m^2].

    Returns
    -------
    float
        Force towards +x (extension) [N].
    """
    # same as Pa Aa - Pb Ab - P_atm (Aa - Ab), written in gauge form to avoid cancellation
    return (Pa - P_ATM) * Aa - (Pb - P_ATM) * Ab


_piston_ufunc = elementwise(piston_force_kernel, 4)


@njit_inline
def piston_net_force_kernel(Pa: float, Pb: float, Aa: float, Ab: float, A_rod: float) -> float:
    """Net pneumatic force on a piston in absolute pressures, eq. 4.13 with areas.

    .. math:: F = P_a A_a - P_b A_b - P_{atm} A_{rod}

    The form the digital twin uses (its integrator and its ODE right-hand side), with
    the rod area given on its own: an equivalent piston (twin pistons,
    rotary drives) may have ``A_rod != Aa - Ab``. When ``A_rod = Aa - Ab`` it equals
    :func:`piston_force_kernel` up to rounding (that one uses gauge pressures to avoid
    cancellation; the twin keeps this order, so its results stay the same bit for bit).

    Parameters
    ----------
    Pa, Pb : float
        Absolute pressures in chambers A and B [Pa].
    Aa, Ab : float
        Piston areas on sides A and B [m^2].
    A_rod : float
        Rod cross-section on which the atmosphere pushes [m^2].

    Returns
    -------
    float
        Force towards +x (extension), friction not included [N].

    Examples
    --------
    Section 4.2.3: 61.37 psi and 40.22 psi (gauge) in the DNC 32 (32 mm bore,
    12 mm rod) at breakaway, the published 150 N of eq. 4.15:

    >>> import math
    >>> from pneufdd.physics.units import psig_to_pa
    >>> Aa = math.pi / 4 * 0.032**2
    >>> A_rod = math.pi / 4 * 0.012**2
    >>> F = piston_net_force_kernel(psig_to_pa(61.37), psig_to_pa(40.22), Aa, Aa - A_rod, A_rod)
    >>> round(F, 1)
    148.6
    """
    return Pa * Aa - Pb * Ab - P_ATM * A_rod


def piston_force(
    Pa: npt.ArrayLike, Pb: npt.ArrayLike, Aa: npt.ArrayLike, Ab: npt.ArrayLike
) -> FloatOrArray:
    """Net pneumatic force on the piston, the left side of eq. 4.13 with areas.

    .. math:: F = P_a A_a - P_b A_b - P_{atm}(A_a - A_b)

    Parameters
    ----------
    Pa : float or array_like
        Absolute pressure in chamber A (blind side) [Pa].
    Pb : float or array_like
        Absolute pressure in chamber B (rod side) [Pa].
    Aa : float or array_like
        Piston area on side A [m^2].
    Ab : float or array_like
        Annular piston area on side B, Aa minus the rod area [m^2].

    Returns
    -------
    float or ndarray
        Force towards +x (extension) [N].

    Examples
    --------
    Both chambers at atmosphere: no force.

    >>> piston_force(101325.0, 101325.0, 8.0e-4, 6.9e-4)
    0.0
    """
    pa = as_float_array(Pa, "Pa")
    require(pa, pa >= 0.0, "Pa", "absolute pressure >= 0 Pa")
    pb = as_float_array(Pb, "Pb")
    require(pb, pb >= 0.0, "Pb", "absolute pressure >= 0 Pa")
    aa = as_float_array(Aa, "Aa")
    require(aa, aa >= 0.0, "Aa", "area >= 0 m^2")
    ab = as_float_array(Ab, "Ab")
    require(ab, (ab >= 0.0) & (ab <= aa), "Ab", "area in [0, Aa] m^2")
    return scalar_or_array(_piston_ufunc(pa, pb, aa, ab))


def stick_slip_force_from_pressures(
    Pa: npt.ArrayLike, Pb: npt.ArrayLike, Aa: npt.ArrayLike, Ab: npt.ArrayLike
) -> FloatOrArray:
    """Breakaway friction from the chamber pressures at motion onset, eq. 4.15.

    .. math:: F_{sf} = (P_a - P_{atm}) A_a - (P_b - P_{atm}) A_b \\Big|_{t = t_2}

    Eq. 4.15 uses gauge pressures; with absolute pressures that is the net
    pneumatic force :func:`piston_force` at the instant t_2 the piston starts to
    move (acceleration starts, velocity still zero).

    Parameters
    ----------
    Pa : float or array_like
        Absolute pressure in chamber A at motion onset [Pa].
    Pb : float or array_like
        Absolute pressure in chamber B at motion onset [Pa].
    Aa : float or array_like
        Piston area on side A [m^2].
    Ab : float or array_like
        Annular piston area on side B [m^2].

    Returns
    -------
    float or ndarray
        Stick-slip friction force Fsf [N].

    Examples
    --------
    Section 4.2.3: 61.37 psi and 40.22 psi (gauge) in the DNC 32 (32 mm bore,
    12 mm rod) give the published 150 N:

    >>> import math
    >>> from pneufdd.physics.units import psig_to_pa
    >>> Aa = math.pi / 4 * 0.032**2
    >>> Ab = Aa - math.pi / 4 * 0.012**2
    >>> round(stick_slip_force_from_pressures(psig_to_pa(61.37), psig_to_pa(40.22), Aa, Ab), 1)
    148.6
    """
    return piston_force(Pa, Pb, Aa, Ab)
