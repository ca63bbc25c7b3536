"""Faults and nuisances applied to the compiled plant, cycle by cycle, with their truth.

:class:`RunConditions` sets the plant's arrays (:mod:`pneufdd.sim.layout`) for each
cycle from the description's values, the faults present at the cycle's start
(:class:`pneufdd.sim.faults.FaultSchedule`) and the nuisances then
(:class:`pneufdd.sim.nuisances.Nuisances`), and records what it set: the recording's
``fault_timeline`` and ``nuisance_timeline`` (one row per cycle and fault, one per
cycle) and the header dips drawn. A run without faults and nuisances never builds
one, so its arrays and its recording are those of a twin without this module.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.physics.constants import KELVIN_OFFSET
from pneufdd.physics.faults import (
    CUSHION_LENGTH_DNC32_MM,
    header_dip_profile,
    seal_friction_temperature_factors,
    throttled_cv,
    worn_friction,
)
from pneufdd.physics.restrictions import series_cv
from pneufdd.physics.units import kg_s_to_slpm, psig_to_pa
from pneufdd.sim import layout as lay
from pneufdd.sim.compile import Plant, switch_edge_times, tube_cv
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.faults import FAULT_KINDS, Fault, FaultSchedule
from pneufdd.sim.nuisances import Nuisances

__all__ = ["RunConditions", "check_conditions", "prepare"]

_SP = [lay.SP_REG_OFFSET, lay.SP_T_WALL, lay.SP_T_SUPPLY, lay.SP_VSW_MODE, lay.SP_VSW_PARAM]
_AP = [
    lay.AP_FS, lay.AP_FC, lay.AP_CVF, lay.AP_MASS, lay.AP_ON_DELAY, lay.AP_OFF_DELAY,
    lay.AP_PISTON_LEAK, lay.AP_CUSH_LEN, lay.AP_PILOT_MIN,
]  # fmt: skip
_CP = [
    lay.CP_CV_EXH, lay.CP_CV_CUSH, lay.CP_SPOOL_IN, lay.CP_SPOOL_OUT, lay.CP_SW_MODE,
    lay.CP_SW_PARAM,
]  # fmt: skip
_SWITCH_MODES = {
    "stuck-on": lay.SW_STUCK_ON,
    "stuck-off": lay.SW_STUCK_OFF,
    "late": lay.SW_LATE,
    "missing-edge": lay.SW_MISS,
}
_PSI_PER_BAR = 14.503773773


@dataclass
class _Line:
    """The restrictions of one chamber's exhaust path, as described."""

    valve: float
    tube: float
    meter: float
    cushion: float


def _seed_sequence(seed: int | None, stream: int) -> np.random.SeedSequence:
    """A random stream of its own for the run's ``seed``: the run's main generator
    (phases, jitter, friction scatter, noise) draws the same with and without it."""
    return np.random.SeedSequence(seed, spawn_key=(34, stream))


