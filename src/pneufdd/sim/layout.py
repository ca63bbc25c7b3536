"""Column indices of the parameter and state arrays shared by compile and kernel.

The compiled integrator takes plain numpy arrays; these constants name their columns.
The twin's sample interval and stick band are here too: the kernel and the reference
right-hand side (:mod:`pneufdd.sim.rhs`) share them.
"""

from __future__ import annotations

SAMPLE_DT = 1e-3
"""Output (analog) sample interval of the twin [s]."""

STICK_BAND = 1e-4
"""Half-width of the Karnopp stick band of the twin's pistons, eq. 4.14 [m/s]
(``v_stick`` of :func:`pneufdd.physics.friction.friction_force_kernel`); the kernel
and :mod:`pneufdd.sim.rhs` use it."""

# supply parameters (float array)
SP_P_HOUSE = 0  # nominal house pressure [Pa abs]
SP_DRIFT_STD = 1  # OU standard deviation [Pa]
SP_COMP_BAND = 2  # compressor load/unload band, peak to peak [Pa]
SP_COMP_PERIOD = 3  # compressor cycle period [s]
SP_COMP_PHASE = 4  # phase at t = 0 [-], 0..1
SP_P_SET = 5  # regulator set point [Pa abs]
SP_REG_CV = 6
SP_REG_XT = 7
SP_REG_EFFECT = 8  # supply-pressure effect of the regulator [-]
SP_V_RES = 9  # reservoir volume [m^3]
SP_LINE_CV = 10
SP_LINE_XT = 11
SP_V_MAN = 12  # manifold volume [m^3]
SP_TAU_TH = 13  # thermal time constant of reservoir/manifold [s]
SP_T_WALL = 14  # wall/ambient temperature [K]
SP_SUPPLY_LEAK = 15  # effective area of the supply leak [m^2]
SP_SCAN = 16  # PLC scan time [s]
SP_WINDOW = 17  # proximity switch window [m]
SP_NOZZLE = 18  # vacuum nozzle effective area [m^2]
SP_VAC_TAU_ON = 19
SP_VAC_TAU_OFF = 20
SP_VAC_LEVEL = 21
SP_VAC_ON_DELAY = 22
SP_VAC_OFF_DELAY = 23
SP_OU_DT = 24  # grid of the house-pressure drift array [s]
SP_N_MOVE = 25  # minimum sub-steps per ms while a piston moves [-]
SP_DP_TOL = 26  # target pressure change per sub-step [Pa]
SP_N_MAX = 27  # maximum sub-steps per ms [-]
SP_REG_OFFSET = 28  # drift of the regulator set point (fault) [Pa]
SP_T_SUPPLY = 29  # temperature of the air the regulator delivers [K]
SP_VSW_MODE = 30  # fault of the vacuum switch (SW_*)
SP_VSW_PARAM = 31  # its size (SW_LATE: delay [s])
SP_VAC_P_RATED = 32  # supply pressure the ejector is rated at [Pa abs]
SP_SIZE = 33

# actuator parameters (float array, one row per actuator)
AP_STROKE = 0  # [m]
AP_MASS = 1  # [kg]
AP_FS = 2  # static (stick-slip) friction [N]
AP_FC = 3  # Coulomb friction [N]
AP_CVF = 4  # viscous friction [N s/m]
AP_AROD = 5  # rod area exposed to atmosphere [m^2]
AP_ON_DELAY = 6  # [s]
AP_OFF_DELAY = 7  # [s]
AP_PISTON_LEAK = 8  # effective area of a leak across the piston seal, A <-> B [m^2]
AP_CUSH_LEN = 9  # end-position cushioning length (0: none) [m]
AP_PILOT_MIN = 10  # supply gauge pressure the valve's pilot needs to shift (0: any) [Pa]
AP_SPRING_F0 = 11  # return spring force at the home end (x = 0) [N]
AP_SPRING_K = 12  # return spring rate [N/m]
AP_SIZE = 13

# actuator valve kinds (int)
VK_BISTABLE = 0
VK_MONOSTABLE = 1
VK_CLOSED_CENTRE = 2
VK_SINGLE_ACTING = 3  # 3/2 monostable: A filled while energised, B always vented

