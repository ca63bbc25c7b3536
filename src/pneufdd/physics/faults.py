"""Faults other than leaks to the atmosphere, and the shop floor's nuisances (issue 34).

The dissertation models leaks only; its future work (section 6.2) names internal
leakage of actuators and valves and faults other than leakage. Each law here is what
the twin (:mod:`pneufdd.sim.kernel`) evaluates for one fault or nuisance; the fault
catalogue that names them, their units and scales is :mod:`pneufdd.sim.faults`
(``docs/faults.md``).

* **Internal leakage** across a piston seal (chamber A <-> chamber B) or a valve spool
  (supply -> port, port -> exhaust) is an orifice, eq. 4.3, between two volumes:
  :func:`seal_leak_mass_flow`. Its size is the effective area Cd*A, given as the
  flow it passes from the nominal supply pressure to the atmosphere
  (:func:`pneufdd.physics.leaks.leak_area`), the test condition of a seal.
* **Meter-out throttle** (a turned screw, clogging): the throttle's Cv scales,
  :func:`throttled_cv`; the exhaust path follows the series rule
  (:func:`pneufdd.physics.flow.series_cv`) and eq. 4.6 is linear in Cv.
* **Friction** (seal wear, lost lubrication): eq. 4.14's breakaway and Coulomb
  terms scale or grow, :func:`worn_friction`.
* **A valve whose pilot needs more pressure** (a stiff or sticking spool): it shifts
  later, the less the supply exceeds what its pilot needs,
  :func:`pilot_delay_factor_kernel`.
* **End-position cushioning** (Festo PPV): over the last ``length`` of the stroke a
  cushioning spigot closes the main exhaust port and the air leaves through the
  adjustable cushion screw only; filling passes freely (the cushion seal is a check
  valve). :func:`cushion_engaged_kernel`, :func:`cushioned_exhaust_cv`.
* **Regulator set-point drift**: :func:`regulator_outlet_pressure_kernel`.
* **Ambient temperature** (nuisance): the gas laws take the temperature as it is; the
  seal friction changes with it, :func:`seal_friction_temperature_factors` (the
  viscous term through the grease's viscosity, ASTM D341, and the seal film's
  inverse hydrodynamics).
* **Supply header dips** from other consumers (nuisance): :func:`header_dip_kernel`.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, eq. 4.3, 4.6, 4.14-4.16, section 6.2.
.. [2] Festo, "Adjustable pneumatic cushioning PPV": the throttling port is
   adjustable and constant along the cushioning length; the cushioning length is
   constant (M. Guelker, Festo USA, "Properly adjusted air cushion", NFPA blog, part
   3); the exhaust air is blocked off in the last centimetres of the stroke and
   released only via a flow control point (Festo FAQ on end-position cushioning).
.. [3] ASTM D341, Standard practice for viscosity-temperature charts for liquid
   petroleum products (the Walther equation).
.. [4] ISO 3448, Industrial liquid lubricants - ISO viscosity classification
   (VG 32: 28.8-35.2 mm^2/s at 40 degC).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from pneufdd.errors import InputError, describe
from pneufdd.physics._jit import (
    FloatOrArray,
    as_float_array,
    njit_inline,
    require,
    scalar_or_array,
)
from pneufdd.physics.constants import KELVIN_OFFSET, T_ROOM
from pneufdd.physics.flow import orifice_mass_flow
from pneufdd.physics.restrictions import series_cv

__all__ = [
    "BASE_OIL_NU40",
    "BASE_OIL_NU100",
    "COULOMB_TEMPERATURE_COEFFICIENT",
    "CUSHION_LENGTH_DNC32_MM",
    "PILOT_MIN_NOMINAL_PA",
    "cushion_engaged_kernel",
    "cushioned_exhaust_cv",
    "header_dip_kernel",
    "header_dip_profile",
    "lubricant_viscosity_ratio",
    "pilot_delay_factor_kernel",
    "regulator_outlet_pressure_kernel",
    "seal_friction_temperature_factors",
    "seal_leak_mass_flow",
    "throttled_cv",
    "worn_friction",
]

CUSHION_LENGTH_DNC32_MM: float = 20.0
"""Cushioning length of a Festo DNC-32 with PPV (datasheet) [mm]: the rig's
``DNC-32-200-PPV-A`` (Table 3.1). The twin's default for an actuator whose
description gives none (capped at a quarter of the stroke)."""

BASE_OIL_NU40: float = 32.0
"""Kinematic viscosity at 40 degC of the seal grease's base oil, ISO VG 32 (ISO 3448
mid-point) [mm^2/s]: an assumption, cylinder greases are not specified further."""

BASE_OIL_NU100: float = 5.44
"""Kinematic viscosity at 100 degC of that oil for a viscosity index of about 100
(ASTM D2270 tables for a VG 32 mineral oil) [mm^2/s]."""

PILOT_MIN_NOMINAL_PA: float = 3.0e5
"""Lowest operating pressure of a healthy piloted valve, the CPE14's 3 bar (Fig. 4.3)
[Pa gauge]."""

COULOMB_TEMPERATURE_COEFFICIENT: float = -0.005
"""Relative change of the breakaway and Coulomb friction per kelvin [1/K]: an
engineering assumption (``docs/assumptions.md``). Festo states only that breakaway
friction rises in the cold (grease more viscous, seals less elastic); Nguyen and
Pham (2021) measured the static friction of an industrial cylinder falling as the
temperature rose from 15 to 49 degC, with no coefficient published in a form kept
here. -0.5 %/K moves the friction by 10 % over a 15 -> 35 degC shift."""


def seal_leak_mass_flow(
    P1: npt.ArrayLike,
    P2: npt.ArrayLike,
    effective_area: npt.ArrayLike,
    T1: npt.ArrayLike = T_ROOM,
    T2: npt.ArrayLike = T_ROOM,
) -> FloatOrArray:
    """Internal leakage between two volumes: the orifice law eq. 4.3, signed.

    .. math::

        \\dot m_{1 \\to 2} = \\begin{cases}
            \\dot m_{orifice}(P_1, P_2, C_d A, 1, T_1), & P_1 \\ge P_2 \\\\
            -\\dot m_{orifice}(P_2, P_1, C_d A, 1, T_2), & P_1 < P_2
        \\end{cases}

    A worn piston seal joins chamber A and chamber B of a cylinder, a worn valve spool
    the supply and a port, or a port and the exhaust. Air flows from the higher
    pressure to the lower and carries its upstream temperature; what one volume loses
    the other gains, so the supply sees a piston-seal leak only through the chamber
    it refills.

    Parameters
    ----------
    P1, P2 : float or array_like
        Absolute pressures of the two volumes [Pa].
    effective_area : float or array_like
        Effective area Cd*A of the leak path [m^2].
    T1, T2 : float or array_like
        Gas temperatures of the two volumes [K].

    Returns
    -------
    float or ndarray
        Mass flow from volume 1 to volume 2 [kg/s]; negative when ``P2 > P1``.

    Examples
    --------
    A seal leak sized at 20 SLPM from 72 psig to the atmosphere, between chambers at
    72 psig and 40 psig:

    >>> from pneufdd.physics.leaks import leak_area
    >>> from pneufdd.physics.units import kg_s_to_slpm, psig_to_pa
    >>> area = leak_area(20.0, "SLPM", reference_pressure=psig_to_pa(72.0))
    >>> round(kg_s_to_slpm(seal_leak_mass_flow(psig_to_pa(72.0), psig_to_pa(40.0), area)), 2)
    19.53
    >>> round(kg_s_to_slpm(seal_leak_mass_flow(psig_to_pa(40.0), psig_to_pa(72.0), area)), 2)
    -19.53
    """
    p1 = as_float_array(P1, "P1")
    p2 = as_float_array(P2, "P2")
    t1 = as_float_array(T1, "T1")
    t2 = as_float_array(T2, "T2")
    forward = p1 >= p2
    upstream_t = np.where(forward, t1, t2)
    flow = np.asarray(
        orifice_mass_flow(np.maximum(p1, p2), np.minimum(p1, p2), effective_area, 1.0, upstream_t)
    )
    return scalar_or_array(np.where(forward, flow, -flow))


def throttled_cv(cv: npt.ArrayLike, change_percent: npt.ArrayLike) -> FloatOrArray:
    """Flow coefficient of a throttle whose setting changed by ``change_percent``.

    .. math:: C_v' = C_v \\left(1 + \\frac{\\Delta}{100}\\right)

    A needle valve turned in or clogged passes less (``change_percent < 0``), one
    turned out more. At fixed pressures eq. 4.6 is linear in Cv, so the throttle alone
    passes ``1 + change/100`` times the flow; in series with the valve and the tube
    (:func:`pneufdd.physics.flow.series_cv`) the path's flow changes less.

    Parameters
    ----------
    cv : float or array_like
        The throttle's flow coefficient as commissioned, > 0 [US gal/(min psi^0.5)].
    change_percent : float or array_like
        Change of its flow coefficient, > -100 [%].

    Returns
    -------
    float or ndarray
        The throttle's flow coefficient now [US gal/(min psi^0.5)].

    Examples
    --------
    The DNC's meter-out throttle (Cv 0.125) closed by 40 %, and the exhaust path with
    the CPE14 valve (Cv 0.3971) and its 0.5 m PUN-6x1 tube (Cv 0.3236):

    >>> round(throttled_cv(0.125, -40.0), 4)
    0.075
    >>> round(series_cv(0.3971, 0.3236, throttled_cv(0.125, -40.0)), 4)
    0.0719
    """
    c = as_float_array(cv, "cv")
    require(c, c > 0.0, "cv", "a flow coefficient > 0")
    change = as_float_array(change_percent, "change_percent")
    require(change, change > -100.0, "change_percent", "a change > -100 % (a shut throttle)")
    return scalar_or_array(c * (1.0 + change / 100.0))


def worn_friction(
    Fsf: float, Fcf: float, change_percent: float = 0.0, added_n: float = 0.0
) -> tuple[float, float]:
    """Breakaway and Coulomb friction of a worn or dry seal (eq. 4.14 terms).

    .. math:: F' = F \\left(1 + \\frac{\\Delta}{100}\\right) + \\Delta F

    Wear roughens the seal lip and the barrel, lost lubrication turns mixed friction
    into boundary friction: both raise the friction at rest and in motion. The two
    terms change together (one seal), the viscous term (the lubricant film) stays.

    Parameters
    ----------
    Fsf, Fcf : float
        Breakaway and Coulomb friction as described [N].
    change_percent : float
        Relative change, > -100 [%].
    added_n : float
        Force added to both [N].

    Returns
    -------
    (float, float)
        Breakaway and Coulomb friction of the faulty seal [N].

    Raises
    ------
    InputError
        If the result would be negative.

    Examples
    --------
    The DNC (section 4.2.3: 150 N, 158.6 N) with 50 % more friction:

    >>> worn_friction(150.0, 158.6, change_percent=50.0)
    (225.0, 237.89999999999998)
    """
    if not (math.isfinite(change_percent) and change_percent > -100.0):
        raise InputError(describe("friction change [%]", change_percent, "> -100 %"))
    if not math.isfinite(added_n):
        raise InputError(describe("friction added [N]", added_n, "a finite force"))
    scale = 1.0 + change_percent / 100.0
    fs, fc = Fsf * scale + added_n, Fcf * scale + added_n
    if fs < 0.0 or fc < 0.0:
        raise InputError(
            describe("friction after the change [N]", (fs, fc), "forces >= 0 (remove less)")
        )
    return fs, fc


def _walther(nu: float) -> float:
    return math.log10(math.log10(nu + 0.7))


def lubricant_viscosity_ratio(
    T: npt.ArrayLike,
    T_ref: float,
    nu40: float = BASE_OIL_NU40,
    nu100: float = BASE_OIL_NU100,
) -> FloatOrArray:
    """Kinematic viscosity of a mineral oil at ``T`` relative to ``T_ref`` (ASTM D341).

    .. math::

        \\log_{10}\\log_{10}(\\nu + 0.7) = A - B \\log_{10} T

    (the Walther equation, :math:`\\nu` in mm^2/s, T in K) through the oil's
    viscosities at 40 and 100 degC: the base oil of the grease in the seal's film
    (:func:`seal_friction_temperature_factors`).

    Parameters
    ----------
    T : float or array_like
        Temperature, 223.15-423.15 K [K].
    T_ref : float
        Reference temperature [K].
    nu40, nu100 : float
        The oil's kinematic viscosity at 40 and 100 degC, ``nu40 > nu100 > 0`` [mm^2/s].

    Returns
    -------
    float or ndarray
        ``nu(T) / nu(T_ref)`` [-].

    Examples
    --------
    The law returns its data points (ISO VG 32, about 100 viscosity index), and the
    viscosity at 15 degC against 35 degC:

    >>> round(lubricant_viscosity_ratio(313.15, 373.15), 4), round(32.0 / 5.44, 4)
    (5.8824, 5.8824)
    >>> round(lubricant_viscosity_ratio(288.15, 308.15), 3)
    2.896
    """
    if not (nu40 > nu100 > 0.0 and math.isfinite(nu40)):
        raise InputError(
            describe("oil viscosities (nu40, nu100)", (nu40, nu100), "nu40 > nu100 > 0")
        )
    t = as_float_array(T, "T")
    require(t, (t >= 223.15) & (t <= 423.15), "T", "a temperature from -50 to 150 degC")
    if not 223.15 <= T_ref <= 423.15:
        raise InputError(describe("T_ref", T_ref, "a temperature from -50 to 150 degC [K]"))
    t40, t100 = 40.0 + KELVIN_OFFSET, 100.0 + KELVIN_OFFSET
    b = (_walther(nu40) - _walther(nu100)) / (math.log10(t100) - math.log10(t40))
    a = _walther(nu40) + b * math.log10(t40)

    def nu(temperature: npt.ArrayLike) -> npt.NDArray[np.float64]:
        return np.asarray(10.0 ** (10.0 ** (a - b * np.log10(temperature))) - 0.7)

    return scalar_or_array(nu(t) / nu(T_ref))


def seal_friction_temperature_factors(
    T: float,
    T_ref: float,
    coulomb_per_k: float = COULOMB_TEMPERATURE_COEFFICIENT,
) -> tuple[float, float]:
    """Factors on the friction terms of eq. 4.14 at temperature ``T``.

    .. math::

        \\frac{F_{sf}(T)}{F_{sf}(T_r)} = \\frac{F_{cf}(T)}{F_{cf}(T_r)}
            = e^{\\alpha (T - T_r)}, \\qquad
        \\frac{C_{vf}(T)}{C_{vf}(T_r)} = \\sqrt{\\frac{\\nu(T)}{\\nu(T_r)}}

    The breakaway and Coulomb terms follow the exponential law with coefficient
    ``alpha`` (:data:`COULOMB_TEMPERATURE_COEFFICIENT`, an assumption). The viscous
    term is the shear of the grease film under the reciprocating seal: by the
    inverse hydrodynamic theory of such seals (Blok 1963; Mueller and Nau, *Fluid
    Sealing Technology*, 1998) the film is ``h ~ sqrt(eta U / (dp/dx)_max)`` thick, so
    its shear force ``eta U / h`` grows as ``sqrt(eta U)``: at a given speed with the
    square root of the base oil's viscosity (:func:`lubricant_viscosity_ratio`; the
    twin keeps eq. 4.14's term linear in the speed). ``T_ref`` is the temperature at
    which the description's friction holds (its ``temperature_c``).

    Parameters
    ----------
    T : float
        Seal (ambient) temperature [K].
    T_ref : float
        Temperature of the described friction [K].
    coulomb_per_k : float
        Relative change of the breakaway and Coulomb friction per kelvin, -0.05 to
        0.05 [1/K].

    Returns
    -------
    (float, float)
        Factor on ``Fsf`` and ``Fcf``, factor on ``Cvf`` [-].

    Examples
    --------
    At 35 degC a seal described at 20 degC:

    >>> [round(f, 3) for f in seal_friction_temperature_factors(308.15, 293.15)]
    [0.928, 0.682]
    """
    if not (math.isfinite(coulomb_per_k) and abs(coulomb_per_k) <= 0.05):
        raise InputError(
            describe("friction change per kelvin", coulomb_per_k, "-0.05 to 0.05 [1/K]")
        )
    coulomb = math.exp(coulomb_per_k * (T - T_ref))
    return coulomb, math.sqrt(float(lubricant_viscosity_ratio(T, T_ref)))


@njit_inline
def pilot_delay_factor_kernel(p_supply: float, p_min_nominal: float, p_min: float) -> float:
    """Factor on a piloted valve's switching-on time when its pilot needs ``p_min``.

    .. math::

        \\frac{t_{on}}{t_{on,0}} = \\sqrt{\\frac{p_s - p_{min,0}}{p_s - p_{min}}}
        \\quad (p_s > p_{min}), \\qquad \\infty \\quad (p_s \\le p_{min})

    The pilot pushes the spool with ``A (p_s - p_min)``, the net of the supply
    pressure on the pilot piston and what holds the spool (spring, seal friction); a
    mass pushed over its stroke ``s`` by a constant force takes
    ``sqrt(2 m s / F)``. A healthy valve (``p_min = p_min,0``, the datasheet's lowest
    operating pressure) has the datasheet's switching time (Fig. 4.3: 20 ms on); a
    stiff or sticking spool needs more pressure and shifts later, not at all while the
    supply is below ``p_min``. Pressures are gauge.

    Parameters
    ----------
    p_supply : float
        Supply (pilot) pressure now, gauge [Pa].
    p_min_nominal : float
        Lowest operating pressure of the healthy valve, gauge [Pa].
    p_min : float
        Pressure the faulty pilot needs, gauge [Pa]; <= ``p_min_nominal``: healthy.

    Returns
    -------
    float
        Factor on the switching-on time [-]; ``inf`` while the valve cannot shift.

    Examples
    --------
    The rig's 72 psig (4.96 bar) supply and a pilot needing 4.6 bar instead of 3 bar:

    >>> round(pilot_delay_factor_kernel(4.96e5, 3.0e5, 4.6e5), 3)
    2.333
    >>> pilot_delay_factor_kernel(4.96e5, 3e5, 2e5), pilot_delay_factor_kernel(4.5e5, 3e5, 4.6e5)
    (1.0, inf)
    """
    if p_min <= p_min_nominal:
        return 1.0
    if p_supply <= p_min:
        return math.inf
    return math.sqrt((p_supply - p_min_nominal) / (p_supply - p_min))


@njit_inline
def cushion_engaged_kernel(x: float, stroke: float, length: float, side: float) -> bool:
    """Whether the cushion of a chamber throttles its exhaust at piston position ``x``.

    Chamber A (``side`` 0.0) is cushioned in the last ``length`` before the home end
    (``x < length``), chamber B (``side`` 1.0) before the extended end
    (``x > stroke - length``). A length of 0 means no cushioning.

    Parameters
    ----------
    x : float
        Piston position from the home end [m].
    stroke : float
        Stroke [m].
    length : float
        Cushioning length [m].
    side : float
        0.0 for chamber A, 1.0 for chamber B.

    Returns
    -------
    bool
        True where the cushion spigot has closed the main exhaust port.

    Examples
    --------
    >>> cushion_engaged_kernel(0.195, 0.2, 0.02, 1.0), cushion_engaged_kernel(0.1, 0.2, 0.02, 1.0)
    (True, False)
    """
    if length <= 0.0:
        return False
    if side == 0.0:
        return x < length
    return x > stroke - length


def cushioned_exhaust_cv(exhaust_cv: float, cushion_cv: float) -> float:
    """Flow coefficient of a chamber's exhaust while its cushion is engaged.

    .. math:: \\frac{1}{C_{v}'^2} = \\frac{1}{C_{v,exhaust}^2} + \\frac{1}{C_{v,cushion}^2}

    The cushion screw is in series with the rest of the exhaust path (valve, tube,
    meter-out throttle).

    Parameters
    ----------
    exhaust_cv : float
        Flow coefficient of the exhaust path, > 0 [US gal/(min psi^0.5)].
    cushion_cv : float
        Flow coefficient of the cushion screw, > 0 [US gal/(min psi^0.5)].

    Returns
    -------
    float
        Flow coefficient of the cushioned exhaust [US gal/(min psi^0.5)].

    Examples
    --------
    >>> round(cushioned_exhaust_cv(0.11, 0.01), 5)
    0.00996
    """
    if not (exhaust_cv > 0.0 and cushion_cv > 0.0):
        raise InputError(
            describe("exhaust and cushion flow coefficients", (exhaust_cv, cushion_cv), "> 0")
        )
    return series_cv(exhaust_cv, cushion_cv)


@njit_inline
def regulator_outlet_pressure_kernel(
    p_set: float, effect: float, p_house: float, p_house_nominal: float, offset: float
) -> float:
    """Pressure a non-relieving regulator delivers from house air at ``p_house`` [Pa].

    .. math:: P_{out} = \\min(P_{set} + e\\,(P_{house} - P_{house,nom}) + \\Delta P_{set},\\
              P_{house})

    The supply-pressure effect ``e`` passes a part of the house pressure's variation;
    ``offset`` is a drift of the set point (a regulator whose spring relaxed, a knob
    turned); the regulator cannot deliver more than its inlet pressure.

    Parameters
    ----------
    p_set : float
        Set point, absolute [Pa].
    effect : float
        Supply-pressure effect [-].
    p_house : float
        House (inlet) pressure now, absolute [Pa].
    p_house_nominal : float
        House pressure at which the set point holds, absolute [Pa].
    offset : float
        Drift of the set point [Pa].

    Returns
    -------
    float
        Outlet pressure, absolute [Pa].

    Examples
    --------
    >>> regulator_outlet_pressure_kernel(5.0e5, 0.08, 6.0e5, 7.0e5, -0.3e5)
    462000.0
    """
    p = p_set + effect * (p_house - p_house_nominal) + offset
    if p > p_house:
        p = p_house
    return p


@njit_inline
def header_dip_kernel(t: float, start: float, duration: float, depth: float) -> float:
    """Pressure drop of the house header during another consumer's demand [Pa].

    .. math:: \\Delta P(t) = D \\sin\\left(\\pi \\frac{t - t_0}{\\tau}\\right),
              \\quad t_0 \\le t \\le t_0 + \\tau

    A half sine of depth ``D`` and duration ``tau``: the header pressure falls while a
    large consumer on the same line (a blow-off, a machine starting) draws air, and
    recovers as the compressor catches up (eq. 4.20: the larger current through the
    shared resistance lowers the pressure downstream).

    Parameters
    ----------
    t : float
        Time [s].
    start : float
        Start of the dip [s].
    duration : float
        Duration, > 0 [s].
    depth : float
        Largest pressure drop [Pa].

    Returns
    -------
    float
        Pressure drop at ``t`` (0 outside the dip) [Pa].

    Examples
    --------
    >>> header_dip_kernel(11.0, 10.0, 2.0, 30000.0), header_dip_kernel(13.0, 10.0, 2.0, 30000.0)
    (30000.0, 0.0)
    """
    if t < start or t > start + duration:
        return 0.0
    return depth * math.sin(math.pi * (t - start) / duration)


def header_dip_profile(
    times: npt.ArrayLike,
    starts: npt.ArrayLike,
    durations: npt.ArrayLike,
    depths: npt.ArrayLike,
) -> npt.NDArray[np.float64]:
    """Total pressure drop of overlapping dips at ``times`` [Pa].

    Parameters
    ----------
    times : array_like
        Times [s].
    starts, durations, depths : array_like
        One entry per dip: start [s], duration (> 0) [s] and depth [Pa].

    Returns
    -------
    ndarray
        Sum of the dips' pressure drops at each time [Pa].

    Examples
    --------
    >>> header_dip_profile([0.5, 1.0, 2.5], [0.0, 2.0], [1.0, 1.0], [1e4, 2e4]).round(3).tolist()
    [10000.0, 0.0, 20000.0]
    """
    t = np.asarray(times, dtype=np.float64)
    s = np.asarray(starts, dtype=np.float64).reshape(-1)
    d = np.asarray(durations, dtype=np.float64).reshape(-1)
    depth = np.asarray(depths, dtype=np.float64).reshape(-1)
    if not (s.size == d.size == depth.size) or np.any(d <= 0.0):
        raise InputError(
            describe("header dips (starts, durations, depths)", (s.size, d.size, depth.size),
                     "equal counts and durations > 0 [s]")
        )  # fmt: skip
    total = np.zeros(t.shape)
    for start, duration, dip in zip(s, d, depth, strict=True):
        inside = (t >= start) & (t <= start + duration)
        total[inside] += dip * np.sin(np.pi * (t[inside] - start) / duration)
    return total
