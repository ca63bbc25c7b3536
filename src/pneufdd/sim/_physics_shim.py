"""TEMPORARY stand-in for ``pneufdd.physics`` kernels (branch ``physics``, not yet merged).

DELETE THIS FILE after ``main`` contains ``pneufdd.physics.flow``, ``friction`` and
``leaks``; the simulator must then import those kernels instead. The names and
signatures mirror the ones announced for the physics package so the swap is a
one-line import change in :mod:`pneufdd.sim.kernel` and :mod:`pneufdd.sim.leaks`.
"""

from __future__ import annotations

import math

from numba import njit

from pneufdd.physics.constants import FT3, GAMMA_AIR, ISA_STANDARD, PSI, R_AIR

__all__ = [
    "isa_mass_flow_kernel",
    "karnopp_friction_kernel",
    "leak_valve_area",
    "orifice_mass_flow_kernel",
]

_X_LAMINAR = 0.005
_ISA_KG_S_PER_SCFH = FT3 / 3600.0 * ISA_STANDARD.density
_G = GAMMA_AIR
_PCR = (2.0 / (_G + 1.0)) ** (_G / (_G - 1.0))
_C1 = math.sqrt(_G / R_AIR * (2.0 / (_G + 1.0)) ** ((_G + 1.0) / (_G - 1.0)))
_C2 = math.sqrt(2.0 * _G / (R_AIR * (_G - 1.0)))


@njit(cache=True)
def _isa_forward(P1: float, P2: float, Cv: float, xT: float, T: float) -> float:
    x = 1.0 - P2 / P1
    lam = x < _X_LAMINAR
    xe = _X_LAMINAR if lam else x
    if xe > xT:
        xe = xT
    y = 1.0 - xe / (3.0 * xT)
    q = 1360.0 * Cv * (P1 / PSI) * y * math.sqrt(xe / (1.8 * T))
    m = q * _ISA_KG_S_PER_SCFH
    if lam:
        m *= x / _X_LAMINAR
    return m


@njit(cache=True)
def isa_mass_flow_kernel(P1: float, P2: float, Cv: float, xT: float, T: float) -> float:
    """Signed ISA valve flow, eq. 4.6 (TEMPORARY shim) [kg/s]."""
    if P1 >= P2:
        return _isa_forward(P1, P2, Cv, xT, T)
    return -_isa_forward(P2, P1, Cv, xT, T)


@njit(cache=True)
def _orifice_forward(P1: float, P2: float, area: float, Cd: float, T: float) -> float:
    r = P2 / P1
    lam = r > 1.0 - _X_LAMINAR
    re = 1.0 - _X_LAMINAR if lam else r
    if re <= _PCR:
        m = Cd * area * _C1 * P1 / math.sqrt(T)
    else:
        m = (
            Cd
            * area
            * _C2
            * P1
            / math.sqrt(T)
            * re ** (1.0 / _G)
            * math.sqrt(1.0 - re ** ((_G - 1.0) / _G))
        )
    if lam:
        m *= (1.0 - r) / _X_LAMINAR
    return m


@njit(cache=True)
def orifice_mass_flow_kernel(P1: float, P2: float, area: float, Cd: float, T: float) -> float:
    """Signed orifice flow, eq. 4.3 (TEMPORARY shim) [kg/s]."""
    if P1 >= P2:
        return _orifice_forward(P1, P2, area, Cd, T)
    return -_orifice_forward(P2, P1, area, Cd, T)


@njit(cache=True)
def karnopp_friction_kernel(
    velocity: float, applied_force: float, Fsf: float, Fcf: float, Cvf: float, dv: float
) -> float:
    """Karnopp friction force opposing motion, eq. 4.14 (TEMPORARY shim) [N]."""
    if abs(velocity) < dv:
        if abs(applied_force) <= Fsf:
            return applied_force
        return Fsf if applied_force > 0.0 else -Fsf
    s = 1.0 if velocity > 0.0 else -1.0
    return s * Fcf + Cvf * velocity


def leak_valve_area(turns: float) -> float:
    """Effective area Cd*A of the GR-3/8B leak valve at ``turns`` (TEMPORARY shim) [m^2].

    Calibrated so 1 turn ~ 10 SLPM and 6 turns ~ 200 SLPM at 5 bar(g) (choked flow
    ~ 6.0e-3 kg/s per (MPa mm^2) ... a smooth power law in between).
    """
    if turns <= 0.0:
        return 0.0
    # choked mass flow per area at 6.013 bar abs, 293 K [kg/(s m^2)]
    per_area = _C1 * 601_325.0 / math.sqrt(293.15)
    slpm_to_kg_s = 1.294e-3 / 60.0
    q = 10.0 * turns ** (math.log(20.0) / math.log(6.0))
    return float(q * slpm_to_kg_s / per_area)


def leak_area(value: float, unit: str, reference_pressure: float) -> float:
    """Effective leak area from turns, orifice diameter [mm] or SLPM (TEMPORARY shim) [m^2]."""
    if unit == "turns":
        return leak_valve_area(value)
    if unit == "mm":
        return 0.61 * math.pi * (value * 1e-3) ** 2 / 4.0
    per_area = float(orifice_mass_flow_kernel(reference_pressure, 101_325.0, 1.0, 1.0, 293.15))
    return value * 1.294e-3 / 60.0 / per_area


def leak_mass_flow(pressure: float, area: float) -> float:
    """Leak mass flow to the atmosphere at 20 degC (TEMPORARY shim) [kg/s]."""
    return float(orifice_mass_flow_kernel(pressure, 101_325.0, area, 1.0, 293.15))