# chamber parameters (float array, row 2*i + side)
CP_AREA = 0  # piston area [m^2]
CP_DEAD = 1  # dead volume incl. tube [m^3]
CP_CV_FILL = 2  # valve + tube, series [-]
CP_CV_EXH = 3  # valve + tube + meter-out throttle, series [-]
CP_XT = 4
CP_LEAK = 5  # effective leak area [m^2]
CP_TAU_TH = 6  # thermal time constant [s]
CP_SPOOL_IN = 7  # effective area of a spool leak supply -> this port [m^2]
CP_SPOOL_OUT = 8  # effective area of a spool leak this port -> exhaust [m^2]
CP_CV_CUSH = 9  # exhaust path with the cushion engaged (CP_CV_EXH + cushion screw) [-]
CP_SW_MODE = 10  # fault of switch 2 i + side (S_<ACT>_A, S_<ACT>_B), SW_*
CP_SW_PARAM = 11  # its size (SW_LATE: delay [s])
CP_P_LINE = 12  # line fed at this pressure by its own regulator or booster [Pa abs]; 0: none
CP_BOOST = 13  # 1: that pressure comes from a booster (also above the manifold's) [-]
CP_SIZE = 14

# switch faults (CP_SW_MODE, SP_VSW_MODE)
SW_OK = 0
SW_STUCK_ON = 1  # reads 1 whatever the piston does
SW_STUCK_OFF = 2  # reads 0 whatever the piston does
SW_LATE = 3  # closes its delay after the piston arrives, opens at once
SW_MISS = 4  # misses the next rising edge (the PLC waits)
SW_OFF = 1e300
"""``State.sw_t`` of a switch whose piston is away: no rising edge pending."""
SW_MISSED = -1e300
"""``State.sw_t`` of a switch that missed the rising edge of this visit."""

# scalar float state
SS_TIME = 0  # simulated time [s]
SS_PHASE_END = 1  # end of the current step's dwell [s]
SS_VAC = 2  # vacuum level 0..1 [-]
SS_OU = 3  # current house-pressure drift [Pa]
SS_SIZE = 4

# scalar int state
IS_SAMPLE = 0  # global sample counter (1 kHz)
IS_STEP = 1  # current step index
IS_PHASE = 2  # 0 = waiting for switches, 1 = dwell/scan
IS_CYCLE_DONE = 3
IS_SIZE = 4

# per-sample flow record columns (besides the per-chamber ones)
FR_REG = 0  # regulator -> reservoir [kg/s]
FR_LINE = 1  # reservoir -> manifold, through Q_In [kg/s]
FR_SUPPLY_LEAK = 2  # manifold -> atmosphere [kg/s]
FR_VAC = 3  # manifold -> ejector nozzle [kg/s]
FR_SIZE = 4

# cumulative masses
CM_REG = 0
CM_LINE = 1
CM_EXHAUST = 2
CM_LEAK = 3
CM_VAC = 4
CM_SIZE = 5


# ``kind`` of :func:`pneufdd.sim.kernel.sensor_reading_kernel`
SENSOR_PRESSURE = 0
"""A pressure sensor: absolute pressure [Pa] in, read in bar(g), absolute [Pa] out."""
SENSOR_FLOW = 1
"""A flow meter: its (lagged) flow [SLPM] in and out."""
SENSOR_POSITION = 2
"""A position sensor: position [m] in, read in [mm], [m] out."""

# where a recorded sensor's true signal comes from (:func:`pneufdd.sim.kernel.truth_rows_kernel`)
TRUTH_NODE_PRESSURE = 0
"""A node's pressure, a column of the kernel's ``p`` (1: the manifold, 2 + c: chamber c)."""
TRUTH_POSITION = 1
"""An actuator's position, a column of ``x``."""
TRUTH_SUPPLY_FLOW = 2
"""A supply-line flow, a column of ``fr`` (``FR_LINE``)."""
TRUTH_CHAMBER_FLOW = 3
"""A chamber's net flow, column c of ``fch`` minus the same column of ``fexh``."""
