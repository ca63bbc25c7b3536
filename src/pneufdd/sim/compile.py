"""Turn a :class:`MachineDescription` and leaks into the arrays of the integrator."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pneufdd.physics.constants import KELVIN_OFFSET, PSI, R_AIR
from pneufdd.physics.restrictions import series_cv
from pneufdd.physics.units import psig_to_pa
from pneufdd.sim import layout as lay
from pneufdd.sim.description import Actuator, MachineDescription, solenoid_slots
from pneufdd.sim.leaks import LeakSpec

__all__ = [
    "DEFAULT_RESOLUTION",
    "Plant",
    "Resolution",
    "compile_plant",
    "piston_areas",
    "series_cv",
    "tube_cv",
]

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

TUBE_FRICTION_FACTOR = 0.03
"""Darcy friction factor of PU tubing at the rig's Reynolds numbers [-] (assumption)."""
TUBE_MINOR_LOSS = 1.5
"""Entrance plus exit loss coefficient of a tube run with push-in fittings [-]."""
_VALVE_KIND = {
    "5/2-bistable": lay.VK_BISTABLE,
    "5/2-monostable": lay.VK_MONOSTABLE,
    "5/3-closed-centre": lay.VK_CLOSED_CENTRE,
    "3/2-monostable": lay.VK_SINGLE_ACTING,
}
_MODE = {"until": 0, "pulse": 1, "hold": 2, "reset": 3}
BREATHER_CV = 0.5
"""Flow coefficient of the vent of a single-acting cylinder's spring side (a sintered
breather in its port, about 500 l/min ANR; assumption, docs/energy.md) [-]."""


def tube_cv(length_m: float, inner_diameter_mm: float) -> float:
    """Flow coefficient of a straight tube, ``Cv = 29.9 d^2 / sqrt(K)`` (Crane TP-410).

    Parameters
    ----------
    length_m : float
        Tube length [m].
    inner_diameter_mm : float
        Inner diameter [mm].

    Returns
    -------
    float
        Equivalent flow coefficient [US gpm/psi^0.5], with ``K = f L / d + 1.5``.

    Examples
    --------
    >>> round(tube_cv(1.0, 4.0), 3)
    0.247
    """
    d_in = inner_diameter_mm / 25.4
    k = TUBE_FRICTION_FACTOR * length_m / (inner_diameter_mm * 1e-3) + TUBE_MINOR_LOSS
    return 29.9 * d_in**2 / math.sqrt(k)


@dataclass
class Plant:
    """Numeric arrays of one machine with its leaks (see :mod:`pneufdd.sim.layout`)."""

    sp: F64
    ap: F64
    vkind: I64
    cp: F64
    act_start: I64
    act_sol: I64
    act_mode: I64
    act_sw: I64
    act_dur: F64
    wait_start: I64
    wait_sw: I64
    wait_val: I64
    dwell: F64
    n_solenoids: int
    n_switches: int
    t_wall: float


def piston_areas(a: Actuator) -> tuple[float, float, float]:
    """Piston area of side A, annular area of side B and rod area [m^2]."""
    area_a = math.pi * (a.bore_mm * 1e-3) ** 2 / 4.0
    rod = math.pi * (a.rod_mm * 1e-3) ** 2 / 4.0
    return area_a, area_a - rod, rod


@dataclass(frozen=True)
class Resolution:
    """Accuracy knobs of the integrator (sub-steps inside each 1 ms output sample).

    Attributes
    ----------
    moving_substeps : int
        Minimum sub-steps per ms while any piston moves [-].
    pressure_step_pa : float
        Target largest pressure change of any active node per sub-step [Pa].
    max_substeps : int
        Sub-steps per ms right after a valve switches, and the upper limit [-].
    """

    moving_substeps: int = 1
    pressure_step_pa: float = 5000.0
    max_substeps: int = 10


DEFAULT_RESOLUTION = Resolution()


