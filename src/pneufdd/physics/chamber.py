"""Cylinder chambers: volume and pressure or mass-temperature dynamics (section 4.2.2).

Two forms of the chamber dynamics are provided:

* :func:`chamber_pressure_derivative` - the dissertation's polytropic pressure
  equation, eq. 4.10/4.12, with empirical exponents alpha_in, alpha_out, alpha;
* :func:`chamber_energy_derivatives` (and its kernel) - the mass and energy
  balances, eq. 4.7-4.9 with the heat-transfer terms kept. The chamber states are
  its air mass m and temperature T; the pressure follows from eq. 4.7.
  :func:`chamber_energy_step_kernel` is the same balance as one time step of the
  internal energy (the digital twin's node update), with the enthalpy each flow
  carries from :func:`enthalpy_flow_kernel`.

The digital twin uses the energy form. Eq. 4.10 with alpha_in != alpha_out does not
conserve mass over a fill/exhaust cycle unless the temperature is tracked: at a fixed
T in eq. 4.10 the mass implied by the state, ``P V / (R T)``, grows by
``alpha_in m_in - alpha_out m_out`` while the true mass grows by ``m_in - m_out``.
Filling and then exhausting the same mass with alpha_in = 1.4 and alpha_out = 1
leaves a phantom 40 % of it in the chamber. In the energy form the "alphas" emerge:
adiabatic filling gives alpha_in = k, slow exhaust with strong wall heat exchange
gives alpha_out -> 1, and mass is conserved exactly.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, eq. 4.7-4.12.
.. [2] Richer, E., Hurmuzlu, Y., A high performance pneumatic force actuator
   system, J. Dyn. Sys. Meas. Control 122 (2000) - origin of eq. 4.10.
"""

from __future__ import annotations

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
from pneufdd.physics.constants import CP_AIR, CV_AIR, GAMMA_AIR, R_AIR, T_ROOM

__all__ = [
    "CV_AIR",
    "chamber_energy_derivatives",
    "chamber_energy_derivatives_kernel",
    "chamber_energy_step_kernel",
    "chamber_pressure",
    "chamber_pressure_derivative",
    "chamber_pressure_derivative_kernel",
    "chamber_pressure_kernel",
    "chamber_volume",
    "chamber_volume_kernel",
    "enthalpy_flow_kernel",
]


@njit_inline
def chamber_volume_kernel(
    x: float, area: float, dead_volume: float, stroke: float, side: float
) -> float:
    """Chamber volume, eq. 4.11; compiled kernel of :func:`chamber_volume`.

    Parameters
    ----------
    x : float
        Piston position from the blind end [m].
    area : float
        Piston effective area on this side [m^2].
    dead_volume : float
        Inactive volume at the end of stroke and ports, V_c [m^3].
    stroke : float
        Stroke L [m]; used for chamber B only.
    side : float
        0.0 for chamber A (blind side), 1.0 for chamber B (rod side) [-].

    Returns
    -------
    float
        Chamber volume [m^3].
    """
    if side == 0.0:
        return dead_volume + area * x
    return dead_volume + area * (stroke - x)


_volume_ufunc = elementwise(chamber_volume_kernel, 5)


