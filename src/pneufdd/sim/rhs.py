"""The plant's equations as an explicit ODE right-hand side, for reference solvers.

:func:`plant_derivatives` states the same physics as the compiled integrator of
:mod:`pneufdd.sim.kernel` (regulator, reservoir, supply line, manifold, valve paths,
leaks, chambers with mass and temperature, pistons with Karnopp friction and return
springs) for fixed valve positions and a constant regulator source, in the form
``dy/dt = f(t, y)``; lines fed at their own pressure (issue 37) are not in it.
It lets a general-purpose solver (``scipy.integrate.solve_ivp``) integrate one motion
segment as an independent check and as the baseline of ``make bench``.

State vector: node masses [kg] (reservoir, manifold, then chambers A/B of every
actuator), node temperatures [K], piston positions [m], piston velocities [m/s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit
from scipy.integrate import solve_ivp

from pneufdd.physics.chamber import (
    chamber_energy_derivatives_kernel,
    chamber_pressure_kernel,
    chamber_volume_kernel,
)
from pneufdd.physics.constants import CV_AIR, P_ATM
from pneufdd.physics.faults import cushion_engaged_kernel
from pneufdd.physics.flow import isa_mass_flow_kernel, orifice_mass_flow_kernel
from pneufdd.physics.friction import friction_force_kernel, piston_net_force_kernel
from pneufdd.sim import layout as lay
from pneufdd.sim.compile import Plant

__all__ = ["SegmentSolution", "plant_derivatives", "solve_segment"]


@njit(cache=True)
def _edge(
    i: int, j: int, f: float, t_i: float, t_j: float, fin: np.ndarray, fout: np.ndarray,
    hin: np.ndarray,
) -> None:  # fmt: skip
    """Book flow f from node i to node j (negative: j to i); -1 is a boundary."""
    if f >= 0.0:
        if i >= 0:
            fout[i] += f
        if j >= 0:
            fin[j] += f
            hin[j] += f * t_i
    else:
        if j >= 0:
            fout[j] -= f
        if i >= 0:
            fin[i] -= f
            hin[i] -= f * t_j


@njit(cache=True)
def plant_derivatives(
    y: np.ndarray,
    sp: np.ndarray,
    ap: np.ndarray,
    cp: np.ndarray,
    conn: np.ndarray,
    p_src: float,
    fric: np.ndarray,
) -> np.ndarray:
    """Time derivative of the plant state for fixed valve connections.

    Parameters
    ----------
    y : ndarray
        State: masses [kg], temperatures [K] of the 2 + 2n nodes, positions [m] and
        velocities [m/s] of the n pistons.
    sp, ap, cp : ndarray
        Supply, actuator and chamber parameters (:mod:`pneufdd.sim.layout`).
    conn : ndarray of int
        Per chamber: 0 closed, 1 to the manifold, 2 to the exhaust.
    p_src : float
        Regulator source pressure [Pa].
    fric : ndarray
        Friction factor per actuator [-].

    Returns
    -------
    ndarray
        dy/dt in the units of ``y`` per second.
    """
    na = ap.shape[0]
    nc = 2 * na
    nn = 2 + nc
    m = y[:nn]
    temp = y[nn : 2 * nn]
    x = y[2 * nn : 2 * nn + na]
    v = y[2 * nn + na :]
    t_wall = sp[lay.SP_T_WALL]
    t_sup = sp[lay.SP_T_SUPPLY]
    vol = np.empty(nn)
    vdot = np.zeros(nn)
    vol[0] = sp[lay.SP_V_RES]
    vol[1] = sp[lay.SP_V_MAN]
    for i in range(na):
        xi = min(max(x[i], 0.0), ap[i, lay.AP_STROKE])
        stroke = ap[i, lay.AP_STROKE]
        vol[2 + 2 * i] = chamber_volume_kernel(
            xi, cp[2 * i, lay.CP_AREA], cp[2 * i, lay.CP_DEAD], stroke, 0.0
        )
        vol[3 + 2 * i] = chamber_volume_kernel(
            xi, cp[2 * i + 1, lay.CP_AREA], cp[2 * i + 1, lay.CP_DEAD], stroke, 1.0
        )
        vdot[2 + 2 * i] = cp[2 * i, lay.CP_AREA] * v[i]
        vdot[3 + 2 * i] = -cp[2 * i + 1, lay.CP_AREA] * v[i]
    p = np.empty(nn)
    for j in range(nn):
        p[j] = chamber_pressure_kernel(m[j], temp[j], vol[j])
    fin = np.zeros(nn)
    fout = np.zeros(nn)
    hin = np.zeros(nn)
    f_reg = 0.0
    if p_src > p[0]:
        f_reg = isa_mass_flow_kernel(p_src, p[0], sp[lay.SP_REG_CV], sp[lay.SP_REG_XT], t_sup)
    _edge(-1, 0, f_reg, t_sup, temp[0], fin, fout, hin)
    t_up = temp[0] if p[0] >= p[1] else temp[1]
    f_line = isa_mass_flow_kernel(p[0], p[1], sp[lay.SP_LINE_CV], sp[lay.SP_LINE_XT], t_up)
    _edge(0, 1, f_line, temp[0], temp[1], fin, fout, hin)
    f_sl = orifice_mass_flow_kernel(p[1], P_ATM, sp[lay.SP_SUPPLY_LEAK], 1.0, temp[1])
    _edge(1, -1, f_sl, temp[1], t_wall, fin, fout, hin)
    for c in range(nc):
        j = 2 + c
        if conn[c] == 1:
            t_up = temp[1] if p[1] >= p[j] else temp[j]
            f = isa_mass_flow_kernel(p[1], p[j], cp[c, lay.CP_CV_FILL], cp[c, lay.CP_XT], t_up)
            _edge(1, j, f, temp[1], temp[j], fin, fout, hin)
        elif conn[c] == 2:
            t_up = temp[j] if p[j] >= P_ATM else t_wall
            i = c // 2
            cv_e = cp[c, lay.CP_CV_EXH]
            if cushion_engaged_kernel(x[i], ap[i, lay.AP_STROKE], ap[i, lay.AP_CUSH_LEN], c % 2):
                cv_e = cp[c, lay.CP_CV_CUSH]
            f = isa_mass_flow_kernel(p[j], P_ATM, cv_e, cp[c, lay.CP_XT], t_up)
            _edge(j, -1, f, temp[j], t_wall, fin, fout, hin)
        f = orifice_mass_flow_kernel(p[j], P_ATM, cp[c, lay.CP_LEAK], 1.0, temp[j])
        _edge(j, -1, f, temp[j], t_wall, fin, fout, hin)
        # faults (issue 34): spool leaks supply -> port and port -> exhaust
        t_up = temp[1] if p[1] >= p[j] else temp[j]
        f = orifice_mass_flow_kernel(
            max(p[1], p[j]), min(p[1], p[j]), cp[c, lay.CP_SPOOL_IN], 1.0, t_up
        )
        _edge(1, j, f if p[1] >= p[j] else -f, temp[1], temp[j], fin, fout, hin)
        f = orifice_mass_flow_kernel(p[j], P_ATM, cp[c, lay.CP_SPOOL_OUT], 1.0, temp[j])
        _edge(j, -1, f, temp[j], t_wall, fin, fout, hin)
    for i in range(na):  # a leaking piston seal, chamber A <-> chamber B
        ja = 2 + 2 * i
        jb = ja + 1
        t_up = temp[ja] if p[ja] >= p[jb] else temp[jb]
        f = orifice_mass_flow_kernel(
            max(p[ja], p[jb]), min(p[ja], p[jb]), ap[i, lay.AP_PISTON_LEAK], 1.0, t_up
        )
        _edge(ja, jb, f if p[ja] >= p[jb] else -f, temp[ja], temp[jb], fin, fout, hin)
    dy = np.zeros(y.size)
    for j in range(nn):
        tau = sp[lay.SP_TAU_TH] if j < 2 else cp[j - 2, lay.CP_TAU_TH]
        h_a = m[j] * CV_AIR / tau
        t_in = hin[j] / fin[j] if fin[j] > 0.0 else temp[j]
        dm, dt = chamber_energy_derivatives_kernel(
            m[j], temp[j], vol[j], vdot[j], fin[j], fout[j], t_in, h_a, t_wall
        )
        dy[j] = dm
        dy[nn + j] = dt
    for i in range(na):
        force = piston_net_force_kernel(
            p[2 + 2 * i],
            p[3 + 2 * i],
            cp[2 * i, lay.CP_AREA],
            cp[2 * i + 1, lay.CP_AREA],
            ap[i, lay.AP_AROD],
        )
        force -= ap[i, lay.AP_SPRING_F0] + ap[i, lay.AP_SPRING_K] * x[i]  # return spring
        stroke = ap[i, lay.AP_STROKE]
        ff = friction_force_kernel(
            v[i],
            force,
            ap[i, lay.AP_FS] * fric[i],
            ap[i, lay.AP_FC] * fric[i],
            ap[i, lay.AP_CVF],
            lay.STICK_BAND,
        )
        acc = (force - ff) / ap[i, lay.AP_MASS]
        at_stop = (x[i] <= 0.0 and v[i] <= 0.0 and acc < 0.0) or (
            x[i] >= stroke and v[i] >= 0.0 and acc > 0.0
        )
        if at_stop:
            acc = 0.0
        dy[2 * nn + i] = v[i]
        dy[2 * nn + na + i] = acc
    return dy


@dataclass(frozen=True)
class SegmentSolution:
    """Result of :func:`solve_segment`."""

    t_end: float
    """Time the watched piston reached its end stop [s] (NaN if it did not)."""
    y_end: npt.NDArray[np.float64]
    """State at ``t_end``."""
    n_rhs: int
    """Right-hand-side evaluations."""


def solve_segment(
    plant: Plant,
    y0: npt.NDArray[np.float64],
    conn: npt.NDArray[np.int64],
    actuator: int,
    t_max: float,
    method: str = "LSODA",
    rtol: float = 1e-6,
    atol: npt.NDArray[np.float64] | None = None,
) -> SegmentSolution:
    """Integrate until piston ``actuator`` reaches its B (extended) end stop.

    Parameters
    ----------
    plant : Plant
        Compiled machine (:func:`pneufdd.sim.compile.compile_plant`).
    y0 : ndarray
        Initial state (see :func:`plant_derivatives`).
    conn : ndarray of int
        Valve connection of each chamber (0 closed, 1 manifold, 2 exhaust).
    actuator : int
        Index of the piston whose arrival ends the segment.
    t_max : float
        Longest segment [s].
    method : str
        ``solve_ivp`` method.
    rtol : float
        Relative tolerance [-].
    atol : ndarray, optional
        Absolute tolerances per state; default scales with the state's magnitude.

    Returns
    -------
    SegmentSolution
    """
    na = plant.ap.shape[0]
    nn = 2 + 2 * na
    stroke = float(plant.ap[actuator, lay.AP_STROKE])
    fric = np.ones(na)
    p_src = float(plant.sp[lay.SP_P_SET] + plant.sp[lay.SP_REG_OFFSET])
    if atol is None:
        atol = np.concatenate(
            [np.maximum(y0[:nn], 1e-9) * rtol, np.full(nn, 1e-3), np.full(na, 1e-7),
             np.full(na, 1e-6)]
        )  # fmt: skip
    calls = [0]

    def rhs(t: float, y: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        calls[0] += 1
        return plant_derivatives(y, plant.sp, plant.ap, plant.cp, conn, p_src, fric)

    def arrived(t: float, y: npt.NDArray[np.float64]) -> float:
        return float(y[2 * nn + actuator] - (stroke - 1e-9))

    arrived.terminal = True  # type: ignore[attr-defined]
    arrived.direction = 1.0  # type: ignore[attr-defined]
    sol = solve_ivp(rhs, (0.0, t_max), y0, method=method, rtol=rtol, atol=atol, events=arrived)
    if sol.t_events[0].size:
        return SegmentSolution(float(sol.t_events[0][0]), sol.y_events[0][0], calls[0])
    return SegmentSolution(float("nan"), sol.y[:, -1], calls[0])