class RunConditions:
    """The faults and nuisances of one run, applied to its plant before each cycle.

    Parameters
    ----------
    desc : MachineDescription
        The machine (checked faults and nuisances refer to it).
    plant : Plant
        Its compiled arrays; their values now are the description's (kept as the base).
    faults : FaultSchedule, optional
        The faults over the run.
    nuisances : Nuisances, optional
        The nuisances over the run.
    seed : int or None
        The run's seed (missing edges and, unless given, header dips draw from streams
        of their own derived from it).
    """

    def __init__(
        self,
        desc: MachineDescription,
        plant: Plant,
        faults: FaultSchedule | None,
        nuisances: Nuisances | None,
        seed: int | None,
    ) -> None:
        self.desc, self.plant = desc, plant
        self.faults, self.nuisances = faults, nuisances
        self.base = (plant.sp[_SP].copy(), plant.ap[:, _AP].copy(), plant.cp[:, _CP].copy())
        self.t_ref = plant.t_wall
        self.p_nominal = float(psig_to_pa(desc.nominal_supply_psig))
        self.lines = [
            _Line(a.valve.cv, tube_cv(a.tube_length_m, a.tube_inner_diameter_mm), meter, cushion)
            for a in desc.actuators
            for meter, cushion in ((a.meter_out_cv_a, a.cushion_cv_a),
                                   (a.meter_out_cv_b, a.cushion_cv_b))
        ]  # fmt: skip
        self.fault_timeline: list[dict[str, Any]] = []
        self.nuisance_timeline: list[dict[str, Any]] = []
        self._edges = np.random.default_rng(_seed_sequence(seed, 1))
        dips = nuisances.header_dips if nuisances else None
        self.dips: list[tuple[float, float, float]] = []
        self._next_dip = 0.0
        if dips is not None:
            stream = _seed_sequence(dips.seed if dips.seed is not None else seed, 2)
            self._dip_rng = np.random.default_rng(stream)
            self._next_dip = float(self._dip_rng.exponential(1.0 / dips.rate_per_s))
        self._switch_faults_before = False

    # ------------------------------------------------------------------ per cycle
    def apply(self, cycle: int, time_s: float, state: dict[str, npt.NDArray[Any]] | None) -> None:
        """Set the plant for the cycle starting at ``time_s`` and record its truth.

        ``state`` gets its switch edge times refreshed when switch faults start; with
        None (the plant set for the initial state, before the first cycle) nothing is
        recorded and no missing edge is drawn.
        """
        plant, desc = self.plant, self.desc
        plant.sp[_SP], plant.ap[:, _AP], plant.cp[:, _CP] = (b.copy() for b in self.base)
        coulomb, viscous = self._apply_nuisances(cycle, time_s, state is not None)
        active = self.faults.active(time_s) if self.faults else []
        wear = {f.location: (f, size) for f, size in active if f.kind == "friction"}
        for i, a in enumerate(desc.actuators):
            fs, fc = plant.ap[i, lay.AP_FS], plant.ap[i, lay.AP_FC]
            if a.id in wear:
                fault, size = wear[a.id]
                pct, added = (size, 0.0) if fault.unit == "%" else (0.0, size)
                fs, fc = worn_friction(fs, fc, pct, added)
            if a.id in wear or coulomb != 1.0:
                plant.ap[i, lay.AP_FS], plant.ap[i, lay.AP_FC] = fs * coulomb, fc * coulomb
            if viscous != 1.0:
                plant.ap[i, lay.AP_CVF] *= viscous
        rows = []
        for fault, size in active:
            truth = self._apply_fault(fault, size, state is not None)
            rows.append({"cycle": cycle, "cycle_start_s": time_s, **fault.as_metadata(),
                         "size": size, **truth})  # fmt: skip
            for key in ("start_s", "growth_per_s", "repair_s"):
                rows[-1].pop(key)
        self._exhaust_paths(active)
        if state is not None:
            self.fault_timeline += rows
        # switch faults the kernel acts on this cycle (a missing edge not drawn is none):
        # the kernel keeps the switches' edge times only while there are some
        switch_faults = bool(
            np.any(plant.cp[:, lay.CP_SW_MODE] != lay.SW_OK)
            or plant.sp[lay.SP_VSW_MODE] != lay.SW_OK
        )
        if switch_faults and not self._switch_faults_before and state is not None:
            vac = np.zeros(plant.n_switches - 2 * len(desc.actuators))
            if vac.size:
                vac[0] = state["ss"][lay.SS_VAC] >= plant.sp[lay.SP_VAC_LEVEL]
            state["sw_t"][...] = switch_edge_times(plant, state["x"], vac)
        self._switch_faults_before = switch_faults and state is not None

    def _apply_nuisances(self, cycle: int, time_s: float, record: bool) -> tuple[float, float]:
        """Ambient, supply air and payloads for the cycle: the friction factors."""
        n = self.nuisances
        if n is None:
            return 1.0, 1.0
        plant = self.plant
        row: dict[str, Any] = {"cycle": cycle, "cycle_start_s": time_s}
        coulomb = viscous = 1.0
        if n.ambient is not None:
            t_amb = n.ambient.at(time_s) + KELVIN_OFFSET
            plant.sp[lay.SP_T_WALL] = plant.sp[lay.SP_T_SUPPLY] = t_amb
            coulomb, viscous = seal_friction_temperature_factors(
                t_amb, self.t_ref, n.friction_per_k
            )
            row["ambient_c"] = t_amb - KELVIN_OFFSET
        if n.supply_air is not None:
            plant.sp[lay.SP_T_SUPPLY] = n.supply_air.at(time_s) + KELVIN_OFFSET
            row["supply_air_c"] = plant.sp[lay.SP_T_SUPPLY] - KELVIN_OFFSET
        payload = n.payload_at(time_s)
        ids = self.desc.actuator_ids
        for actuator, kg in payload.items():
            plant.ap[ids.index(actuator), lay.AP_MASS] += kg
        if n.payloads:
            row["payload_kg"] = payload
        row["friction_factor"] = {"coulomb": coulomb, "viscous": viscous}
        if record:
            self.nuisance_timeline.append(row)
        return coulomb, viscous

    def _leak_area(self, fault: Fault, size: float) -> tuple[float, dict[str, Any]]:
        """Effective area of an internal leak, and its flow at the nominal pressure."""
        from pneufdd.physics.leaks import leak_area, leak_mass_flow

        ref = self.p_nominal if fault.unit == "SLPM" else None
        area = float(leak_area(size, fault.unit, ref))
        slpm = kg_s_to_slpm(float(leak_mass_flow(self.p_nominal, area)))
        return area, {"effective_area_m2": area, "slpm_at_nominal": slpm}

    def _apply_fault(self, fault: Fault, size: float, draw: bool) -> dict[str, Any]:
        """Set the plant for one fault; its truth beyond the size (e.g. an area).

        A missing edge is drawn only when ``draw`` (a cycle, not the initial state).
        """
        plant, desc, kind = self.plant, self.desc, fault.kind
        target = FAULT_KINDS[kind].target
        if target == "supply":
            bar = size if fault.unit == "bar" else size / _PSI_PER_BAR
            plant.sp[lay.SP_REG_OFFSET] = bar * 1e5
            return {}
        if target == "switch":
            s = desc.switches.index(fault.location)
            mode = _SWITCH_MODES[kind]
            truth: dict[str, Any] = {}
            if kind == "missing-edge":
                missed = draw and bool(self._edges.uniform() < size / 100.0)
                mode = lay.SW_MISS if missed else lay.SW_OK
                truth["missed"] = missed
            param = size * 1e-3 if kind == "late" else 0.0
            if s < 2 * len(desc.actuators):
                plant.cp[s, lay.CP_SW_MODE], plant.cp[s, lay.CP_SW_PARAM] = mode, param
            else:
                plant.sp[lay.SP_VSW_MODE], plant.sp[lay.SP_VSW_PARAM] = mode, param
            return truth
        if target == "actuator":
            i = desc.actuator_ids.index(fault.location)
            if kind == "piston-leak":
                area, truth = self._leak_area(fault, size)
                plant.ap[i, lay.AP_PISTON_LEAK] = area
                return truth
            if kind == "valve-delay":
                plant.ap[i, lay.AP_ON_DELAY] += size * 1e-3
                plant.ap[i, lay.AP_OFF_DELAY] += size * 1e-3
            elif kind == "valve-pilot":
                plant.ap[i, lay.AP_PILOT_MIN] = (
                    size if fault.unit == "bar" else size / _PSI_PER_BAR
                ) * 1e5
            return {}  # friction: set with the temperature factors in apply()
        c = self._chamber(fault.location)
        if kind in ("valve-leak-in", "valve-leak-out"):
            area, truth = self._leak_area(fault, size)
            plant.cp[c, lay.CP_SPOOL_IN if kind == "valve-leak-in" else lay.CP_SPOOL_OUT] = area
            return truth
        return {}  # throttle, cushion: the exhaust paths, set together in _exhaust_paths

    def _chamber(self, line: str) -> int:
        """Chamber row of a line ``<ACT>_A`` / ``<ACT>_B``."""
        act, side = line.rsplit("_", 1)
        return 2 * self.desc.actuator_ids.index(act) + (0 if side == "A" else 1)

    def _exhaust_paths(self, active: list[tuple[Fault, float]]) -> None:
        """Exhaust Cvs of lines with a throttle or cushion fault (both may act on one)."""
        changed: dict[int, tuple[float, float]] = {}
        for fault, size in active:
            if fault.kind not in ("throttle", "cushion"):
                continue
            c = self._chamber(fault.location)
            line = self.lines[c]
            meter, cushion = changed.get(c, (line.meter, line.cushion))
            if fault.kind == "throttle":
                meter = size if fault.unit == "Cv" else float(throttled_cv(line.meter, size))
            else:
                cushion = size if fault.unit == "Cv" else float(throttled_cv(line.cushion, size))
                i = c // 2
                a = self.desc.actuators[i]
                length = a.cushion_length_mm or min(CUSHION_LENGTH_DNC32_MM, a.stroke_mm / 4.0)
                self.plant.ap[i, lay.AP_CUSH_LEN] = length * 1e-3
            changed[c] = (meter, cushion)
        for c, (meter, cushion) in changed.items():
            line = self.lines[c]
            exhaust = series_cv(line.valve, line.tube, meter)
            self.plant.cp[c, lay.CP_CV_EXH] = exhaust
            self.plant.cp[c, lay.CP_CV_CUSH] = (
                series_cv(line.valve, line.tube, meter, cushion) if cushion > 0.0 else exhaust
            )

    # ------------------------------------------------------------------ header dips
    def dip_grid(self, time_s: float, n: int, step_s: float) -> npt.NDArray[np.float64] | None:
        """The house-pressure change of the header dips on a cycle's drift grid [Pa].

        Grid point ``k`` is at ``time_s + k step_s`` (the kernel interpolates linearly
        between them); None without dips.
        """
        dips = self.nuisances.header_dips if self.nuisances else None
        if dips is None:
            return None
        end = time_s + (n - 1) * step_s
        while self._next_dip <= end:
            self.dips.append((self._next_dip, dips.duration_s, dips.depth_pa))
            self._next_dip += float(self._dip_rng.exponential(1.0 / dips.rate_per_s))
        near = [d for d in self.dips if d[0] <= end and d[0] + d[1] >= time_s]
        grid = time_s + step_s * np.arange(n)
        if not near:
            return np.zeros(n)
        starts, durations, depths = (np.array(col) for col in zip(*near, strict=True))
        return -header_dip_profile(grid, starts, durations, depths)

    def metadata(self, duration_s: float) -> dict[str, Any]:
        """The recording's ground truth of these conditions (a run of ``duration_s``)."""
        meta: dict[str, Any] = {}
        if self.faults is not None:
            meta["fault_schedule"] = self.faults.as_metadata()
            meta["fault_timeline"] = self.fault_timeline
        if self.nuisances is not None:
            meta["nuisances"] = self.nuisances.as_metadata()
            meta["nuisance_timeline"] = self.nuisance_timeline
            if self.nuisances.header_dips is not None:
                meta["header_dips"] = [
                    {"start_s": s, "duration_s": d, "depth_pa": p}
                    for s, d, p in self.dips
                    if s < duration_s
                ]
        return meta