def chamber_volume(
    x: npt.ArrayLike,
    area: float,
    dead_volume: float,
    chamber: str = "A",
    stroke: float | None = None,
) -> FloatOrArray:
    """Volume of cylinder chamber A (blind side) or B (rod side), eq. 4.11.

    .. math::

        V_a = V_{ca} + A_a x, \\qquad V_b = V_{cb} + A_b (L - x)

    Parameters
    ----------
    x : float or array_like
        Piston position measured from the blind end, 0 <= x <= L [m].
    area : float
        Piston effective area of this chamber, A_a or A_b [m^2].
    dead_volume : float
        Inactive volume of this chamber, V_ca or V_cb [m^3].
    chamber : {"A", "B"}
        Which chamber.
    stroke : float, optional
        Stroke L [m]; required for chamber B, and bounds ``x`` when given.

    Returns
    -------
    float or ndarray
        Chamber volume [m^3].

    Raises
    ------
    InputError
        For an unknown chamber, a missing stroke for chamber B, negative area or
        dead volume, or a position outside the stroke.

    Examples
    --------
    DNC 32 cylinder (Figure 4.10), 200 mm stroke, rod side at mid-stroke with
    an assumed 5 cm^3 dead volume:

    >>> import math
    >>> Ab = math.pi / 4 * (0.032**2 - 0.012**2)
    >>> round(chamber_volume(0.1, Ab, 5e-6, "B", stroke=0.2) * 1e6, 2)
    74.12
    """
    if chamber not in ("A", "B"):
        raise InputError(describe("parameter 'chamber'", chamber, ["A", "B"]))
    if chamber == "B" and stroke is None:
        raise InputError(describe("parameter 'stroke' for chamber B", stroke, "a length > 0 m"))
    xs = as_float_array(x, "x")
    a = as_float_array(area, "area")
    require(a, a >= 0.0, "area", "area >= 0 m^2")
    vc = as_float_array(dead_volume, "dead_volume")
    require(vc, vc >= 0.0, "dead_volume", "volume >= 0 m^3")
    length = 0.0 if stroke is None else float(as_float_array(stroke, "stroke"))
    if stroke is not None:
        require(xs, (xs >= 0.0) & (xs <= length), "x", f"position in [0, {length}] m")
    else:
        require(xs, xs >= 0.0, "x", "position >= 0 m")
    side = 0.0 if chamber == "A" else 1.0
    return scalar_or_array(_volume_ufunc(xs, a, vc, length, side))


@njit
def chamber_pressure_derivative_kernel(
    P: float,
    V: float,
    dV_dt: float,
    mass_flow_in: float,
    mass_flow_out: float,
    T: float,
    alpha_in: float,
    alpha_out: float,
    alpha: float,
) -> float:
    """Chamber pressure derivative, eq. 4.10; compiled kernel.

    Parameters
    ----------
    P : float
        Chamber absolute pressure [Pa].
    V : float
        Chamber volume [m^3].
    dV_dt : float
        Rate of change of the volume [m^3/s].
    mass_flow_in, mass_flow_out : float
        Mass flows entering and leaving [kg/s].
    T : float
        Gas temperature [K].
    alpha_in, alpha_out, alpha : float
        Polytropic exponents for charging, discharging, piston motion [-].

    Returns
    -------
    float
        dP/dt [Pa/s].
    """
    return R_AIR * T / V * (alpha_in * mass_flow_in - alpha_out * mass_flow_out) - (
        alpha * P / V * dV_dt
    )


_dpdt_ufunc = elementwise(chamber_pressure_derivative_kernel, 9)