def compile_plant(
    machine: MachineDescription,
    leaks: list[LeakSpec],
    resolution: Resolution = DEFAULT_RESOLUTION,
) -> Plant:
    """Build the integrator's arrays from a validated description and resolved leaks."""
    s = machine.supply
    t_wall = machine.temperature_c + KELVIN_OFFSET
    sp = np.zeros(lay.SP_SIZE)
    sp[lay.SP_P_HOUSE] = psig_to_pa(s.house_psig)
    sp[lay.SP_DRIFT_STD] = s.house_drift_psi * PSI
    sp[lay.SP_COMP_BAND] = s.compressor_band_psi * PSI
    sp[lay.SP_COMP_PERIOD] = s.compressor_period_s
    sp[lay.SP_P_SET] = psig_to_pa(s.regulator_set_psig)
    sp[lay.SP_REG_CV] = s.regulator_cv
    sp[lay.SP_REG_XT] = s.regulator_xt
    sp[lay.SP_REG_EFFECT] = s.regulator_supply_effect
    sp[lay.SP_V_RES] = s.reservoir_volume_l * 1e-3
    sp[lay.SP_LINE_CV] = s.line_cv
    sp[lay.SP_LINE_XT] = s.line_xt
    sp[lay.SP_V_MAN] = s.manifold_volume_l * 1e-3
    sp[lay.SP_TAU_TH] = s.thermal_time_s
    sp[lay.SP_T_WALL] = t_wall
    sp[lay.SP_T_SUPPLY] = t_wall  # the supply air at the ambient temperature
    sp[lay.SP_SCAN] = machine.scan_time_s
    sp[lay.SP_WINDOW] = machine.switch_window_mm * 1e-3
    sp[lay.SP_OU_DT] = 0.1
    sp[lay.SP_N_MOVE] = resolution.moving_substeps
    sp[lay.SP_DP_TOL] = resolution.pressure_step_pa
    sp[lay.SP_N_MAX] = resolution.max_substeps
    vac = machine.vacuum
    if vac is not None:
        sp[lay.SP_NOZZLE] = vac.nozzle_cd * math.pi * (vac.nozzle_diameter_mm * 1e-3) ** 2 / 4
        sp[lay.SP_VAC_TAU_ON] = vac.evacuation_time_s
        sp[lay.SP_VAC_TAU_OFF] = vac.release_time_s
        sp[lay.SP_VAC_LEVEL] = vac.switch_level
        sp[lay.SP_VAC_ON_DELAY] = vac.on_delay_s
        sp[lay.SP_VAC_OFF_DELAY] = vac.off_delay_s
        rated = s.regulator_set_psig if vac.rated_psig is None else vac.rated_psig
        sp[lay.SP_VAC_P_RATED] = psig_to_pa(rated)
    else:
        sp[lay.SP_VAC_TAU_ON] = sp[lay.SP_VAC_TAU_OFF] = 1.0
        sp[lay.SP_VAC_LEVEL] = 0.5
        sp[lay.SP_VAC_P_RATED] = sp[lay.SP_P_SET]
    na = len(machine.actuators)
    ap = np.zeros((na, lay.AP_SIZE))
    cp = np.zeros((2 * na, lay.CP_SIZE))
    vkind = np.zeros(na, dtype=np.int64)
    leak_by_loc = {lk.location: lk.area_m2 for lk in leaks}
    sp[lay.SP_SUPPLY_LEAK] = leak_by_loc.get("supply", 0.0)
    for i, a in enumerate(machine.actuators):
        area_a, area_b, rod = piston_areas(a)
        ap[i, lay.AP_STROKE] = a.stroke_mm * 1e-3
        ap[i, lay.AP_MASS] = a.moving_mass_kg
        ap[i, lay.AP_FS] = a.static_friction_n
        ap[i, lay.AP_FC] = a.coulomb_friction_n
        ap[i, lay.AP_CVF] = a.viscous_friction_n_s_m
        ap[i, lay.AP_AROD] = rod
        ap[i, lay.AP_ON_DELAY] = a.valve.on_delay_s
        ap[i, lay.AP_OFF_DELAY] = a.valve.off_delay_s
        ap[i, lay.AP_CUSH_LEN] = a.cushion_length_mm * 1e-3
        ap[i, lay.AP_SPRING_F0] = a.spring_preload_n
        ap[i, lay.AP_SPRING_K] = a.spring_rate_n_per_mm * 1e3
        vkind[i] = _VALVE_KIND[a.valve.kind]
        tube = tube_cv(a.tube_length_m, a.tube_inner_diameter_mm)
        tube_vol = math.pi * (a.tube_inner_diameter_mm * 1e-3) ** 2 / 4 * a.tube_length_m
        for side, area, dead, meter, cushion, line_psig in (
            (
                0,
                area_a,
                a.dead_volume_a_cm3,
                a.meter_out_cv_a,
                a.cushion_cv_a,
                a.line_pressure_psig_a,
            ),
            (
                1,
                area_b,
                a.dead_volume_b_cm3,
                a.meter_out_cv_b,
                a.cushion_cv_b,
                a.line_pressure_psig_b,
            ),
        ):
            c = 2 * i + side
            cp[c, lay.CP_AREA] = area
            cp[c, lay.CP_DEAD] = dead * 1e-6 + tube_vol
            cp[c, lay.CP_CV_FILL] = series_cv(a.valve.cv, tube)
            cp[c, lay.CP_CV_EXH] = series_cv(a.valve.cv, tube, meter)
            cp[c, lay.CP_CV_CUSH] = (
                series_cv(a.valve.cv, tube, meter, cushion)
                if cushion > 0.0
                else cp[c, lay.CP_CV_EXH]
            )
            cp[c, lay.CP_XT] = a.valve.xt
            cp[c, lay.CP_LEAK] = leak_by_loc.get(f"{a.id}_{'AB'[side]}", 0.0)
            cp[c, lay.CP_TAU_TH] = a.thermal_time_s
            if line_psig > 0.0:
                cp[c, lay.CP_P_LINE] = psig_to_pa(line_psig)
                cp[c, lay.CP_BOOST] = 1.0 if a.booster else 0.0
        if a.valve.kind == "3/2-monostable":
            # the spring side has no line: vented at the cylinder through its breather
            c = 2 * i + 1
            cp[c, lay.CP_DEAD] = a.dead_volume_b_cm3 * 1e-6
            cp[c, lay.CP_CV_FILL] = 0.0
            cp[c, lay.CP_CV_EXH] = BREATHER_CV
            cp[c, lay.CP_CV_CUSH] = BREATHER_CV
    program = _program_arrays(machine)
    return Plant(
        sp=sp,
        ap=ap,
        vkind=vkind,
        cp=cp,
        **program,  # type: ignore[arg-type]
        dwell=np.asarray([st.dwell_s for st in machine.steps], dtype=np.float64),
        n_solenoids=len(solenoid_slots(machine)),
        n_switches=len(machine.switches),
        t_wall=t_wall,
    )