def check_conditions(
    desc: MachineDescription, faults: FaultSchedule | None, nuisances: Nuisances | None
) -> None:
    """Refuse faults and nuisances that do not fit ``desc`` (before any simulation).

    Raises
    ------
    InputError
        Naming the fault or nuisance and what the machine allows.
    """
    from pneufdd.errors import InputError, describe

    if nuisances is not None:
        nuisances.check(desc)
    if faults is None:
        return
    faults.check(desc)
    for fault in faults.faults:
        if fault.kind == "throttle":
            act = desc.actuators[desc.actuator_ids.index(fault.location[:-2])]
            meter = act.meter_out_cv_a if fault.location.endswith("_A") else act.meter_out_cv_b
            if meter >= 50.0:
                raise InputError(
                    describe(f"throttle fault on {fault.location}", fault.size,
                             "a line with a meter-out throttle (its meter_out_cv is 50, free)")
                )  # fmt: skip
        if fault.kind in ("piston-leak", "valve-leak-in", "valve-leak-out"):
            ident = fault.location if fault.location in desc.actuator_ids else fault.location[:-2]
            act = desc.actuators[desc.actuator_ids.index(ident)]
            if act.line_pressure_psig_a > 0.0 or act.line_pressure_psig_b > 0.0:
                raise InputError(
                    describe(f"{fault.kind} fault on {fault.location}", ident,
                             "an actuator fed by the manifold (the twin does not model this "
                             "fault on a line with its own regulator or booster)")
                )  # fmt: skip
        if math.isfinite(fault.size) and fault.kind == "friction" and fault.unit == "N":
            act = desc.actuators[desc.actuator_ids.index(fault.location)]
            worn_friction(act.static_friction_n, act.coulomb_friction_n, 0.0, fault.size)


