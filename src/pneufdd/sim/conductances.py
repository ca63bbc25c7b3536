"""Conductances and sources of the twin's compiled integrator (:mod:`pneufdd.sim.kernel`).

The chamber balances of the kernel are linear in the pressures at the end of a
sub-step: every flow path enters them as a secant conductance ``f / (p1 - p2)``
[kg/(s Pa)] of the flow laws of :mod:`pneufdd.physics.flow` (eq. 4.2-4.6), evaluated at
the sub-step's start. Compiled with numba and inlined into the kernel.
"""

from __future__ import annotations

from numba import njit

from pneufdd.physics.flow import isa_mass_flow_kernel, orifice_mass_flow_kernel

__all__ = ["house_pressure", "isa_conductance", "line_source_pressure", "orifice_conductance"]


@njit(cache=True, inline="always")
def isa_conductance(p1: float, p2: float, cv: float, xt: float, t1: float, t2: float) -> float:
    """Secant conductance of an ISA valve path, f / (p1 - p2) [kg/(s Pa)].

    Below 1 Pa of difference the slope over the last pascal above the higher
    pressure; one call site of the flow kernel, so inlining stays small.
    """
    if cv <= 0.0:
        return 0.0
    if p1 >= p2:
        hi, lo, t = p1, p2, t1
    else:
        hi, lo, t = p2, p1, t2
    d = hi - lo
    if d < 1.0:
        hi, lo, d = hi + 1.0, hi, 1.0
    return isa_mass_flow_kernel(hi, lo, cv, xt, t) / d


@njit(cache=True, inline="always")
def orifice_conductance(p1: float, p2: float, area: float, t1: float, t2: float) -> float:
    """Secant conductance of an orifice (effective area, Cd included) [kg/(s Pa)]."""
    if area <= 0.0:
        return 0.0
    if p1 >= p2:
        hi, lo, t = p1, p2, t1
    else:
        hi, lo, t = p2, p1, t2
    d = hi - lo
    if d < 1.0:
        hi, lo, d = hi + 1.0, hi, 1.0
    return orifice_mass_flow_kernel(hi, lo, area, 1.0, t) / d


@njit(cache=True, inline="always")
def line_source_pressure(p_manifold: float, p_line: float, boost: float) -> float:
    """Pressure a connected line is fed from [Pa]: the manifold's, or its own source's
    (``p_line`` > 0: a regulator while the manifold is above it; ``boost``: always).

    Examples
    --------
    >>> line_source_pressure(7e5, 4e5, 0.0), line_source_pressure(3e5, 4e5, 0.0)
    (400000.0, 300000.0)
    >>> line_source_pressure(3e5, 4e5, 1.0)  # a booster holds its pressure
    400000.0
    """
    if p_line > 0.0 and (boost > 0.0 or p_manifold > p_line):
        return p_line
    return p_manifold


@njit(cache=True, inline="always")
def house_pressure(
    t: float, period: float, phase: float, p_house: float, band: float, drift: float
) -> float:
    """House-air pressure: nominal + compressor load/unload cycle + slow drift [Pa].

    ``t`` time [s], ``period`` of the compressor cycle [s], its ``phase`` at t = 0
    [-], nominal ``p_house`` [Pa], load/unload ``band`` peak to peak [Pa] and the
    slow ``drift`` at t [Pa]. Scalars only: array arguments of a helper cost a
    reference count each call.
    """
    ph = (t / period + phase) % 1.0
    # loaded (rising) for 30 % of the period, unloaded (falling) for 70 %
    saw = ph / 0.3 if ph < 0.3 else 1.0 - (ph - 0.3) / 0.7
    return p_house + band * (saw - 0.5) + drift