def _program_arrays(machine: MachineDescription) -> dict[str, I64 | F64]:
    """The PLC program as the kernel's flat arrays: each step's actions and waits."""
    solenoids = solenoid_slots(machine)
    switches = machine.switches
    act_start = [0]
    act_sol: list[int] = []
    act_mode: list[int] = []
    act_sw: list[int] = []
    act_dur: list[float] = []
    wait_start = [0]
    wait_sw: list[int] = []
    wait_val: list[int] = []
    for step in machine.steps:
        for act in step.actions:
            act_sol.append(solenoids.index(act.solenoid))
            act_mode.append(_MODE[act.mode])
            act_sw.append(switches.index(act.switch) if act.switch else -1)
            act_dur.append(act.duration_s)
        act_start.append(len(act_sol))
        for w in step.wait:
            wait_sw.append(switches.index(w))
            wait_val.append(1)
        for w in step.wait_off:
            wait_sw.append(switches.index(w))
            wait_val.append(0)
        wait_start.append(len(wait_sw))

    def ints(v: list[int]) -> I64:
        return np.asarray(v, dtype=np.int64).reshape(-1)

    return {
        "act_start": ints(act_start),
        "act_sol": ints(act_sol),
        "act_mode": ints(act_mode),
        "act_sw": ints(act_sw),
        "act_dur": np.asarray(act_dur, dtype=np.float64).reshape(-1),
        "wait_start": ints(wait_start),
        "wait_sw": ints(wait_sw),
        "wait_val": ints(wait_val),
    }