def chamber_pressure_derivative(
    P: npt.ArrayLike,
    V: npt.ArrayLike,
    dV_dt: npt.ArrayLike,
    mass_flow_in: npt.ArrayLike,
    mass_flow_out: npt.ArrayLike,
    T: npt.ArrayLike = T_ROOM,
    alpha_in: npt.ArrayLike = GAMMA_AIR,
    alpha_out: npt.ArrayLike = 1.0,
    alpha: npt.ArrayLike = 1.2,
) -> FloatOrArray:
    """Pressure derivative of a cylinder chamber, eq. 4.10 (eq. 4.12 with eq. 4.11).

    .. math::

        \\dot P = \\frac{R T}{V}\\left(\\alpha_{in}\\dot m_{in}
                  - \\alpha_{out}\\dot m_{out}\\right) - \\alpha \\frac{P}{V}\\dot V

    Defaults follow section 4.2.2: alpha_in = k = 1.4 (charging close to
    adiabatic), alpha_out = 1 (discharging close to isothermal), alpha = 1.2 for
    compression/expansion by the piston (Al-Ibrahim and Otis). This form does not
    conserve mass over a fill/exhaust cycle when alpha_in != alpha_out (see the
    module notes); the twin uses :func:`chamber_energy_derivatives_kernel`.

    Parameters
    ----------
    P : float or array_like
        Chamber absolute pressure [Pa].
    V : float or array_like
        Chamber volume, > 0 [m^3].
    dV_dt : float or array_like
        Rate of change of the chamber volume [m^3/s].
    mass_flow_in : float or array_like
        Mass flow entering the chamber [kg/s].
    mass_flow_out : float or array_like
        Mass flow leaving the chamber [kg/s].
    T : float or array_like
        Gas temperature [K].
    alpha_in : float or array_like
        Polytropic exponent while charging, 1 <= alpha_in <= k [-].
    alpha_out : float or array_like
        Polytropic exponent while discharging, 1 <= alpha_out <= k [-].
    alpha : float or array_like
        Polytropic exponent of compression by the piston [-].

    Returns
    -------
    float or ndarray
        dP/dt [Pa/s].

    Examples
    --------
    Chamber A of the DNC 32 (8.04 cm^3 dead volume assumed), piston at rest,
    charged with 5 g/min at 20 degC and 2 bar absolute:

    >>> round(chamber_pressure_derivative(2e5, 8.04e-6, 0.0, 5e-3 / 60, 0.0))
    1221097
    """
    p = as_float_array(P, "P")
    require(p, p >= 0.0, "P", "absolute pressure >= 0 Pa")
    v = as_float_array(V, "V")
    require(v, v > 0.0, "V", "volume > 0 m^3")
    t = as_float_array(T, "T")
    require(t, t > 0.0, "T", "absolute temperature > 0 K")
    return scalar_or_array(
        _dpdt_ufunc(
            p,
            v,
            as_float_array(dV_dt, "dV_dt"),
            as_float_array(mass_flow_in, "mass_flow_in"),
            as_float_array(mass_flow_out, "mass_flow_out"),
            t,
            as_float_array(alpha_in, "alpha_in"),
            as_float_array(alpha_out, "alpha_out"),
            as_float_array(alpha, "alpha"),
        )
    )


@njit_inline
def chamber_pressure_kernel(m: float, T: float, V: float) -> float:
    """Chamber pressure from the ideal gas law, eq. 4.7: P = m R T / V [Pa].

    Parameters
    ----------
    m : float
        Air mass in the chamber [kg].
    T : float
        Gas temperature [K].
    V : float
        Chamber volume [m^3].

    Returns
    -------
    float
        Absolute pressure [Pa].
    """
    return m * R_AIR * T / V


_pressure_ufunc = elementwise(chamber_pressure_kernel, 3)


def chamber_pressure(m: npt.ArrayLike, T: npt.ArrayLike, V: npt.ArrayLike) -> FloatOrArray:
    """Absolute pressure of the air in a chamber, ideal gas law eq. 4.7.

    .. math:: P = \\frac{m R T}{V}

    Parameters
    ----------
    m : float or array_like
        Air mass, >= 0 [kg].
    T : float or array_like
        Gas temperature, > 0 [K].
    V : float or array_like
        Chamber volume, > 0 [m^3].

    Returns
    -------
    float or ndarray
        Absolute pressure [Pa].

    Examples
    --------
    >>> round(chamber_pressure(1.2e-5, 293.15, 1e-5))
    100981
    """
    mm = as_float_array(m, "m")
    require(mm, mm >= 0.0, "m", "mass >= 0 kg")
    t = as_float_array(T, "T")
    require(t, t > 0.0, "T", "absolute temperature > 0 K")
    v = as_float_array(V, "V")
    require(v, v > 0.0, "V", "volume > 0 m^3")
    return scalar_or_array(_pressure_ufunc(mm, t, v))


@njit
def chamber_energy_derivatives_kernel(
    m: float,
    T: float,
    V: float,
    dV_dt: float,
    mass_flow_in: float,
    mass_flow_out: float,
    T_in: float,
    hA: float,
    T_wall: float,
) -> tuple[float, float]:
    """Mass and temperature derivatives of a chamber, eq. 4.7-4.9; compiled kernel.

    Parameters
    ----------
    m : float
        Air mass in the chamber, > 0 [kg].
    T : float
        Gas temperature [K].
    V : float
        Chamber volume [m^3].
    dV_dt : float
        Rate of change of the volume [m^3/s].
    mass_flow_in, mass_flow_out : float
        Mass flows entering and leaving, each >= 0 [kg/s].
    T_in : float
        Stagnation temperature of the entering air [K].
    hA : float
        Convective heat-transfer coefficient times wall area [W/K].
    T_wall : float
        Wall temperature [K].

    Returns
    -------
    dm_dt : float
        Rate of change of the mass [kg/s].
    dT_dt : float
        Rate of change of the gas temperature [K/s].
    """
    P = m * R_AIR * T / V
    q = hA * (T_wall - T)
    dm_dt = mass_flow_in - mass_flow_out
    dT_dt = (mass_flow_in * (GAMMA_AIR * T_in - T) - mass_flow_out * (GAMMA_AIR - 1.0) * T) / m + (
        q - P * dV_dt
    ) / (m * CV_AIR)
    return dm_dt, dT_dt


