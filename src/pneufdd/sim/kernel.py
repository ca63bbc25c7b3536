"""Compiled integrator of the machine: supply, valves, chambers, pistons and the PLC.

One call of :func:`run_cycle` simulates one machine cycle (all PLC steps) at a
1 kHz output rate. Inside each 1 ms sample the plant is advanced with ``n``
sub-steps of a linearly-implicit scheme:

* Every pneumatic connection ``i -> j`` (regulator, supply line, valve paths, leaks,
  ejector nozzle) is written as ``f = g (p_i - p_j)`` with the secant conductance
  ``g`` evaluated from the physics flow kernels (eq. 4.3 orifice, eq. 4.6 ISA valve)
  at the start of the sub-step. The pressures at the end of the sub-step follow
  from the implicit (backward-Euler) node balances; the network is a tree
  (source - reservoir - manifold - chambers - atmosphere), so chambers are
  eliminated into the manifold and a 2x2 system remains (O(n) per sub-step).
  The scheme is unconditionally stable and monotone (no pressure overshoot) for
  the stiff small volumes near equilibrium.
* The resulting edge flows update MASS and INTERNAL ENERGY of every node
  (eq. 4.7-4.9 with heat exchange to the wall), so mass is conserved exactly:
  each edge flow leaves one node and enters the other.
* Pistons follow eq. 4.13 with real areas and the atmosphere on the rod,
  ``P_A A_A - P_B A_B - P_atm A_rod - F_f = M x''`` (a return spring a load), Karnopp
  friction (eq. 4.14), inelastic end stops (semi-implicit Euler). A line may be fed
  at its own pressure (regulator or booster): a fixed draw on the manifold.
* Sub-steps adapt: 1 per ms when all is quiet, up to 25 during valve transients and
  strokes. Chambers of resting actuators at the pressure of the node they connect to
  (and without leak) are frozen until the difference exceeds a wake threshold.

The kernel takes five typed records (:mod:`pneufdd.sim.records`: plant parameters,
PLC program, the cycle's random draws, state, outputs). Its physics is the compiled
functions of :mod:`pneufdd.physics`: valve and orifice flow (eq. 4.6, 4.3), chamber
volume and pressure (eq. 4.11, 4.7), the enthalpy an edge carries and a node's mass and
energy step (eq. 4.7-4.9), the piston force (eq. 4.13) and Karnopp friction (eq. 4.14);
:mod:`pneufdd.sim.rhs` calls the same ones, with the energy balance in its derivative
form (``chamber_energy_derivatives_kernel``). The small ones are inlined
(:func:`pneufdd.physics._jit.njit_inline`) and evaluate the kernel's former arithmetic
in its order: bit-identical results, no measurable cost (issue 31). What stays here is the
integrator itself, for which physics/ has no law: the implicit node balances and their
elimination, the secant conductances, the stick/slip state machine and end stops, the
freeze/wake rule, the PLC, and the twin's house-air and ejector models.

The body stays one loop on purpose (``docs/twin.md``, Numerics): split into compiled
stage functions the cycle took 43 % longer (numba passes and reference-counts every
array argument of every stage call once per sub-step), with the stages inlined about
50 % longer, with reference counting off 3-6 % longer. For the same reason its helpers
take scalars only and are inlined; the ISA valve kernel stays one compiled function
shared by its five call sites (inlining it everywhere cost 4 s more compilation for
about 4 % speed). Where the time goes, and the work skipped while it cannot change
anything: ``docs/twin.md``, Speed (issue 13, item 3).

The kernel releases the GIL (``nogil``): the diagnosis's simulation checks run
independent explanations on several threads of one process
(:mod:`pneufdd.diagnosis.localisation.check`).

Faults beyond leaks (issue 34, ``docs/faults.md``; the laws in
:mod:`pneufdd.physics.faults`) enter as parameters the caller sets between cycles
(:mod:`pneufdd.sim.conditions`) and a few branches, each behind a flag computed once per
cycle, so a run without them computes what it did before, bit for bit: a leaking piston
seal couples the two chambers' implicit balances (solved as a pair, still linear in the
manifold pressure), spool leaks add conductances beside the valve paths, a cushion
throttles a chamber's exhaust over its zone, a valve's pilot lengthens its on-delay,
faulty switches change what the PLC reads, the regulator takes a set-point offset and
the supply air its own temperature.

The PLC (section 3.2.3) runs every millisecond: a step starts by applying its
valve commands, ends when all awaited switches (and its dwell timer) are
satisfied, plus a random part of a scan time. Solenoids with an ``until``
condition are released when their switch closes; valve spools follow their
solenoids after the switching delays (20 ms on, 42 ms off, Fig. 4.3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pneufdd.physics.chamber import (
    chamber_energy_step_kernel,
    chamber_pressure_kernel,
    chamber_volume_kernel,
    enthalpy_flow_kernel,
)
from pneufdd.physics.constants import GAMMA_AIR, P_ATM, R_AIR
from pneufdd.physics.faults import (
    PILOT_MIN_NOMINAL_PA,
    cushion_engaged_kernel,
    pilot_delay_factor_kernel,
    regulator_outlet_pressure_kernel,
)
from pneufdd.physics.friction import friction_force_kernel, piston_net_force_kernel
from pneufdd.sim import layout as lay
from pneufdd.sim.conductances import house_pressure as _house_pressure
from pneufdd.sim.conductances import isa_conductance as _isa_g
from pneufdd.sim.conductances import line_source_pressure as _line_source
from pneufdd.sim.conductances import orifice_conductance as _orifice_g
from pneufdd.sim.layout import SAMPLE_DT
from pneufdd.sim.records import CycleDraws, Outputs, PlantParams, Program, State
from pneufdd.sim.signal_kernels import (
    first_order_recursion_kernel,
    sensor_reading_kernel,
    truth_rows_kernel,
)

__all__ = [
    "SAMPLE_DT",
    "first_order_recursion_kernel",
    "run_cycle",
    "sensor_reading_kernel",
    "truth_rows_kernel",
]

_G = GAMMA_AIR
# Travel after a breakaway, without re-sticking, that makes it the start of sustained
# motion (the stroke start of section 3.3) rather than a stick-slip creep [m].
_SUSTAINED_TRAVEL = 2e-4
_WAKE = 300.0  # pressure difference that wakes a frozen chamber [Pa]
_SLEEP = 30.0  # pressure difference below which a resting chamber may freeze [Pa]


@njit(cache=True, nogil=True)
def run_cycle(
    plant: PlantParams,
    program: Program,
    draws: CycleDraws,
    state: State,
    out: Outputs,
) -> tuple[int, int, int, int]:
    """Simulate one PLC cycle; ``state`` and ``out`` are updated in place.

    Returns
    -------
    n_samples : int
        Number of 1 kHz samples written to the ``out_*`` arrays.
    status : int
        0 = cycle complete; 1 = output buffer full (machine stalled).
    n_events : int
        Number of stroke records written to ``ev_*``.
    substeps : int
        Total number of integration sub-steps taken.
    """
    # the records' arrays, unpacked once per cycle (not in the hot loops)
    sp, ap, vkind, cp = plant
    act_start, act_sol, act_mode, act_sw, act_dur, wait_start, wait_sw, wait_val, dwell = program
    jitter, fric, ou = draws
    m, temp, x, v, stuck, spool, cmd, eff, chg, rel_sw, rel_t, ss, istate, cum = state[:14]
    mv_t0, mv_dir, sw_t = state.mv_t0, state.mv_dir, state.sw_t
    out_p, out_x, out_vac, out_fch, out_fexh, out_fleak, out_fr, out_cum = out[:8]
    out_mass, out_cmd, out_sw, out_step, step_t = out[8:13]
    ev_act, ev_dir, ev_t0, ev_t1, out_fpl = out.ev_act, out.ev_dir, out.ev_t0, out.ev_t1, out.fpl
    na = x.size
    nc = 2 * na
    nn = 2 + nc
    ns = cmd.size
    nsw = out_sw.shape[1]
    has_vac = ns > nc
    nsteps = dwell.size
    max_samples = out_p.shape[0]
    t_wall = sp[lay.SP_T_WALL]
    window = sp[lay.SP_WINDOW]
    n_move = int(sp[lay.SP_N_MOVE])
    n_max = int(sp[lay.SP_N_MAX])
    dp_tol = sp[lay.SP_DP_TOL]
    t0 = ss[lay.SS_TIME]
    ou_dt = sp[lay.SP_OU_DT]
    n_ou = ou.size
    comp_period = sp[lay.SP_COMP_PERIOD]
    comp_phase = sp[lay.SP_COMP_PHASE]
    p_house = sp[lay.SP_P_HOUSE]
    comp_band = sp[lay.SP_COMP_BAND]
    vol = np.empty(nn)
    vdot = np.zeros(nn)
    vol[0] = sp[lay.SP_V_RES]
    vol[1] = sp[lay.SP_V_MAN]
    p = np.empty(nn)
    energy_in = np.zeros(nn)
    dm = np.zeros(nn)
    g_fill = np.zeros(nc)
    g_exh = np.zeros(nc)
    g_leak = np.zeros(nc)
    src = np.zeros(nc)  # a line fed by its own regulator or booster: its pressure; else 0
    g_own = np.zeros(nc)  # and its fill conductance from there
    # own line pressures, springs: tested once a cycle; without them, the loops as before
    own_lines = np.any(cp[:, lay.CP_P_LINE] > 0.0)
    springs = np.any(ap[:, lay.AP_SPRING_F0] != 0.0) or np.any(ap[:, lay.AP_SPRING_K] != 0.0)
    conn = np.zeros(nc, dtype=np.int64)  # 0 closed, 1 manifold, 2 exhaust
    awake = np.ones(nc, dtype=np.int64)
    aw = np.zeros(nc, dtype=np.int64)
    alpha = np.zeros(nc)
    beta = np.zeros(nc)
    sw = np.zeros(nsw, dtype=np.uint8)
    # faults (issue 34, docs/faults.md): which of their branches this cycle needs, and
    # the chambers a leak or a fault keeps awake
    t_sup = sp[lay.SP_T_SUPPLY]
    hold = np.zeros(nc, dtype=np.int64)
    g_pl = np.zeros(na)
    has_pl = has_cush = has_spool = False
    has_swf = has_vac and sp[lay.SP_VSW_MODE] != lay.SW_OK
    for c in range(nc):
        spool_leak = cp[c, lay.CP_SPOOL_IN] > 0.0 or cp[c, lay.CP_SPOOL_OUT] > 0.0
        piston_leak = ap[c // 2, lay.AP_PISTON_LEAK] > 0.0
        has_spool = has_spool or spool_leak
        has_pl = has_pl or piston_leak
        has_cush = has_cush or ap[c // 2, lay.AP_CUSH_LEN] > 0.0
        has_swf = has_swf or cp[c, lay.CP_SW_MODE] != lay.SW_OK
        if cp[c, lay.CP_LEAK] > 0.0 or spool_leak or piston_leak:
            hold[c] = 1
    n_ev = 0
    total_sub = 0
    dp_prev = 1e9
    spool_changed = True
    n_out = 0
    istate[lay.IS_STEP] = 0
    istate[lay.IS_PHASE] = -1  # -1: step not yet started
    istate[lay.IS_CYCLE_DONE] = 0

    # heat exchange: the gas temperature relaxes to the wall with exp(-dt / tau)
    decay = np.ones((n_max + 1, nn))
    for q in range(1, n_max + 1):
        for j in range(nn):
            tau = sp[lay.SP_TAU_TH] if j < 2 else cp[j - 2, lay.CP_TAU_TH]
            decay[q, j] = math.exp(-SAMPLE_DT / q / tau)
    for c in range(nc):
        i = c // 2  # eq. 4.11, chamber A (c even) or B (c odd)
        vol[2 + c] = chamber_volume_kernel(
            x[i], cp[c, lay.CP_AREA], cp[c, lay.CP_DEAD], ap[i, lay.AP_STROKE], float(c % 2)
        )
    # node pressures [Pa]: kept current, recomputed only where a node's state changes
    for j in range(nn):
        p[j] = chamber_pressure_kernel(m[j], temp[j], vol[j])
    # Work skipped while it cannot change anything (the first sample does all of it):
    # the position switches while no piston moved, the release checks while no
    # solenoid waits for a release, the spool logic while no solenoid changed.
    x_moved = True
    armed = True
    pending = True
    eff_changed = True

    while True:
        t = ss[lay.SS_TIME]
        # ---------------------------------------------------------- switches
        if x_moved or has_swf:
            for i in range(na):
                sw[2 * i] = 1 if x[i] <= window else 0
                sw[2 * i + 1] = 1 if x[i] >= ap[i, lay.AP_STROKE] - window else 0
            x_moved = False
        if has_vac:
            sw[nc] = 1 if ss[lay.SS_VAC] >= sp[lay.SP_VAC_LEVEL] else 0
        if has_swf:  # faulty switches: what the PLC reads instead (docs/faults.md)
            for s in range(nsw):
                mode = cp[s, lay.CP_SW_MODE] if s < nc else sp[lay.SP_VSW_MODE]
                if sw[s] == 0:
                    sw_t[s] = lay.SW_OFF
                elif sw_t[s] == lay.SW_OFF:  # the piston (or the vacuum) just arrived
                    sw_t[s] = lay.SW_MISSED if mode == lay.SW_MISS else t
                if mode == lay.SW_STUCK_ON:
                    sw[s] = 1
                elif mode == lay.SW_STUCK_OFF or sw_t[s] == lay.SW_MISSED:
                    sw[s] = 0
                elif mode == lay.SW_LATE and sw[s] == 1:
                    delay = cp[s, lay.CP_SW_PARAM] if s < nc else sp[lay.SP_VSW_PARAM]
                    if t - sw_t[s] < delay - 1e-9:
                        sw[s] = 0
        # ---------------------------------------------------------------- PLC
        if armed:
            armed = False
            for s in range(ns):
                by_switch = rel_sw[s] >= 0 and sw[rel_sw[s]] == 1
                by_time = rel_t[s] >= 0.0 and t >= rel_t[s]
                if cmd[s] == 1 and (by_switch or by_time):
                    cmd[s] = 0
                    chg[s] = t
                    rel_sw[s] = -1
                    rel_t[s] = -1.0
                    pending = True
                elif cmd[s] == 1 and (rel_sw[s] >= 0 or rel_t[s] >= 0.0):
                    armed = True
        k = istate[lay.IS_STEP]
        if istate[lay.IS_PHASE] == 1 and t >= ss[lay.SS_PHASE_END] - 1e-9:
            k += 1
            istate[lay.IS_STEP] = k
            istate[lay.IS_PHASE] = -1
            if k >= nsteps:
                istate[lay.IS_CYCLE_DONE] = 1
                break
        if istate[lay.IS_PHASE] == -1:
            step_t[k] = t
            for a in range(act_start[k], act_start[k + 1]):
                s = act_sol[a]
                mode = act_mode[a]
                if mode == 3:
                    if cmd[s] == 1:
                        cmd[s] = 0
                        chg[s] = t
                    rel_sw[s] = -1
                    rel_t[s] = -1.0
                else:
                    if cmd[s] == 0:
                        cmd[s] = 1
                        chg[s] = t
                    rel_sw[s] = act_sw[a] if mode == 0 else -1
                    rel_t[s] = t + act_dur[a] if mode == 1 else -1.0
                    armed = armed or mode <= 1
            pending = True
            istate[lay.IS_PHASE] = 0
        if istate[lay.IS_PHASE] == 0:
            ok = True
            for w in range(wait_start[k], wait_start[k + 1]):
                if sw[wait_sw[w]] != wait_val[w]:
                    ok = False
                    break
            if ok:
                istate[lay.IS_PHASE] = 1
                ss[lay.SS_PHASE_END] = t + dwell[k] + jitter[k]
        # ------------------------------------------------- solenoids -> spools
        if pending:
            pending = False
            for s in range(ns):
                if eff[s] != cmd[s]:
                    if s < nc:
                        delay = (
                            ap[s // 2, lay.AP_ON_DELAY]
                            if cmd[s] == 1
                            else ap[s // 2, lay.AP_OFF_DELAY]
                        )
                    else:
                        delay = sp[lay.SP_VAC_ON_DELAY] if cmd[s] == 1 else sp[lay.SP_VAC_OFF_DELAY]
                    if cmd[s] == 1 and s < nc and ap[s // 2, lay.AP_PILOT_MIN] > 0.0:
                        # a valve whose pilot needs more pressure shifts later
                        delay *= pilot_delay_factor_kernel(
                            p[1] - P_ATM, PILOT_MIN_NOMINAL_PA, ap[s // 2, lay.AP_PILOT_MIN]
                        )
                    if t - chg[s] >= delay - 1e-9:
                        eff[s] = cmd[s]
                        eff_changed = True
                    else:
                        pending = True
        for i in range(na if eff_changed else 0):
            ea = eff[2 * i]
            eb = eff[2 * i + 1]
            old = spool[i]
            if vkind[i] == lay.VK_BISTABLE:
                if ea == 1 and eb == 0:
                    spool[i] = 1
                elif eb == 1 and ea == 0:
                    spool[i] = -1
            elif vkind[i] == lay.VK_MONOSTABLE or vkind[i] == lay.VK_SINGLE_ACTING:
                spool[i] = 1 if ea == 1 else -1
            elif vkind[i] == lay.VK_CLOSED_CENTRE:
                if ea == 1 and eb == 0:
                    spool[i] = 1
                elif eb == 1 and ea == 0:
                    spool[i] = -1
                else:
                    spool[i] = 0
            if spool[i] != old:
                spool_changed = True
                awake[2 * i] = 1
                awake[2 * i + 1] = 1
            if spool[i] == 1:
                conn[2 * i] = 1
                conn[2 * i + 1] = 2
            elif spool[i] == -1:
                conn[2 * i] = 2
                # a single-acting cylinder's spring side is vented, never supplied
                conn[2 * i + 1] = 2 if vkind[i] == lay.VK_SINGLE_ACTING else 1
            else:
                conn[2 * i] = 0
                conn[2 * i + 1] = 0
        eff_changed = False
        vac_on = has_vac and eff[nc] == 1
        # -------------------------------------------------------------- record
        if n_out >= max_samples:
            return n_out, 1, n_ev, total_sub
        for j in range(nn):
            out_p[n_out, j] = p[j]
        for i in range(na):
            out_x[n_out, i] = x[i]
        for i in range(na if has_pl else 0):  # without: not written (the caller knows)
            out_fpl[n_out, i] = 0.0  # summed over the sub-steps below
        out_vac[n_out] = ss[lay.SS_VAC]
        for s in range(ns):
            out_cmd[n_out, s] = cmd[s]
        for s in range(nsw):
            out_sw[n_out, s] = sw[s]
        out_step[n_out] = k
        mass = 0.0
        for j in range(nn):
            mass += m[j]
        out_mass[n_out] = mass
        for q in range(cum.size):
            out_cum[n_out, q] = cum[q]
        # -------------------------------------------------- freeze / wake
        any_moving = False
        for i in range(na):
            if stuck[i] == 0:
                any_moving = True
        for c in range(nc):
            i = c // 2
            if stuck[i] == 0 or hold[c] == 1:
                awake[c] = 1
                continue
            if conn[c] == 1:
                p_up = _line_source(p[1], cp[c, lay.CP_P_LINE], cp[c, lay.CP_BOOST])
                d = abs(p[2 + c] - (p_up if own_lines else p[1]))
            elif conn[c] == 2:
                d = abs(p[2 + c] - P_ATM)
            else:
                d = 0.0
            # an exhausted chamber holds almost no air: its temperature does not matter
            settled = conn[c] == 2 or abs(temp[2 + c] - t_wall) < 0.5
            if awake[c] == 1 and d < _SLEEP and settled:
                awake[c] = 0
            elif awake[c] == 0 and d > _WAKE:
                awake[c] = 1
        n_aw = 0  # the awake chambers, in order: the sub-step loops run over these only
        for c in range(nc):
            if awake[c] == 1:
                aw[n_aw] = c
                n_aw += 1
        # ---------------------------------------------------- sub-step count
        nsub = 1
        if any_moving:
            nsub = n_move
        need = math.ceil(dp_prev / dp_tol)
        if need > nsub:
            nsub = need
        if spool_changed:
            nsub = n_max
        if nsub > n_max:
            nsub = n_max
        spool_changed = False
        dt = SAMPLE_DT / nsub
        total_sub += nsub
        for c in range(nc):
            out_fch[n_out, c] = 0.0
            out_fexh[n_out, c] = 0.0
            out_fleak[n_out, c] = 0.0
        for q in range(4):
            out_fr[n_out, q] = 0.0
        p_start_m = p[1]
        dp_max = 0.0
        for sub in range(nsub):
            ts = t + sub * dt
            u_ou = (ts - t0) / ou_dt
            i_ou = int(u_ou)
            if i_ou >= n_ou - 1:
                drift = ou[n_ou - 1]
            else:
                w_ou = u_ou - i_ou
                drift = ou[i_ou] * (1.0 - w_ou) + ou[i_ou + 1] * w_ou
            ph = _house_pressure(ts, comp_period, comp_phase, p_house, comp_band, drift)
            p_src = regulator_outlet_pressure_kernel(
                sp[lay.SP_P_SET], sp[lay.SP_REG_EFFECT], ph, p_house, sp[lay.SP_REG_OFFSET]
            )
            for j in range(nn):
                energy_in[j] = 0.0
                dm[j] = 0.0
            # ----- conductances at the start of the sub-step
            if p_src > p[0]:
                g_sr = _isa_g(p_src, p[0], sp[lay.SP_REG_CV], sp[lay.SP_REG_XT], t_sup, temp[0])
            else:
                g_sr = 0.0  # non-relieving regulator: no back flow
            g_rm = _isa_g(p[0], p[1], sp[lay.SP_LINE_CV], sp[lay.SP_LINE_XT], temp[0], temp[1])
            g_ml = _orifice_g(p[1], P_ATM, sp[lay.SP_SUPPLY_LEAK], temp[1], t_wall)
            g_mv = 0.0
            if vac_on:
                g_mv = _orifice_g(p[1], P_ATM, sp[lay.SP_NOZZLE], temp[1], t_wall)
            a_r = vol[0] / (_G * R_AIR * temp[0] * dt)
            a_m = vol[1] / (_G * R_AIR * temp[1] * dt)
            lhs_m = a_m + g_rm + g_ml + g_mv
            rhs_m = a_m * p[1] + (g_ml + g_mv) * P_ATM
            # conductances of the awake chambers (independent: the CPU overlaps them)
            for q in range(n_aw):
                c = aw[q]
                j = 2 + c
                g_fill[c] = 0.0
                g_exh[c] = 0.0
                if conn[c] == 1:
                    g_fill[c] = _isa_g(
                        p[1], p[j], cp[c, lay.CP_CV_FILL], cp[c, lay.CP_XT], temp[1], temp[j]
                    )
                elif conn[c] == 2:
                    g_exh[c] = _isa_g(
                        p[j], P_ATM, cp[c, lay.CP_CV_EXH], cp[c, lay.CP_XT], temp[j], t_wall
                    )
                g_leak[c] = _orifice_g(p[j], P_ATM, cp[c, lay.CP_LEAK], temp[j], t_wall)
            if own_lines:
                # own regulator or booster: a non-relieving source, not the manifold
                for q in range(n_aw):
                    c = aw[q]
                    j = 2 + c
                    src[c] = 0.0
                    g_own[c] = 0.0
                    if conn[c] == 1:
                        p_up = _line_source(p[1], cp[c, lay.CP_P_LINE], cp[c, lay.CP_BOOST])
                        if p_up != p[1]:
                            src[c] = p_up
                            g_fill[c] = 0.0
                            cv, xt = cp[c, lay.CP_CV_FILL], cp[c, lay.CP_XT]
                            if p[j] < p_up:
                                g_own[c] = _isa_g(p_up, p[j], cv, xt, temp[1], temp[j])
            # faults (issue 34), in loops of their own so that the loops above and
            # below stay those of a run without them: a cushion throttling an exhaust,
            # a worn spool (supply -> port, port -> exhaust)
            for q in range(n_aw if has_cush or has_spool else 0):
                c = aw[q]
                j = 2 + c
                i = c // 2
                if (
                    has_cush
                    and conn[c] == 2
                    and cushion_engaged_kernel(
                        x[i], ap[i, lay.AP_STROKE], ap[i, lay.AP_CUSH_LEN], float(c % 2)
                    )
                ):
                    cv_e = cp[c, lay.CP_CV_CUSH]
                    g_exh[c] = _isa_g(p[j], P_ATM, cv_e, cp[c, lay.CP_XT], temp[j], t_wall)
                g_fill[c] += _orifice_g(p[1], p[j], cp[c, lay.CP_SPOOL_IN], temp[1], temp[j])
                g_exh[c] += _orifice_g(p[j], P_ATM, cp[c, lay.CP_SPOOL_OUT], temp[j], t_wall)
            for q in range(0 if has_pl else n_aw):
                c = aw[q]
                j = 2 + c
                a_c = vol[j] / (_G * R_AIR * temp[j] * dt)
                s_c = 0.0 if vdot[j] == 0.0 else -p[j] * vdot[j] / (R_AIR * temp[j])
                den = a_c + g_fill[c] + g_exh[c] + g_leak[c]
                alpha[c] = (a_c * p[j] + s_c + (g_exh[c] + g_leak[c]) * P_ATM) / den
                beta[c] = g_fill[c] / den
                lhs_m += g_fill[c] * (1.0 - beta[c])
                rhs_m += g_fill[c] * alpha[c]
            # a leaking piston seal joins chambers A and B: their two balances are
            # solved together, still linear in the manifold pressure (the same loop as
            # above, its leaking pairs kept for the pair solution)
            for q in range(n_aw if has_pl else 0):
                c = aw[q]
                j = 2 + c
                a_c = vol[j] / (_G * R_AIR * temp[j] * dt)
                s_c = 0.0 if vdot[j] == 0.0 else -p[j] * vdot[j] / (R_AIR * temp[j])
                den = a_c + g_fill[c] + g_exh[c] + g_leak[c]
                num = a_c * p[j] + s_c + (g_exh[c] + g_leak[c]) * P_ATM
                if ap[c // 2, lay.AP_PISTON_LEAK] > 0.0:
                    alpha[c] = num
                    beta[c] = den
                    continue
                alpha[c] = num / den
                beta[c] = g_fill[c] / den
                lhs_m += g_fill[c] * (1.0 - beta[c])
                rhs_m += g_fill[c] * alpha[c]
            for i in range(na if has_pl else 0):
                if ap[i, lay.AP_PISTON_LEAK] <= 0.0:
                    continue
                ca = 2 * i
                cb = ca + 1
                g = _orifice_g(
                    p[2 + ca], p[2 + cb], ap[i, lay.AP_PISTON_LEAK], temp[2 + ca], temp[2 + cb]
                )
                g_pl[i] = g
                den_a = beta[ca] + g
                den_b = beta[cb] + g
                num_a = alpha[ca]
                num_b = alpha[cb]
                det = den_a * den_b - g * g
                alpha[ca] = (den_b * num_a + g * num_b) / det
                beta[ca] = (den_b * g_fill[ca] + g * g_fill[cb]) / det
                alpha[cb] = (g * num_a + den_a * num_b) / det
                beta[cb] = (g * g_fill[ca] + den_a * g_fill[cb]) / det
                lhs_m += g_fill[ca] * (1.0 - beta[ca]) + g_fill[cb] * (1.0 - beta[cb])
                rhs_m += g_fill[ca] * alpha[ca] + g_fill[cb] * alpha[cb]
            if own_lines:  # the own sources: a fixed draw on the manifold
                for q in range(n_aw):
                    c = aw[q]
                    if src[c] > 0.0:
                        j = 2 + c
                        a_c = vol[j] / (_G * R_AIR * temp[j] * dt)
                        s_c = 0.0 if vdot[j] == 0.0 else -p[j] * vdot[j] / (R_AIR * temp[j])
                        den = a_c + g_own[c] + g_exh[c] + g_leak[c]
                        alpha[c] = (
                            a_c * p[j] + s_c + (g_exh[c] + g_leak[c]) * P_ATM + g_own[c] * src[c]
                        ) / den
                        rhs_m -= g_own[c] * (src[c] - alpha[c])
            # 2x2: reservoir and manifold
            a11 = a_r + g_sr + g_rm
            b1 = a_r * p[0] + g_sr * p_src
            det = a11 * lhs_m - g_rm * g_rm
            pr_new = (b1 * lhs_m + g_rm * rhs_m) / det
            pm_new = (a11 * rhs_m + g_rm * b1) / det
            # ----- edge flows (positive in the named direction)
            f_reg = g_sr * (p_src - pr_new)
            f_line = g_rm * (pr_new - pm_new)
            f_sl = g_ml * (pm_new - P_ATM)
            f_vac = g_mv * (pm_new - P_ATM)
            dm[0] += f_reg - f_line
            dm[1] += f_line - f_sl - f_vac
            energy_in[0] += enthalpy_flow_kernel(f_reg, t_sup, t_sup)
            h = enthalpy_flow_kernel(f_line, temp[0], temp[1])
            energy_in[0] -= h
            energy_in[1] += h
            energy_in[1] -= enthalpy_flow_kernel(f_sl + f_vac, temp[1], t_wall)
            out_fr[n_out, lay.FR_REG] += f_reg
            out_fr[n_out, lay.FR_LINE] += f_line
            out_fr[n_out, lay.FR_SUPPLY_LEAK] += f_sl
            out_fr[n_out, lay.FR_VAC] += f_vac
            for q in range(n_aw):
                c = aw[q]
                j = 2 + c
                pc_new = alpha[c] + beta[c] * pm_new
                f_in = g_fill[c] * (pm_new - pc_new)
                f_ex = g_exh[c] * (pc_new - P_ATM)
                f_lk = g_leak[c] * (pc_new - P_ATM)
                dm[1] -= f_in
                dm[j] += f_in - f_ex - f_lk
                h = enthalpy_flow_kernel(f_in, temp[1], temp[j])
                energy_in[1] -= h
                energy_in[j] += h
                energy_in[j] -= enthalpy_flow_kernel(f_ex + f_lk, temp[j], t_wall)
                out_fch[n_out, c] += f_in
                out_fexh[n_out, c] += f_ex
                out_fleak[n_out, c] += f_lk
                cum[lay.CM_EXHAUST] += f_ex * dt
                cum[lay.CM_LEAK] += f_lk * dt
            for i in range(na if has_pl else 0):
                if ap[i, lay.AP_PISTON_LEAK] <= 0.0:
                    continue
                ja = 2 + 2 * i
                jb = ja + 1
                pa_new = alpha[ja - 2] + beta[ja - 2] * pm_new
                pb_new = alpha[jb - 2] + beta[jb - 2] * pm_new
                f_pl = g_pl[i] * (pa_new - pb_new)
                dm[ja] -= f_pl
                dm[jb] += f_pl
                h = enthalpy_flow_kernel(f_pl, temp[ja], temp[jb])
                energy_in[ja] -= h
                energy_in[jb] += h
                out_fpl[n_out, i] += f_pl
            if own_lines:  # the own sources' inflow, drawn from the manifold
                for q in range(n_aw):
                    c = aw[q]
                    if src[c] > 0.0:
                        j = 2 + c
                        f_in = g_own[c] * (src[c] - alpha[c])
                        dm[1] -= f_in
                        dm[j] += f_in
                        h = enthalpy_flow_kernel(f_in, temp[1], temp[j])
                        energy_in[1] -= h
                        energy_in[j] += h
                        out_fch[n_out, c] += f_in
            cum[lay.CM_REG] += f_reg * dt
            cum[lay.CM_LINE] += f_line * dt
            cum[lay.CM_LEAK] += f_sl * dt
            cum[lay.CM_VAC] += f_vac * dt
            # ----- pistons (eq. 4.13, 4.14) with the pressures at sub-step start: force
            # and friction from physics/; the stick/slip switching, end stops and stroke
            # records are the integrator's (semi-implicit Euler), so they stay here
            for i in range(na):
                ca = 2 + 2 * i
                cb = ca + 1
                vdot[ca] = 0.0
                vdot[cb] = 0.0
                if stuck[i] == 1 and awake[2 * i] == 0 and awake[2 * i + 1] == 0:
                    continue
                stroke = ap[i, lay.AP_STROKE]
                force = piston_net_force_kernel(
                    p[ca],
                    p[cb],
                    cp[2 * i, lay.CP_AREA],
                    cp[2 * i + 1, lay.CP_AREA],
                    ap[i, lay.AP_AROD],
                )
                if springs:
                    # a return spring pushes towards the home end (x = 0)
                    force -= ap[i, lay.AP_SPRING_F0] + ap[i, lay.AP_SPRING_K] * x[i]
                fs = ap[i, lay.AP_FS] * fric[i]
                fc = ap[i, lay.AP_FC] * fric[i]
                cvf = ap[i, lay.AP_CVF]
                if stuck[i] == 1:
                    blocked = (x[i] <= 0.0 and force <= 0.0) or (x[i] >= stroke and force >= 0.0)
                    if blocked or abs(force) <= fs:
                        continue
                    stuck[i] = 0
                    if mv_t0[i, 0] < 0.0:
                        mv_t0[i, 0] = ts
                        mv_dir[i] = 1 if force > 0.0 else -1
                        mv_t0[i, 3] = 0.0
                    if mv_t0[i, 3] == 0.0:
                        # a (new) breakaway before sustained travel: candidate start
                        mv_t0[i, 1] = ts
                        mv_t0[i, 2] = x[i]
                    v_old = 0.0
                else:
                    v_old = v[i]
                ff = friction_force_kernel(v_old, force, fs, fc, cvf, lay.STICK_BAND)
                acc = (force - ff) / ap[i, lay.AP_MASS]
                v_new = v_old + acc * dt
                if v_old != 0.0 and v_new * v_old < 0.0:
                    v_new = 0.0
                    stuck[i] = 1
                elif abs(v_new) < lay.STICK_BAND and abs(force) <= fs:
                    # inside the Karnopp band with a force below breakaway: sticks
                    v_new = 0.0
                    stuck[i] = 1
                x_new = x[i] + v_new * dt
                if x_new <= 0.0:
                    x_new = 0.0
                    v_new = 0.0
                    stuck[i] = 1
                elif x_new >= stroke:
                    x_new = stroke
                    v_new = 0.0
                    stuck[i] = 1
                if mv_t0[i, 3] == 0.0 and abs(x_new - mv_t0[i, 2]) >= _SUSTAINED_TRAVEL:
                    mv_t0[i, 3] = 1.0
                if stuck[i] == 1 and mv_t0[i, 0] >= 0.0 and (x_new <= 0.0 or x_new >= stroke):
                    if n_ev < ev_act.size:
                        ev_act[n_ev] = i
                        ev_dir[n_ev] = mv_dir[i]
                        ev_t0[n_ev, 0] = mv_t0[i, 1]
                        ev_t0[n_ev, 1] = mv_t0[i, 0]
                        ev_t1[n_ev] = ts + dt
                        n_ev += 1
                    mv_t0[i, 0] = -1.0
                    mv_t0[i, 3] = 1.0
                vdot[ca] = cp[2 * i, lay.CP_AREA] * (x_new - x[i]) / dt
                vdot[cb] = -cp[2 * i + 1, lay.CP_AREA] * (x_new - x[i]) / dt
                if x_new != x[i]:
                    x_moved = True
                x[i] = x_new
                v[i] = v_new
            # ----- mass and energy update (eq. 4.7-4.9), heat exchange to the wall; the
            # step is physics' (inlined, same bits), the volume follows the piston
            for j in range(nn):
                if j >= 2 and awake[j - 2] == 0 and vdot[j] == 0.0:
                    continue
                m_new, t_new = chamber_energy_step_kernel(
                    m[j], temp[j], p[j], vdot[j], dm[j], energy_in[j], dt, t_wall, decay[nsub, j]
                )
                v_new_j = vol[j] + vdot[j] * dt
                m[j] = m_new
                temp[j] = t_new
                vol[j] = v_new_j
                p[j] = chamber_pressure_kernel(m_new, t_new, v_new_j)
            # vacuum level (first order towards full vacuum while the ejector blows)
            if has_vac:
                if vac_on:
                    # an ejector reaches its full vacuum from ~50 % of the nominal supply
                    # gauge pressure on; below that the attainable vacuum falls linearly
                    drive = 2.0 * (pm_new - P_ATM) / (sp[lay.SP_VAC_P_RATED] - P_ATM)
                    drive = min(max(drive, 0.0), 1.0)
                    ss[lay.SS_VAC] += dt * (drive - ss[lay.SS_VAC]) / sp[lay.SP_VAC_TAU_ON]
                else:
                    ss[lay.SS_VAC] -= dt * ss[lay.SS_VAC] / sp[lay.SP_VAC_TAU_OFF]
        # ----------------------------------------- finish the 1 ms sample
        if nsub > 1:  # sums of the sub-steps -> mean flows over the sample
            for q in range(n_aw):
                c = aw[q]
                out_fch[n_out, c] /= nsub
                out_fexh[n_out, c] /= nsub
                out_fleak[n_out, c] /= nsub
            for q in range(4):
                out_fr[n_out, q] /= nsub
            for i in range(na if has_pl else 0):
                out_fpl[n_out, i] /= nsub
        dp_max = 0.0
        for q in range(n_aw):
            c = aw[q]
            d = abs(p[2 + c] - out_p[n_out, 2 + c])
            if d > dp_max:
                dp_max = d
        d = abs(p[1] - p_start_m)
        if d > dp_max:
            dp_max = d
        dp_prev = dp_max
        n_out += 1
        istate[lay.IS_SAMPLE] += 1
        ss[lay.SS_TIME] = istate[lay.IS_SAMPLE] * SAMPLE_DT
    return n_out, 0, n_ev, total_sub