def prepare(
    desc: MachineDescription,
    plant: Plant,
    faults: FaultSchedule | Iterable[Fault | str] | None,
    nuisances: Nuisances | None,
    seed: int | None,
) -> RunConditions | None:
    """A run's faults and nuisances, checked and applied to ``plant`` for its start.

    The ambient temperature and a regulator drift at t = 0 set the initial state's
    temperature and pressures (:func:`pneufdd.sim.compile.initial_state`). None when
    there are none (an empty list of faults is none).

    Raises
    ------
    InputError
        For faults or nuisances that do not fit ``desc`` (:func:`check_conditions`).
    """
    from pneufdd.errors import InputError, describe

    schedule = faults if isinstance(faults, FaultSchedule) or faults is None else None
    if schedule is None and faults is not None:
        schedule = FaultSchedule(faults)  # type: ignore[arg-type]
    if schedule is not None and not schedule.faults:
        schedule = None
    if nuisances is not None and not isinstance(nuisances, Nuisances):
        raise InputError(describe("nuisances", nuisances, "a pneufdd.sim.nuisances.Nuisances"))
    if schedule is None and nuisances is None:
        return None
    check_conditions(desc, schedule, nuisances)
    conditions = RunConditions(desc, plant, schedule, nuisances, seed)
    conditions.apply(0, 0.0, None)
    plant.t_wall = float(plant.sp[lay.SP_T_WALL])
    return conditions