def chamber_energy_derivatives(
    m: float,
    T: float,
    V: float,
    dV_dt: float,
    mass_flow_in: float,
    mass_flow_out: float,
    T_in: float = T_ROOM,
    hA: float = 0.0,
    T_wall: float = T_ROOM,
) -> tuple[float, float]:
    """Mass and energy balance of a chamber with wall heat transfer, eq. 4.7-4.9.

    With the internal energy :math:`U = m c_v T`, enthalpy :math:`c_p = k c_v`
    carried by the flows (air leaves at chamber temperature), boundary work
    :math:`P\\dot V` and convection :math:`\\dot q = hA (T_w - T)`:

    .. math::

        \\dot m = \\dot m_{in} - \\dot m_{out}

        \\dot T = \\frac{\\dot m_{in}(k T_{in} - T) - \\dot m_{out}(k-1)T}{m}
                 + \\frac{hA (T_w - T) - P \\dot V}{m c_v},
        \\qquad P = \\frac{m R T}{V}

    It reproduces eq. 4.10 as limits: with hA = 0 and T_in = T, dP/dt equals eq.
    4.10 with all alphas = k; with T held at T_wall (hA -> infinity) all alphas = 1.

    Parameters
    ----------
    m : float
        Air mass in the chamber, > 0 [kg].
    T : float
        Gas temperature, > 0 [K].
    V : float
        Chamber volume, > 0 [m^3].
    dV_dt : float
        Rate of change of the volume [m^3/s].
    mass_flow_in : float
        Mass flow entering, >= 0 [kg/s].
    mass_flow_out : float
        Mass flow leaving, >= 0 [kg/s].
    T_in : float
        Temperature of the entering air, > 0 [K].
    hA : float
        Heat-transfer coefficient times wall area, >= 0 [W/K].
    T_wall : float
        Wall temperature, > 0 [K].

    Returns
    -------
    dm_dt : float
        Rate of change of the mass [kg/s].
    dT_dt : float
        Rate of change of the gas temperature [K/s].

    Examples
    --------
    Adiabatic charging of 8 cm^3 at 2 bar with room-temperature air heats it:

    >>> m = 2e5 * 8e-6 / (287.058 * 293.15)
    >>> dm, dT = chamber_energy_derivatives(m, 293.15, 8e-6, 0.0, 1e-4, 0.0)
    >>> round(dm, 6), round(dT, 1)
    (0.0001, 616.7)
    """
    values = {
        "m": m,
        "T": T,
        "V": V,
        "dV_dt": dV_dt,
        "mass_flow_in": mass_flow_in,
        "mass_flow_out": mass_flow_out,
        "T_in": T_in,
        "hA": hA,
        "T_wall": T_wall,
    }
    checked = {name: float(as_float_array(v, name)) for name, v in values.items()}
    for name in ("m", "T", "V", "T_in", "T_wall"):
        if checked[name] <= 0.0:
            raise InputError(describe(f"parameter {name!r}", checked[name], "a value > 0"))
    for name in ("mass_flow_in", "mass_flow_out", "hA"):
        if checked[name] < 0.0:
            raise InputError(describe(f"parameter {name!r}", checked[name], "a value >= 0"))
    dm_dt, dT_dt = chamber_energy_derivatives_kernel(*checked.values())
    return float(dm_dt), float(dT_dt)