def _line_pressure(p_set: float, chamber: F64) -> float:
    """Pressure a line settles at: the set point, or its own regulator's or booster's [Pa]."""
    p_line = float(chamber[lay.CP_P_LINE])
    if p_line > 0.0 and (chamber[lay.CP_BOOST] > 0.0 or p_line < p_set):
        return p_line
    return p_set


def initial_state(machine: MachineDescription, plant: Plant) -> dict[str, F64 | I64]:
    """Machine at rest before the first cycle: actuators at their ``initial`` ends.

    The pressurised side of every actuator (A when extended, B when retracted) is at
    the regulator set point, the other at the atmosphere; for a 5/3 closed-centre
    valve the spool is in the centre with the same chamber pressures.
    """
    na = len(machine.actuators)
    nn = 2 + 2 * na
    # a drifted regulator (a fault of issue 34) holds its own pressure
    p_set = plant.sp[lay.SP_P_SET] + plant.sp[lay.SP_REG_OFFSET]
    p_atm = 101_325.0
    t_wall = plant.t_wall
    x = np.zeros(na)
    spool = np.zeros(na, dtype=np.int64)
    pressure = np.full(nn, p_set)
    vol = np.zeros(nn)
    vol[0] = plant.sp[lay.SP_V_RES]
    vol[1] = plant.sp[lay.SP_V_MAN]
    for i, a in enumerate(machine.actuators):
        ext = a.initial == "extended"
        x[i] = plant.ap[i, lay.AP_STROKE] if ext else 0.0
        if a.valve.kind != "5/3-closed-centre":
            spool[i] = 1 if ext else -1
        fed = [_line_pressure(p_set, plant.cp[2 * i + side]) for side in (0, 1)]
        if a.valve.kind == "3/2-monostable":
            fed[1] = p_atm  # the spring side is vented
        pressure[2 + 2 * i] = fed[0] if ext else p_atm
        pressure[3 + 2 * i] = p_atm if ext else fed[1]
        vol[2 + 2 * i] = plant.cp[2 * i, lay.CP_DEAD] + plant.cp[2 * i, lay.CP_AREA] * x[i]
        vol[3 + 2 * i] = plant.cp[2 * i + 1, lay.CP_DEAD] + plant.cp[2 * i + 1, lay.CP_AREA] * (
            plant.ap[i, lay.AP_STROKE] - x[i]
        )
    temp = np.full(nn, t_wall)
    mass = pressure * vol / (R_AIR * temp)
    ns = plant.n_solenoids
    return {
        "m": mass,
        "temp": temp,
        "x": x,
        "v": np.zeros(na),
        "stuck": np.ones(na, dtype=np.int64),
        "spool": spool,
        "cmd": np.zeros(ns, dtype=np.int64),
        "eff": np.zeros(ns, dtype=np.int64),
        "chg": np.full(ns, -1e9),
        "rel_sw": np.full(ns, -1, dtype=np.int64),
        "rel_t": np.full(ns, -1.0),
        "ss": np.zeros(lay.SS_SIZE),
        "istate": np.zeros(lay.IS_SIZE, dtype=np.int64),
        "cum": np.zeros(lay.CM_SIZE),
        "mv_t0": np.tile(np.array([-1.0, -1.0, 0.0, 1.0]), (na, 1)),
        "mv_dir": np.zeros(na, dtype=np.int64),
        "sw_t": switch_edge_times(plant, x, np.zeros(plant.n_switches - 2 * na)),
    }


def switch_edge_times(plant: Plant, x: F64, vacuum_switch: F64) -> F64:
    """``State.sw_t`` of switches that have been in their state for a long time.

    A switch whose piston is at its end closed long ago (-1e9 s); one whose piston is
    away has no rising edge pending (:data:`pneufdd.sim.layout.SW_OFF`). ``x`` are the
    piston positions [m], ``vacuum_switch`` the vacuum switch's reading (0 or 1; empty
    without a vacuum).
    """
    window = plant.sp[lay.SP_WINDOW]
    closed = []
    for i in range(x.size):
        closed += [x[i] <= window, x[i] >= plant.ap[i, lay.AP_STROKE] - window]
    closed += [bool(v) for v in vacuum_switch]
    return np.where(np.array(closed, dtype=bool).reshape(-1), -1e9, lay.SW_OFF)
