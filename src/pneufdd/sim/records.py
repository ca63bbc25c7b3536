"""Typed records the compiled twin works on (numba passes them as named tuples).

:func:`pneufdd.sim.kernel.run_cycle` takes five records instead of 49 positional
arrays; each stage of the kernel reads and writes the records' fields by name. The
index constants of the packed parameter and state arrays live in
:mod:`pneufdd.sim.layout`.

* :class:`PlantParams`: what the machine is (supply, actuators, valves, chambers);
* :class:`Program`: what the PLC does (step actions, awaited switches, dwell times);
* :class:`CycleDraws`: the random part of one cycle (scan jitter, friction factors,
  house-air drift);
* :class:`State`: everything that carries over from one cycle to the next;
* :class:`Outputs`: the 1 kHz samples, step start times and stroke events one cycle
  writes.
"""

from __future__ import annotations

from typing import Any, NamedTuple

__all__ = ["CycleDraws", "Outputs", "PlantParams", "Program", "State"]

Array = Any  # numba needs plain ndarrays here; mypy sees them as Any


class PlantParams(NamedTuple):
    """The compiled machine (:class:`pneufdd.sim.compile.Plant`)."""

    sp: Array  # supply parameters (SP_*)
    ap: Array  # per actuator (AP_*)
    vkind: Array  # valve kind per actuator (VK_*)
    cp: Array  # per chamber (CP_*)


class Program(NamedTuple):
    """The PLC sequence in flat arrays (CSR: ``act_start[k]:act_start[k + 1]``)."""

    act_start: Array
    act_sol: Array
    act_mode: Array  # 0 until switch, 1 for a duration, 2 held, 3 released
    act_sw: Array
    act_dur: Array
    wait_start: Array
    wait_sw: Array
    wait_val: Array
    dwell: Array


class CycleDraws(NamedTuple):
    """Random quantities of one cycle."""

    jitter: Array  # extra time per step end (PLC scan) [s]
    fric: Array  # friction factor per actuator [-]
    ou: Array  # house-air drift, every 0.1 s [Pa]


class State(NamedTuple):
    """The machine's state between cycles (updated in place)."""

    m: Array  # node masses [kg]
    temp: Array  # node temperatures [K]
    x: Array  # piston positions [m]
    v: Array  # piston velocities [m/s]
    stuck: Array  # 1: piston held by static friction or an end stop
    spool: Array  # valve spool position per actuator (1, 0, -1)
    cmd: Array  # solenoid commands of the PLC
    eff: Array  # solenoids in effect (after the switching delays)
    chg: Array  # time of the last command change per solenoid [s]
    rel_sw: Array  # switch releasing each solenoid (-1: none)
    rel_t: Array  # time releasing each solenoid (-1: none) [s]
    ss: Array  # scalar floats (SS_*)
    istate: Array  # scalar ints (IS_*)
    cum: Array  # cumulative masses (CM_*) [kg]
    mv_t0: Array  # per actuator: motion start, candidate start, its position, sustained
    mv_dir: Array  # per actuator: direction of the current motion
    sw_t: Array  # per switch: time its piston arrived (SW_OFF: away; SW_MISSED) [s]


class Outputs(NamedTuple):
    """What one cycle writes (reusable buffers; the first ``n_samples`` rows count)."""

    p: Array
    x: Array
    vac: Array
    fch: Array
    fexh: Array
    fleak: Array
    fr: Array
    cum: Array
    mass: Array
    cmd: Array
    sw: Array
    step: Array
    step_t: Array
    ev_act: Array
    ev_dir: Array
    ev_t0: Array
    ev_t1: Array
    fpl: Array  # per actuator: flow across the piston seal, A -> B [kg/s]