@njit_inline
def enthalpy_flow_kernel(mass_flow: float, T_from: float, T_to: float) -> float:
    """Enthalpy a mass flow carries from one node to another, eq. 4.8 [W].

    .. math:: \\dot H = c_p \\dot m \\, T_{up}

    The air carries the stagnation temperature of the node it leaves: ``T_from`` when
    the flow is positive (towards ``to``), ``T_to`` when it is negative.

    Parameters
    ----------
    mass_flow : float
        Mass flow from node ``from`` to node ``to``, negative for the reverse [kg/s].
    T_from : float
        Gas temperature of node ``from`` [K].
    T_to : float
        Gas temperature of node ``to`` [K].

    Returns
    -------
    float
        Enthalpy flow from ``from`` to ``to`` [W].

    Examples
    --------
    1 g/s of room air:

    >>> round(enthalpy_flow_kernel(1e-3, 293.15, 350.0), 1)
    294.5
    """
    return CP_AIR * mass_flow * (T_from if mass_flow > 0.0 else T_to)


@njit_inline
def chamber_energy_step_kernel(
    m: float,
    T: float,
    P: float,
    dV_dt: float,
    mass_rate: float,
    enthalpy_rate: float,
    dt: float,
    T_wall: float,
    decay: float,
) -> tuple[float, float]:
    """One time step of a node's mass and energy balance, eq. 4.7-4.9 in energy form.

    The digital twin's node update: the internal energy ``U = m c_v T`` gains the net
    enthalpy inflow and loses the boundary work, the mass its net inflow; the gas
    temperature then relaxes towards the wall by the factor ``decay`` (heat exchange
    as a first-order lag, ``decay = exp(-dt / tau)``):

    .. math::

        U' = m c_v T + \\Delta t \\, (\\dot H - P \\dot V), \\qquad
        m' = m + \\Delta t \\, \\dot m, \\qquad
        T' = T_w + \\left(\\frac{U'}{m' c_v} - T_w\\right) d

    Two numerical guards: the mass never falls below 1e-12 kg and the temperature
    never below 150 K (an almost empty node's energy balance is ill-conditioned).
    With ``decay = 1`` and ``dt -> 0``, ``(T' - T) / dt`` is the temperature derivative
    of :func:`chamber_energy_derivatives` with ``hA = 0`` (the same equations in the
    mass-temperature form an ODE solver integrates); the twin integrates U because
    then every edge's enthalpy leaves one node and enters the other exactly.

    Parameters
    ----------
    m : float
        Air mass at the start of the step [kg].
    T : float
        Gas temperature at the start of the step [K].
    P : float
        Pressure at the start of the step [Pa].
    dV_dt : float
        Rate of change of the volume [m^3/s].
    mass_rate : float
        Net mass inflow [kg/s].
    enthalpy_rate : float
        Net enthalpy inflow (:func:`enthalpy_flow_kernel` of every edge) [W].
    dt : float
        Time step [s].
    T_wall : float
        Wall temperature [K].
    decay : float
        Heat-exchange factor of the step, ``exp(-dt / tau)``; 1 = adiabatic [-].

    Returns
    -------
    m_new : float
        Air mass at the end of the step [kg].
    T_new : float
        Gas temperature at the end of the step [K].

    Examples
    --------
    Adiabatic charging of 8 cm^3 at 2 bar with 0.1 g/s of room-temperature air over
    1 us heats it at the rate :func:`chamber_energy_derivatives` gives:

    >>> m, T = 2e5 * 8e-6 / (287.058 * 293.15), 293.15
    >>> h = enthalpy_flow_kernel(1e-4, T, T)
    >>> m_new, T_new = chamber_energy_step_kernel(m, T, 2e5, 0.0, 1e-4, h, 1e-6, T, 1.0)
    >>> round((T_new - T) / 1e-6, 1)
    616.7
    """
    u = m * CV_AIR * T
    u += dt * (enthalpy_rate - P * dV_dt)
    m_new = m + dt * mass_rate
    if m_new < 1e-12:
        m_new = 1e-12
    T_new = u / (m_new * CV_AIR)
    T_new = T_wall + (T_new - T_wall) * decay
    if T_new < 150.0:
        T_new = 150.0
    return m_new, T_new
