"""Mass flow of air through orifices and valves (dissertation section 4.2.1).

Three laws are provided, each as a compiled scalar kernel (for the simulator's own
numba code) and as a public array function wrapping that kernel:

* :func:`orifice_mass_flow` - compressible flow through a fixed orifice, eq. 4.2-4.3;
* :func:`iso6358_mass_flow` - sonic conductance ``C`` and critical ratio ``b``,
  eq. 4.5 (ISO 6358-1:2013, JIS B 8390);
* :func:`isa_mass_flow` - flow coefficient ``Cv`` and pressure differential ratio
  factor ``xT``, eq. 4.6 (ANSI/ISA-75.01.01, IEC 60534-2-1).

All three are signed (reverse flow when ``P2 > P1``), zero at equal pressures,
continuous at every regime border and have a finite slope ``d(flow)/dP2`` as
``P2 -> P1``. The last property comes from the laminar branch of ISO 6358-1:2013:
above the pressure ratio :data:`LAMINAR_RATIO` = 0.999 the flow is taken linear in
``1 - P2/P1`` and matched continuously to the turbulent law at the border. The
square-root laws alone have an infinite slope at equal pressures, which stalls the
stiff integrator of the digital twin.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, Stony Brook University, eq. 4.2-4.6.
.. [2] ISO 6358-1:2013, Pneumatic fluid power - Determination of flow-rate
   characteristics of components using compressible fluids - Part 1.
.. [3] ANSI/ISA-75.01.01-2007 (IEC 60534-2-1 mod), Flow equations for sizing
   control valves, gas equation with N7 = 1360.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from pneufdd.errors import InputError, describe
from pneufdd.physics._jit import (
    FloatOrArray,
    as_float_array,
    elementwise,
    njit,
    njit_inline,
    require,
    scalar_or_array,
)
from pneufdd.physics.constants import ANR, FT3, GAMMA_AIR, ISA_STANDARD, PSI, R_AIR, T_ROOM

__all__ = [
    "CRITICAL_RATIO",
    "DM3_PER_S_BAR",
    "ISA_N7_SCFM",
    "LAMINAR_RATIO",
    "critical_pressure_ratio",
    "isa_mass_flow",
    "isa_mass_flow_kernel",
    "iso6358_mass_flow",
    "iso6358_mass_flow_kernel",
    "orifice_mass_flow",
    "orifice_mass_flow_kernel",
    "sonic_conductance_from_catalogue",
]

LAMINAR_RATIO: float = 0.999
"""Pressure ratio P2/P1 above which flow is laminar (linear), ISO 6358-1:2013 [-]."""

_K = GAMMA_AIR
CRITICAL_RATIO: float = (2.0 / (_K + 1.0)) ** (_K / (_K - 1.0))
"""Critical pressure ratio of air, eq. 4.2 with k = 1.4: 0.5283 [-]."""

_C1 = math.sqrt(_K / R_AIR * (2.0 / (_K + 1.0)) ** ((_K + 1.0) / (_K - 1.0)))
_C2 = math.sqrt(2.0 * _K / (R_AIR * (_K - 1.0)))

DM3_PER_S_BAR: float = 1e-3 / 1e5
"""One catalogue unit of sonic conductance, 1 dm^3/(s bar), in SI [m^3/(s Pa)]."""

ISA_N7_SCFM: float = 1360.0 / 60.0
"""ISA-75.01 constant N7 = 1360 scfh (psia, degR) per minute: 22.67 [scfm/(psia)]."""

_RANKINE_PER_KELVIN = 1.8
_RHO0 = ANR.density
_T0 = ANR.temperature
_ISA_MASS_PER_SCFM = FT3 / 60.0 * ISA_STANDARD.density


def critical_pressure_ratio(k: float = GAMMA_AIR) -> float:
    """Critical pressure ratio at which an orifice chokes, eq. 4.2.

    .. math:: P_{cr} = \\left(\\frac{2}{k+1}\\right)^{k/(k-1)}

    Parameters
    ----------
    k : float
        Ratio of specific heats [-]; must exceed 1.

    Returns
    -------
    float
        Critical ratio of downstream to upstream absolute pressure [-].

    Examples
    --------
    >>> round(critical_pressure_ratio(1.4), 4)
    0.5283
    """
    if not (math.isfinite(k) and k > 1.0):
        raise InputError(describe("parameter 'k'", k, "a finite number > 1"))
    return float((2.0 / (k + 1.0)) ** (k / (k - 1.0)))


# ---------------------------------------------------------------------------
# Compressible orifice, eq. 4.2-4.3
# ---------------------------------------------------------------------------


@njit_inline
def _orifice_turbulent(r: float) -> float:
    # Mass flux factor of eq. 4.3 per unit C_D A P1 / sqrt(T) [sqrt(kg K/J)].
    if r <= CRITICAL_RATIO:
        return _C1
    return float(_C2 * r ** (1.0 / _K) * math.sqrt(1.0 - r ** ((_K - 1.0) / _K)))


@njit_inline
def _orifice_forward(P1: float, P2: float, area: float, Cd: float, T: float) -> float:
    if P1 <= 0.0:
        return 0.0
    r = P2 / P1
    scale = Cd * area * P1 / math.sqrt(T)
    if r <= LAMINAR_RATIO:
        return scale * _orifice_turbulent(r)
    return scale * _orifice_turbulent(LAMINAR_RATIO) * (1.0 - r) / (1.0 - LAMINAR_RATIO)


@njit
def orifice_mass_flow_kernel(P1: float, P2: float, area: float, Cd: float, T: float) -> float:
    """Signed orifice mass flow, compiled scalar kernel of :func:`orifice_mass_flow`.

    Parameters
    ----------
    P1, P2 : float
        Absolute pressures at the two ports [Pa]; positive flow goes 1 -> 2.
    area : float
        Geometric orifice area [m^2].
    Cd : float
        Discharge coefficient [-].
    T : float
        Upstream gas temperature [K].

    Returns
    -------
    float
        Mass flow from port 1 to port 2 [kg/s].
    """
    if P1 >= P2:
        return _orifice_forward(P1, P2, area, Cd, T)
    return -_orifice_forward(P2, P1, area, Cd, T)


_orifice_ufunc = elementwise(orifice_mass_flow_kernel, 5)


def _pressures(P1: npt.ArrayLike, P2: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    p1 = as_float_array(P1, "P1")
    p2 = as_float_array(P2, "P2")
    require(p1, p1 >= 0.0, "P1", "absolute pressure >= 0 Pa")
    require(p2, p2 >= 0.0, "P2", "absolute pressure >= 0 Pa")
    return p1, p2


def _temperature(T: npt.ArrayLike) -> np.ndarray:
    t = as_float_array(T, "T")
    require(t, t > 0.0, "T", "absolute temperature > 0 K")
    return t


def orifice_mass_flow(
    P1: npt.ArrayLike,
    P2: npt.ArrayLike,
    area: npt.ArrayLike,
    Cd: npt.ArrayLike = 1.0,
    T: npt.ArrayLike = T_ROOM,
) -> FloatOrArray:
    """Mass flow of air through a fixed orifice, eq. 4.2-4.3 with a laminar branch.

    .. math::

        \\dot m = \\begin{cases}
            C_D A C_1 \\dfrac{P_1}{\\sqrt T}, & r \\le P_{cr} \\\\
            C_D A C_2 \\dfrac{P_1}{\\sqrt T}\\, r^{1/k}\\sqrt{1 - r^{(k-1)/k}},
                & P_{cr} < r \\le r_{lam} \\\\
            \\dot m(r_{lam})\\, \\dfrac{1 - r}{1 - r_{lam}}, & r > r_{lam}
        \\end{cases}

    with :math:`r = P_2/P_1`, :math:`C_1 = \\sqrt{k/R\\,(2/(k+1))^{(k+1)/(k-1)}}`,
    :math:`C_2 = \\sqrt{2k/(R(k-1))}`, :math:`P_{cr}` from eq. 4.2 (0.528 for k = 1.4)
    and :math:`r_{lam}` = :data:`LAMINAR_RATIO` = 0.999. The third (laminar) branch
    is the regularisation of ISO 6358-1:2013 applied to the orifice law: it keeps
    d(flow)/dP2 finite at equal pressures and joins the turbulent law continuously.
    For ``P2 > P1`` the ports are swapped and the flow negated.

    Parameters
    ----------
    P1 : float or array_like
        Absolute pressure at port 1 [Pa].
    P2 : float or array_like
        Absolute pressure at port 2 [Pa].
    area : float or array_like
        Geometric orifice area A [m^2]; pass an effective area C_D A with Cd = 1.
    Cd : float or array_like
        Discharge coefficient C_D [-]; 1 for an ideal nozzle, 0.61 for a sharp edge.
    T : float or array_like
        Upstream gas temperature [K].

    Returns
    -------
    float or ndarray
        Mass flow from port 1 to port 2 [kg/s]; negative when ``P2 > P1``.

    Raises
    ------
    InputError
        For negative pressures, area or Cd, a non-positive temperature, NaN or inf.

    Examples
    --------
    A 1/4 in ideal orifice at 90 psig discharging to atmosphere (Figure 1.2 row 90,
    column 1/4 lists 92 cfm; the ideal value is 95.2 scfm):

    >>> from pneufdd.physics.units import kg_s_to_scfm, psig_to_pa
    >>> import math
    >>> area = math.pi / 4 * (0.25 * 0.0254) ** 2
    >>> m = orifice_mass_flow(psig_to_pa(90.0), 101325.0, area)
    >>> round(m, 5), round(kg_s_to_scfm(m), 1)
    (0.05396, 95.2)
    """
    p1, p2 = _pressures(P1, P2)
    a = as_float_array(area, "area")
    require(a, a >= 0.0, "area", "area >= 0 m^2")
    cd = as_float_array(Cd, "Cd")
    require(cd, cd >= 0.0, "Cd", "discharge coefficient >= 0")
    return scalar_or_array(_orifice_ufunc(p1, p2, a, cd, _temperature(T)))


# ---------------------------------------------------------------------------
# ISO 6358, eq. 4.5
# ---------------------------------------------------------------------------


@njit
def _iso6358_turbulent(r: float, b: float) -> float:
    if r <= b:
        return 1.0
    z = (r - b) / (1.0 - b)
    return math.sqrt(1.0 - z * z)


@njit
def _iso6358_forward(P1: float, P2: float, C: float, b: float, T: float) -> float:
    if P1 <= 0.0:
        return 0.0
    r = P2 / P1
    choked = _RHO0 * C * P1 * math.sqrt(_T0 / T)
    if r <= LAMINAR_RATIO:
        return choked * _iso6358_turbulent(r, b)
    return choked * _iso6358_turbulent(LAMINAR_RATIO, b) * (1.0 - r) / (1.0 - LAMINAR_RATIO)


@njit
def iso6358_mass_flow_kernel(P1: float, P2: float, C: float, b: float, T: float) -> float:
    """Signed ISO 6358 mass flow, compiled scalar kernel of :func:`iso6358_mass_flow`.

    Parameters
    ----------
    P1, P2 : float
        Absolute pressures at the two ports [Pa]; positive flow goes 1 -> 2.
    C : float
        Sonic conductance referred to ANR [m^3/(s Pa)].
    b : float
        Critical pressure ratio, 0 <= b < 0.999 [-].
    T : float
        Upstream gas temperature [K].

    Returns
    -------
    float
        Mass flow from port 1 to port 2 [kg/s].
    """
    if P1 >= P2:
        return _iso6358_forward(P1, P2, C, b, T)
    return -_iso6358_forward(P2, P1, C, b, T)


_iso6358_ufunc = elementwise(iso6358_mass_flow_kernel, 5)


def sonic_conductance_from_catalogue(C_catalogue: npt.ArrayLike) -> FloatOrArray:
    """Convert a catalogue sonic conductance in dm^3/(s bar) to SI.

    .. math:: 1\\ \\mathrm{dm^3/(s\\,bar)} = 10^{-3}\\,\\mathrm{m^3/s} / 10^5\\,\\mathrm{Pa}
              = 10^{-8}\\ \\mathrm{m^3/(s\\,Pa)}

    Parameters
    ----------
    C_catalogue : float or array_like
        Sonic conductance as catalogues print it, ANR basis [dm^3/(s bar)].

    Returns
    -------
    float or ndarray
        Sonic conductance [m^3/(s Pa)].

    Examples
    --------
    >>> sonic_conductance_from_catalogue(2.0)
    2e-08
    """
    return scalar_or_array(as_float_array(C_catalogue, "C_catalogue") * DM3_PER_S_BAR)


def iso6358_mass_flow(
    P1: npt.ArrayLike,
    P2: npt.ArrayLike,
    C: npt.ArrayLike,
    b: npt.ArrayLike,
    T: npt.ArrayLike = T_ROOM,
) -> FloatOrArray:
    """Mass flow through a component rated by ISO 6358 (C, b), eq. 4.5.

    .. math::

        \\dot m = \\rho_0 C P_1 \\sqrt{T_0/T} \\cdot \\begin{cases}
            1, & r \\le b \\\\
            \\sqrt{1 - \\left(\\dfrac{r - b}{1 - b}\\right)^2}, & b < r \\le r_{lam} \\\\
            \\sqrt{1 - \\left(\\dfrac{r_{lam} - b}{1 - b}\\right)^2}
                \\dfrac{1 - r}{1 - r_{lam}}, & r > r_{lam}
        \\end{cases}

    with :math:`r = P_2/P_1`, the ISO 8778 reference atmosphere
    :math:`\\rho_0` = 1.185 kg/m^3, :math:`T_0` = 293.15 K (``constants.ANR``), the
    subsonic index m = 0.5 and the laminar branch of ISO 6358-1:2013 above
    :math:`r_{lam}` = 0.999. The dissertation prints eq. 4.5 as
    ``600 C P1 sqrt(1 - (P2/P1 - b)^2)`` in l/min: the factor 600 converts
    C [dm^3/(s bar)] x P1 [MPa] to dm^3/min, and the ``(1 - b)`` denominator of
    the standard is missing in print; the standard's form is used here.

    Catalogues give C in dm^3/(s bar); convert with
    :func:`sonic_conductance_from_catalogue` (1 dm^3/(s bar) = 1e-8 m^3/(s Pa)).

    Parameters
    ----------
    P1 : float or array_like
        Absolute pressure at port 1 [Pa].
    P2 : float or array_like
        Absolute pressure at port 2 [Pa].
    C : float or array_like
        Sonic conductance referred to ANR [m^3/(s Pa)].
    b : float or array_like
        Critical pressure ratio, 0 <= b < 0.999 [-].
    T : float or array_like
        Upstream gas temperature [K].

    Returns
    -------
    float or ndarray
        Mass flow from port 1 to port 2 [kg/s]; negative when ``P2 > P1``.

    Raises
    ------
    InputError
        For negative pressures or C, b outside [0, 0.999), a non-positive temperature.

    Examples
    --------
    SMC's worked example (C = 2 dm^3/(s bar), b = 0.3, 0.4 -> 0.3 MPa gauge on
    a 0.1 MPa atmosphere, 20 degC) states 420 dm^3/min (ANR):

    >>> from pneufdd.physics.units import kg_s_to_l_min_anr
    >>> m = iso6358_mass_flow(0.5e6, 0.4e6, sonic_conductance_from_catalogue(2.0), 0.3)
    >>> round(kg_s_to_l_min_anr(m), 1)
    419.9
    """
    p1, p2 = _pressures(P1, P2)
    c = as_float_array(C, "C")
    require(c, c >= 0.0, "C", "sonic conductance >= 0 m^3/(s Pa)")
    bb = as_float_array(b, "b")
    require(bb, (bb >= 0.0) & (bb < LAMINAR_RATIO), "b", "critical ratio in [0, 0.999)")
    return scalar_or_array(_iso6358_ufunc(p1, p2, c, bb, _temperature(T)))


# ---------------------------------------------------------------------------
# ISA-75.01, eq. 4.6
# ---------------------------------------------------------------------------


@njit_inline
def _isa_turbulent(P1: float, x: float, Cv: float, xT: float, T: float) -> float:
    # Eq. 4.6 in scfm at ISA standard (60 degF, 14.73 psia) times its density.
    xe = min(x, xT)
    Y = 1.0 - xe / (3.0 * xT)
    scfm = ISA_N7_SCFM * Cv * (P1 / PSI) * Y * math.sqrt(xe / (_RANKINE_PER_KELVIN * T))
    return scfm * _ISA_MASS_PER_SCFM


@njit_inline
def _isa_forward(P1: float, P2: float, Cv: float, xT: float, T: float) -> float:
    if P1 <= 0.0:
        return 0.0
    x = 1.0 - P2 / P1
    x_lam = 1.0 - LAMINAR_RATIO
    if x >= x_lam:
        return _isa_turbulent(P1, x, Cv, xT, T)
    return _isa_turbulent(P1, x_lam, Cv, xT, T) * x / x_lam


@njit
def isa_mass_flow_kernel(P1: float, P2: float, Cv: float, xT: float, T: float) -> float:
    """Signed ISA-75.01 mass flow, compiled scalar kernel of :func:`isa_mass_flow`.

    Parameters
    ----------
    P1, P2 : float
        Absolute pressures at the two ports [Pa]; positive flow goes 1 -> 2.
    Cv : float
        Flow coefficient [US gal/(min psi^0.5)].
    xT : float
        Pressure differential ratio factor at choked flow, 0.001 < xT <= 1 [-].
    T : float
        Upstream gas temperature [K].

    Returns
    -------
    float
        Mass flow from port 1 to port 2 [kg/s].
    """
    if P1 >= P2:
        return _isa_forward(P1, P2, Cv, xT, T)
    return -_isa_forward(P2, P1, Cv, xT, T)


_isa_ufunc = elementwise(isa_mass_flow_kernel, 5)


def isa_mass_flow(
    P1: npt.ArrayLike,
    P2: npt.ArrayLike,
    Cv: npt.ArrayLike,
    xT: npt.ArrayLike = 1.0,
    T: npt.ArrayLike = T_ROOM,
) -> FloatOrArray:
    """Mass flow through a valve rated by Cv and xT (ANSI/ISA-75.01 gas equation), eq. 4.6.

    .. math::

        Q_{scfm} = 22.67\\, C_v\\, P_{1,psia}\\, \\left(1 - \\frac{x_e}{3 x_T}\\right)
                   \\sqrt{\\frac{x_e}{T_{R}}}, \\qquad
        x = 1 - \\frac{P_2}{P_1},\\quad x_e = \\min(x, x_T)

        \\dot m = Q_{scfm} \\cdot 0.0283168\\,\\mathrm{m^3/ft^3} / 60 \\cdot \\rho_{ISA}

    The constant 22.67 is the ISA-75.01 N7 = 1360 (scfh, psia, degR) divided by 60,
    for air (specific gravity Gg = 1, Fk = k/1.4 = 1, Z = 1, no piping factor); its
    volumetric flow is referred to the ISA standard, 60 degF and 14.73 psia
    (``constants.ISA_STANDARD``, 1.2254 kg/m^3), by which it is turned into mass.
    Findings on the printed eq. 4.6 (documented in ``docs/physics.md``):

    * both branches print ``sqrt(X_T/T)``; the standard has ``sqrt(x/T)`` in the
      subsonic branch, used here;
    * the choked constant "11.51" is garbled: continuity at ``x = xT`` (where the
      expansion factor Y = 2/3) requires 22.67 x 2/3 = 15.11; this function
      reaches choking by ``x_e = min(x, xT)``, which is continuous by construction;
    * the dissertation's 413.6 l/min at 6 -> 5 bar(g) is this scfm value times
      28.317 l/ft^3, i.e. a volume at the ISA basis, not at its own 0 degC basis.

    For ``x < 0.001`` (``P2/P1 > 0.999``) the flow is linear in x and matched to
    the turbulent value at x = 0.001 (laminar branch of ISO 6358-1:2013), so the
    slope at equal pressures is finite. For ``P2 > P1`` ports swap, flow negates.

    Parameters
    ----------
    P1 : float or array_like
        Absolute pressure at port 1 [Pa].
    P2 : float or array_like
        Absolute pressure at port 2 [Pa].
    Cv : float or array_like
        Flow coefficient [US gal/(min psi^0.5)].
    xT : float or array_like
        Pressure differential ratio factor at choked flow, 0.01 <= xT <= 1 [-].
    T : float or array_like
        Upstream gas temperature [K].

    Returns
    -------
    float or ndarray
        Mass flow from port 1 to port 2 [kg/s]; negative when ``P2 > P1``.

    Raises
    ------
    InputError
        For negative pressures or Cv, xT outside [0.01, 1], a non-positive temperature.

    Examples
    --------
    The Festo CPE14 valve of Figure 4.3 (Cv = 0.3988, xT = 1) at 6 -> 5 bar(g),
    20 degC, as litres per minute at the ISA standard (catalogue: 410 l/min):

    >>> from pneufdd.physics.constants import ISA_STANDARD
    >>> from pneufdd.physics.units import bar_gauge_to_pa
    >>> m = isa_mass_flow(bar_gauge_to_pa(6.0), bar_gauge_to_pa(5.0), 0.3988)
    >>> round(m / ISA_STANDARD.density * 60e3, 1)
    407.7
    """
    p1, p2 = _pressures(P1, P2)
    cv = as_float_array(Cv, "Cv")
    require(cv, cv >= 0.0, "Cv", "flow coefficient >= 0")
    xt = as_float_array(xT, "xT")
    require(xt, (xt >= 0.01) & (xt <= 1.0), "xT", "pressure ratio factor in [0.01, 1]")
    return scalar_or_array(_isa_ufunc(p1, p2, cv, xt, _temperature(T)))
