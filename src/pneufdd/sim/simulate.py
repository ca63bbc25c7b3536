"""``simulate``: run the digital twin for a number of cycles and record it like the rig."""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pneufdd import __version__
from pneufdd.errors import InputError, PneufddError, describe
from pneufdd.limits import check_memory
from pneufdd.recording import Recording
from pneufdd.sim import layout as lay
from pneufdd.sim.buffers import POOL, BufferShape, OutputBuffers
from pneufdd.sim.compile import DEFAULT_RESOLUTION, Plant, Resolution, compile_plant, initial_state
from pneufdd.sim.description import MachineDescription, Sensor, solenoid_slots
from pneufdd.sim.layout import SAMPLE_DT
from pneufdd.sim.leaks import Leak, LeakSpec, resolve_leaks
from pneufdd.sim.loading import MachineLike, load_machine
from pneufdd.sim.prebuilt import compiled_twin
from pneufdd.sim.records import CycleDraws, Outputs, PlantParams, Program, State
from pneufdd.sim.result import SimulatedStroke, SimulationResult
from pneufdd.sim.schedule import LeakSchedule, apply_leak_schedule
from pneufdd.sim.sensors import SENSOR_SI_UNIT, apply_sensor, first_order_recursion

if TYPE_CHECKING:  # imported when a run has faults or nuisances (they load numba)
    from pneufdd.sim.conditions import RunConditions
    from pneufdd.sim.faults import Fault, FaultSchedule
    from pneufdd.sim.nuisances import Nuisances

    FaultsLike = FaultSchedule | Iterable[Fault | str] | None

__all__ = [
    "SIMULATOR_VERSION",
    "MachineStalledError",
    "as_exported",
    "kernel_arguments",
    "run_simulation",
    "simulate",
]

SIMULATOR_VERSION = f"pneufdd.sim {__version__} (twin model 1)"
ANALOG_RATE_HZ = 1000.0
DIGITAL_RATE_HZ = 100.0
_DIGITAL_EVERY = round(ANALOG_RATE_HZ / DIGITAL_RATE_HZ)
BUFFER_START_S = 20.0
"""Cycle length the output buffers first hold [s]. A longer cycle is simulated again
from the state it started in, with buffers for ``max_cycle_s``, so the results do not
depend on it (a stalled machine is detected after 20 s + ``max_cycle_s`` of simulated
time instead of ``max_cycle_s``); buffers sized for ``max_cycle_s`` (120 s) from the
start cost about 3-6 ms of page faults per run (measured, issue 13)."""
RUN_END_IDLE_S = 0.3
"""Idle time recorded after the last cycle's last step [s]: the PLC stops in cycle-stop
mode and the DAQ runs on briefly, as on the rig, so the last cycle's final switch
edges are in the recording and it segments as complete."""

LeaksLike = Mapping[str, Any] | Iterable[Leak] | None


class MachineStalledError(PneufddError):
    """The machine stopped progressing: a step waited longer than ``max_cycle_s``."""


class _NoiseStreams:
    """Sensor noise draws kept between runs that reach the same generator state.

    A run draws its sensor noise last, ``n`` standard normals per sensor in the
    description's order, so sensor ``k`` reads draws ``k n .. (k + 1) n`` of the
    generator's normal stream from the state it has then. That state depends only on
    the seed and on draws whose number is fixed (phases, jitter, friction, drift), not
    on the leaks: every simulation of a diagnosis's check (one seed, one number of
    cycles) reaches the same one, and only ``n`` differs. Drawing the normals cost
    about 6 ms of a four-cycle festo-dsd run (11 sensors of about 60,000 samples);
    the check runs 25-50 of them. numpy's ``Generator.standard_normal`` gives the
    same numbers drawn at once or in pieces (its ziggurat keeps nothing between
    calls; ``tests/test_sim_api.py`` checks it), so a stream kept for a state and
    extended on demand gives every run exactly the draws of its own generator.

    At most ``keep`` streams of at most ``max_bytes`` each are kept (thread-safe; a
    four-cycle festo-dsd check needs about 5.3 MB); a longer stream (a long run's) is
    drawn and not kept.
    """

    def __init__(self, keep: int = 2, max_bytes: int = 8 * 2**20) -> None:
        self._keep = keep
        self._max = max_bytes // 8
        self._lock = threading.Lock()
        self._streams: list[tuple[str, npt.NDArray[np.float64], np.random.Generator]] = []

    def draws(self, rng: np.random.Generator, rows: int, n: int) -> npt.NDArray[np.float64]:
        """The next ``rows * n`` standard normals of ``rng``, as ``rows`` rows of ``n``.

        Read-only. ``rng`` is advanced past them only when they are drawn anew (not
        when a kept stream serves them): the caller draws nothing after its noise.
        """
        count = rows * n
        if count > self._max:
            return rng.standard_normal(count).reshape(rows, n)
        key = repr(rng.bit_generator.state)
        with self._lock:
            for i, (kept, stream, rest) in enumerate(self._streams):
                if kept == key:
                    if stream.size < count:  # extend from where the stream ended
                        stream = np.concatenate([stream, rest.standard_normal(count - stream.size)])
                        stream.flags.writeable = False
                        self._streams[i] = (kept, stream, rest)
                    return stream[:count].reshape(rows, n)
            stream = rng.standard_normal(count)
            stream.flags.writeable = False
            rest = np.random.Generator(type(rng.bit_generator)())
            rest.bit_generator.state = rng.bit_generator.state
            self._streams.append((key, stream, rest))
            del self._streams[: -self._keep]
            return stream.reshape(rows, n)


_NOISE = _NoiseStreams()


def _ou_grid(rng: np.random.Generator, start: float, std: float, tau: float, n: int) -> Any:
    """Ornstein-Uhlenbeck drift of the house pressure on a 0.1 s grid, from ``start`` [Pa]."""
    a = math.exp(-0.1 / tau)
    b = std * math.sqrt(1.0 - a * a)
    drive = np.empty(n)
    drive[0] = start
    drive[1:] = rng.standard_normal(n - 1) * b
    return first_order_recursion(drive, 1.0, a)


def _stall_message(
    machine: MachineDescription,
    cycle: int,
    step: int,
    leaks: int = 0,
    max_cycle_s: float = 120.0,
    faults: str = "",
) -> str:
    st = machine.steps[min(step, len(machine.steps) - 1)]
    cause = (
        f"the faults {faults} keep an actuator or a switch from reaching its end"
        if faults
        else "a leak this large keeps an actuator from reaching its switch"
        if leaks
        else "no leak is simulated: the description's supply, valves or loads cannot move "
        "the actuator to its switch"
    )
    return (
        f"machine {machine.name!r} stalled in cycle {cycle + 1}, step {step + 1} "
        f"({st.name!r}) waiting for {list(st.wait) + ['not ' + w for w in st.wait_off]} "
        f"longer than max_cycle_s = {max_cycle_s:g} s; {cause}, or max_cycle_s is too short"
    )


def _check_args(cycles: int, seed: int | None, max_cycle_s: float) -> None:
    if isinstance(cycles, bool) or not isinstance(cycles, int | np.integer) or cycles < 1:
        raise InputError(describe("cycles", cycles, "an integer >= 1"))
    if seed is not None and (
        isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0
    ):
        raise InputError(describe("seed", seed, "a non-negative integer or None"))
    if not (math.isfinite(max_cycle_s) and max_cycle_s > 0):
        raise InputError(describe("max_cycle_s", max_cycle_s, "> 0 [s]"))


class _CycleLoop:
    """One run's state from cycle to cycle, and what its cycles produced.

    Holds the compiled kernel's records over the plant, the machine state and the
    output buffers (from the pool: sized for :data:`BUFFER_START_S`, grown to
    ``max_cycle_s`` when a cycle overflows them), the house-air drift carried over
    cycles, and each cycle's samples, step starts and strokes. Every random
    quantity comes from ``rng``, in the order of the cycles.
    """

    def __init__(
        self,
        desc: MachineDescription,
        plant: Plant,
        state: dict[str, npt.NDArray[Any]],
        sensors: Sequence[Sensor | None],
        rng: np.random.Generator,
        cycles: int,
        max_cycle_s: float,
        conditions: RunConditions | None = None,
    ) -> None:
        self.desc, self.plant, self.state, self.rng = desc, plant, state, rng
        self.conditions = conditions
        self.cycles, self.max_cycle_s = cycles, max_cycle_s
        na = len(desc.actuators)
        nsteps = len(desc.steps)
        self.dims = (2 + 2 * na, na, plant.n_solenoids, plant.n_switches, nsteps)
        self.n_max = int(max_cycle_s / SAMPLE_DT) + 2
        self.n_buf = min(self.n_max, int(BUFFER_START_S / SAMPLE_DT) + 2)
        self.start_shape: BufferShape = (self.n_buf, *self.dims)
        self.buf = self.pooled = POOL.take(self.start_shape)
        self.n_recorded = sum(sensor is not None for sensor in sensors)
        self.n_sensors = len(sensors)
        self.n_ou = int(max_cycle_s / 0.1) + 4
        drift_std = plant.sp[lay.SP_DRIFT_STD]
        self.ou_now = rng.normal(0.0, drift_std) if drift_std > 0 else 0.0
        self.chunks: list[dict[str, npt.NDArray[Any]]] = []
        self.step_start = np.zeros((cycles, nsteps))
        self.strokes: list[SimulatedStroke] = []
        self.total_sub = 0
        self.timeline: list[dict[str, Any]] = []
        self.params, self.program, self.records_state, self.outputs = _records(
            plant, state, self.buf
        )
        self._run_cycle = compiled_twin().run_cycle
        self.truth_sources = _truth_sources(desc, sensors)

    def release(self) -> None:
        """Give the pooled buffers back (the run's result holds copies)."""
        POOL.give(self.start_shape, self.pooled)

    def _draws(self, cyc: int) -> CycleDraws:
        """The random quantities of cycle ``cyc``: scan jitter, friction, house drift."""
        desc, plant, rng = self.desc, self.plant, self.rng
        jitter = rng.uniform(0.0, plant.sp[lay.SP_SCAN], len(desc.steps))
        if cyc == self.cycles - 1:
            jitter[-1] += RUN_END_IDLE_S
        na = len(desc.actuators)
        fric = np.clip(1.0 + desc.friction_scatter * rng.standard_normal(na), 0.5, 1.5)
        tau = desc.supply.house_drift_time_s
        ou = _ou_grid(rng, self.ou_now, plant.sp[lay.SP_DRIFT_STD], tau, self.n_ou)
        return CycleDraws(jitter, fric, ou)

    def _run_kernel(self, draws: CycleDraws) -> tuple[int, int, int, int]:
        """One cycle of the kernel: ``(samples, status, strokes, substeps)``."""
        start_state = {name: arr.copy() for name, arr in self.state.items()}
        run = self._run_cycle
        n, status, n_ev, nsub = run(
            self.params, self.program, draws, self.records_state, self.outputs
        )
        while status != 0 and self.n_buf < self.n_max:
            # buffers full before max_cycle_s: same cycle again, from the same state
            for name, arr in start_state.items():
                self.state[name][...] = arr
            self.n_buf = self.n_max
            self.buf = OutputBuffers(self.n_buf, *self.dims)
            self.outputs = Outputs(*(getattr(self.buf, name) for name in Outputs._fields))
            n, status, n_ev, nsub = run(
                self.params, self.program, draws, self.records_state, self.outputs
            )
        return n, status, n_ev, nsub

    def _cycle_strokes(self, cyc: int, n_ev: int) -> list[SimulatedStroke]:
        """The strokes the kernel completed in cycle ``cyc`` (``n_ev`` of them)."""
        buf = self.buf
        return [
            SimulatedStroke(
                self.desc.actuators[int(buf.ev_act[e])].id,
                int(buf.ev_dir[e]),
                float(buf.ev_t0[e, 0]),
                float(buf.ev_t1[e]),
                int(np.searchsorted(self.step_start[: cyc + 1, 0], buf.ev_t0[e, 1], "right")) - 1,
                float(buf.ev_t0[e, 1]),
            )
            for e in range(n_ev)
        ]

    def cycle(
        self,
        cyc: int,
        specs: list[LeakSpec],
        schedule: LeakSchedule | None,
        keep_outputs: bool,
    ) -> None:
        """Simulate cycle ``cyc`` and keep what it produced.

        Raises
        ------
        MachineStalledError
            If the cycle does not end within ``max_cycle_s``.
        """
        state = self.state
        draws = kernel_draws = self._draws(cyc)
        t_start = float(state["ss"][lay.SS_TIME])
        k_start = int(state["istate"][lay.IS_SAMPLE])
        if schedule is not None:
            self.timeline += apply_leak_schedule(
                self.plant, self.desc, specs, schedule, t_start, cyc
            )
        faults = ""
        if self.conditions is not None:
            self.conditions.apply(cyc, t_start, state)
            dips = self.conditions.dip_grid(t_start, self.n_ou, 0.1)
            if dips is not None:  # the house pressure dips; the drift carried on is the OU's
                kernel_draws = draws._replace(ou=draws.ou + dips)
            rows = [r for r in self.conditions.fault_timeline if r["cycle"] == cyc]
            faults = ", ".join(f"{r['location']}={r['kind']}" for r in rows)
        n, status, n_ev, nsub = self._run_kernel(kernel_draws)
        self.total_sub += nsub
        if status != 0:
            step_now = int(state["istate"][lay.IS_STEP])
            raise MachineStalledError(
                _stall_message(self.desc, cyc, step_now, len(specs), self.max_cycle_s, faults)
            )
        elapsed = float(state["ss"][lay.SS_TIME]) - t_start
        self.ou_now = float(np.interp(elapsed / 0.1, np.arange(self.n_ou), draws.ou))
        self.step_start[cyc] = self.buf.step_t
        self.strokes += self._cycle_strokes(cyc, n_ev)
        done = k_start + n  # samples so far: the run's length follows from them
        expected = done * self.cycles // (cyc + 1) + 1000
        if cyc == 0:  # before the run's buffers are sized from its first cycle
            _check_run_memory(self.cycles, expected, self.n_sensors, self.n_recorded)
        store = self.pooled.truth_store(self.n_recorded, k_start, done, expected)
        piston_leak = bool(np.any(self.plant.ap[:, lay.AP_PISTON_LEAK] > 0.0))
        self.chunks.append(
            _take(self.truth_sources, self.buf, n, k_start, keep_outputs, store, piston_leak)
        )


def _check_run_memory(cycles: int, samples: int, n_sensors: int, n_recorded: int) -> None:
    """Refuse a run whose recording would not fit :data:`MEMORY_BUDGET_BYTES`.

    ``samples`` is the run's length at 1 kHz estimated from its first cycle; each
    sample costs the noise of every sensor, the truth store and the recording of
    each recorded one, and the time axis (8 bytes each; measured peak: about 0.9 of
    this estimate).
    """
    estimate = 8.0 * samples * (n_sensors + 2 * n_recorded + 2)
    check_memory(
        f"cycles (--cycles): {cycles:,} cycles of {samples / cycles * SAMPLE_DT:.1f} s "
        "(split the run into shorter ones)",
        estimate,
    )


def run_simulation(
    machine: MachineLike,
    cycles: int = 1,
    leaks: LeaksLike = None,
    seed: int | None = 0,
    progress: Callable[[int, int], None] | None = None,
    keep_outputs: bool = True,
    max_cycle_s: float = 120.0,
    resolution: Resolution = DEFAULT_RESOLUTION,
    schedule: LeakSchedule | None = None,
    channels: Sequence[str] | None = None,
    faults: FaultsLike = None,
    nuisances: Nuisances | None = None,
    supply_open: Sequence[bool] | None = None,
) -> SimulationResult:
    """Simulate ``cycles`` machine cycles and return true states plus the recording.

    Parameters
    ----------
    machine : str, Path, MachineDescription or dict
        A built-in name (``"festo-dsd"``), a TOML path or a description.
    cycles : int
        Number of complete PLC cycles.
    leaks : mapping or iterable of Leak, optional
        ``{"DNC_B": 4, "supply": "30slpm"}``: location -> size (number = turns of the
        GR-3/8B leak valve, ``"2.5mm"`` orifice diameter, ``"30slpm"`` flow at the
        nominal supply pressure), or a list of :class:`Leak`.
    seed : int, optional
        Seed of the one ``numpy.random.Generator`` behind every random quantity.
    progress : callable, optional
        Called as ``progress(cycles_done, cycles)`` after each cycle.
    keep_outputs : bool
        Keep the internal states (``outputs``); False saves memory for long runs.
    max_cycle_s : float
        A cycle longer than this is a stalled machine [s].
    resolution : Resolution
        Sub-step settings of the integrator (defaults are those benchmarked).
    schedule : LeakSchedule, optional
        Leaks that appear, grow and are repaired during the run
        (:mod:`pneufdd.sim.schedule`): set between cycles from each cycle's start
        time, recorded in the metadata (``leak_schedule``, ``leak_timeline``).
    channels : sequence of str, optional
        The analog channels to record (None: every sensor of the description). Each
        recorded channel is identical to the same channel of a run that records them
        all: sensor noise is drawn channel by channel in the description's order, so
        a channel left out before a recorded one still draws its noise, and channels
        after the last recorded one cost nothing (the twin's check of a diagnosis
        needs only its sensor set's channels).
    faults : FaultSchedule or iterable of Fault or str, optional
        Faults other than leaks (:mod:`pneufdd.sim.faults`, ``docs/faults.md``), e.g.
        ``["DNC=friction:+50%@2min", "DNC_A=throttle:-40%"]``; scheduled like leaks,
        recorded in the metadata (``fault_schedule``, ``fault_timeline``).
    nuisances : Nuisances, optional
        Ambient temperature, payloads, header dips (:mod:`pneufdd.sim.nuisances`);
        recorded in the metadata (``nuisances``, ``nuisance_timeline``, ``header_dips``).
    supply_open : sequence of bool, optional
        Per cycle, whether the supply shut-off valve at the regulator's outlet is open
        (None: always). Closed, the regulator passes no air: the reservoir, the manifold
        and the lines connected to it keep their air and lose it through their leaks
        (the standstill test's pressure decay, ``docs/standstill.md``).

    Returns
    -------
    SimulationResult
    """
    _check_args(cycles, seed, max_cycle_s)
    desc = load_machine(machine)
    sensors = _recorded_sensors(desc, channels)
    specs = resolve_leaks(desc, leaks)
    plant = compile_plant(desc, specs, resolution)
    if schedule is not None:
        schedule.check(desc, specs)
    conditions = _conditions(desc, plant, faults, nuisances, seed)
    rng = np.random.default_rng(seed)
    state = initial_state(desc, plant)
    plant.sp[lay.SP_COMP_PHASE] = rng.uniform()
    run = _CycleLoop(desc, plant, state, sensors, rng, cycles, max_cycle_s, conditions)
    regulator_cv = float(plant.sp[lay.SP_REG_CV])
    if supply_open is not None and len(supply_open) != cycles:
        raise InputError(describe("supply_open", f"{len(supply_open)} flags", f"{cycles}"))
    try:
        for cyc in range(cycles):
            if supply_open is not None:  # a closed shut-off valve: no flow from the regulator
                plant.sp[lay.SP_REG_CV] = regulator_cv if supply_open[cyc] else 0.0
            run.cycle(cyc, specs, schedule, keep_outputs)
            if progress is not None:
                progress(cyc + 1, cycles)
        samples = int(state["istate"][lay.IS_SAMPLE])
        # the schedules' ground truth, after the metadata a run without them has
        ground_truth: dict[str, Any] = {}
        if schedule is not None:
            ground_truth["leak_schedule"] = schedule.as_metadata()
            ground_truth["leak_timeline"] = run.timeline
        if conditions is not None:
            ground_truth.update(conditions.metadata(samples * SAMPLE_DT))
        result = _assemble(
            desc,
            sensors,
            run.pooled.truth,
            samples,
            plant,
            specs,
            run.chunks,
            run.step_start,
            run.strokes,
            rng,
            seed,
            cycles,
            run.total_sub,
            ground_truth,
        )
    finally:
        run.release()
    return result


def _conditions(
    desc: MachineDescription,
    plant: Plant,
    faults: FaultsLike,
    nuisances: Nuisances | None,
    seed: int | None,
) -> RunConditions | None:
    """The run's faults and nuisances, set for its start (None: none; a plain run does not
    import them, nor numba on the prebuilt twin): :func:`pneufdd.sim.conditions.prepare`."""
    if faults is None and nuisances is None:
        return None
    from pneufdd.sim.conditions import prepare

    return prepare(desc, plant, faults, nuisances, seed)


def _records(
    plant: Plant, state: dict[str, npt.NDArray[Any]], buf: OutputBuffers
) -> tuple[PlantParams, Program, State, Outputs]:
    """The compiled kernel's records over the plant, its state and the buffers."""
    params = PlantParams(plant.sp, plant.ap, plant.vkind, plant.cp)
    program = Program(
        plant.act_start, plant.act_sol, plant.act_mode, plant.act_sw, plant.act_dur,
        plant.wait_start, plant.wait_sw, plant.wait_val, plant.dwell,
    )  # fmt: skip
    records_state = State(*(state[name] for name in State._fields))
    outputs = Outputs(*(getattr(buf, name) for name in Outputs._fields))
    return params, program, records_state, outputs


def kernel_arguments(
    machine: MachineLike = "festo-dsd",
) -> tuple[PlantParams, Program, CycleDraws, State, Outputs]:
    """Arguments of :func:`pneufdd.sim.kernel.run_cycle` for ``machine`` at rest, leak-free.

    Records of the kind (array types and layouts) a simulation passes to the kernel,
    over small buffers: :mod:`pneufdd.sim.prebuilt` types the ahead-of-time build with
    them, so the prebuilt twin accepts exactly what :func:`run_simulation` passes.
    """
    desc = load_machine(machine)
    plant = compile_plant(desc, [])
    na = len(desc.actuators)
    buf = OutputBuffers(10, 2 + 2 * na, na, plant.n_solenoids, plant.n_switches, len(desc.steps))
    params, program, state, outputs = _records(plant, initial_state(desc, plant), buf)
    draws = CycleDraws(np.zeros(len(desc.steps)), np.ones(na), np.zeros(4))
    return params, program, draws, state, outputs


def _recorded_sensors(
    desc: MachineDescription, channels: Sequence[str] | None
) -> tuple[Sensor | None, ...]:
    """The description's sensors up to the last one recorded; None for one left out.

    Raises
    ------
    InputError
        If a channel is not one of the description's sensors.
    """
    if channels is None:
        return tuple(desc.sensors)
    names = [s.channel for s in desc.sensors]
    unknown = [c for c in channels if c not in names]
    if unknown:
        raise InputError(describe(f"channels to record of machine {desc.name!r}", unknown, names))
    wanted = set(channels)
    kept = [s if s.channel in wanted else None for s in desc.sensors]
    while kept and kept[-1] is None:
        kept.pop()
    return tuple(kept)


def _take(
    truth_sources: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
    buf: OutputBuffers,
    n: int,
    k0: int,
    keep: bool,
    store: npt.NDArray[np.float64],
    piston_leak: bool = False,
) -> dict[str, npt.NDArray[Any]]:
    """Copy what one cycle produced out of the reusable buffers.

    The recorded sensors' true signals go to ``store`` (one row each, samples
    ``k0 .. k0 + n``; ``truth_sources`` from :func:`_truth_sources`); the digital
    samples are kept, and every internal state when ``keep`` asks for them (memory
    grows with cycles x samples x states).
    """
    source, column = truth_sources
    if source.size:
        compiled_twin().truth_rows(
            buf.p, buf.x, buf.fch, buf.fexh, buf.fr, source, column, store, k0, n
        )
    chunk: dict[str, npt.NDArray[Any]] = {}
    first = (-k0) % _DIGITAL_EVERY  # digital samples fall on every 10th global sample
    chunk["cmd"] = buf.cmd[first:n:_DIGITAL_EVERY].copy()
    chunk["sw"] = buf.sw[first:n:_DIGITAL_EVERY].copy()
    if keep:
        for k in ("p", "x", "fch", "fexh", "fr", "vac", "fleak", "cum", "mass", "step"):
            chunk[k] = getattr(buf, k)[:n].copy()
        # the kernel writes the piston-seal flows only when a seal leaks (issue 34)
        chunk["fpl"] = buf.fpl[:n].copy() if piston_leak else np.zeros((n, buf.fpl.shape[1]))
    return chunk


def _cat(chunks: list[dict[str, npt.NDArray[Any]]], key: str) -> npt.NDArray[Any]:
    if len(chunks) == 1:
        return chunks[0][key]
    return np.concatenate([c[key] for c in chunks], axis=0)


def _truth_sources(
    desc: MachineDescription, sensors: Sequence[Sensor | None]
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Where each recorded sensor's true signal is in the kernel's outputs.

    One (source, column) per recorded sensor, in their order
    (:func:`pneufdd.sim.kernel.truth_rows_kernel`): a position is a column of ``x``,
    the supply's pressure the manifold node of ``p`` and its flow the supply line of
    ``fr``, an actuator line's pressure its chamber's node and its flow the chamber's
    net flow (in minus exhaust).
    """
    ids = desc.actuator_ids
    found: list[tuple[int, int]] = []
    for sensor in sensors:
        if sensor is None:
            continue
        if sensor.kind == "position":
            found.append((lay.TRUTH_POSITION, ids.index(sensor.location)))
        elif sensor.location == "supply":
            if sensor.kind == "pressure":
                found.append((lay.TRUTH_NODE_PRESSURE, 1))
            else:
                found.append((lay.TRUTH_SUPPLY_FLOW, lay.FR_LINE))
        else:
            act, side = sensor.location.rsplit("_", 1)
            c = 2 * ids.index(act) + (0 if side == "A" else 1)
            if sensor.kind == "pressure":
                found.append((lay.TRUTH_NODE_PRESSURE, 2 + c))
            else:
                found.append((lay.TRUTH_CHAMBER_FLOW, c))
    table = np.array(found, dtype=np.int64).reshape(-1, 2)
    return np.ascontiguousarray(table[:, 0]), np.ascontiguousarray(table[:, 1])


def _assemble(
    desc: MachineDescription,
    sensors: Sequence[Sensor | None],
    store: npt.NDArray[np.float64],
    samples: int,
    plant: Plant,
    specs: list[LeakSpec],
    chunks: list[dict[str, npt.NDArray[Any]]],
    step_start: npt.NDArray[np.float64],
    strokes: list[SimulatedStroke],
    rng: np.random.Generator,
    seed: int | None,
    cycles: int,
    total_sub: int,
    ground_truth: dict[str, Any],
) -> SimulationResult:
    # a description without sensors keeps the length its digital samples give
    n = samples if desc.sensors else sum(c["cmd"].shape[0] for c in chunks) * _DIGITAL_EVERY
    time = np.arange(n, dtype=np.float64) * SAMPLE_DT
    analog: dict[str, npt.NDArray[np.float64]] = {}
    units: dict[str, str] = {}
    rows = iter(store)  # one row per recorded sensor, in their order
    # every sensor's noise, a sensor not recorded drawing its own all the same; the
    # generator is not used after this
    noise = _NOISE.draws(rng, len(sensors), n)
    for sensor, draws in zip(sensors, noise, strict=True):
        if sensor is None:
            continue
        truth = next(rows)[:n]
        analog[sensor.channel] = apply_sensor(sensor, truth, draws, ANALOG_RATE_HZ)
        units[sensor.channel] = SENSOR_SI_UNIT[sensor.kind]
    cmd = _cat(chunks, "cmd")
    sw = _cat(chunks, "sw")
    digital: dict[str, npt.NDArray[np.uint8]] = {}
    for j, name in enumerate(solenoid_slots(desc)):
        if name is not None:  # the B slot of a 5/2 monostable valve has no solenoid
            digital[name] = cmd[:, j]
    for j, name in enumerate(desc.switches):
        digital[name] = sw[:, j]
    metadata = {
        "machine": {"name": desc.name, "title": desc.title, "description": desc.raw},
        "leaks": [s.as_metadata() for s in specs],
        "seed": seed,
        "cycles": cycles,
        "simulator": SIMULATOR_VERSION,
        "cycle_start_s": [float(t) for t in step_start[:, 0]],
        "step_names": [s.name for s in desc.steps],
        **ground_truth,
    }
    recording = Recording.from_arrays(
        analog=analog,
        analog_rate_hz=ANALOG_RATE_HZ,
        digital=digital,
        digital_rate_hz=DIGITAL_RATE_HZ,
        units=units,
        metadata=metadata,
    )
    outputs: dict[str, npt.NDArray[Any]] = {}
    if "cum" in chunks[0]:
        p, x, fch, fexh, fr = (_cat(chunks, k) for k in ("p", "x", "fch", "fexh", "fr"))
        outputs = _outputs(desc, chunks, p, x, fch, fexh, fr)
        outputs["step_start"] = step_start
        for a in desc.actuators:
            mine = [s for s in strokes if s.actuator == a.id]
            outputs[f"stroke_start_{a.id}"] = np.array([s.start for s in mine])
            outputs[f"stroke_end_{a.id}"] = np.array([s.end for s in mine])
            outputs[f"stroke_direction_{a.id}"] = np.array([s.direction for s in mine])
            outputs[f"stroke_first_motion_{a.id}"] = np.array([s.first_motion for s in mine])
    return SimulationResult(
        time=time,
        outputs=outputs,
        step_start=step_start,
        strokes=strokes,
        recording=recording,
        machine=desc,
        leaks=specs,
        substeps=total_sub,
    )


def _outputs(
    desc: MachineDescription,
    chunks: list[dict[str, npt.NDArray[Any]]],
    p: Any,
    x: Any,
    fch: Any,
    fexh: Any,
    fr: Any,
) -> dict[str, npt.NDArray[Any]]:
    out: dict[str, npt.NDArray[Any]] = {
        "p_reservoir": p[:, 0],
        "p_manifold": p[:, 1],
    }
    fleak = _cat(chunks, "fleak")
    fpl = _cat(chunks, "fpl")
    for i, a in enumerate(desc.actuators):
        out[f"x_{a.id}"] = x[:, i]
        out[f"mdot_piston_leak_{a.id}"] = fpl[:, i]
        for s, side in enumerate("AB"):
            c = 2 * i + s
            out[f"p_{a.id}_{side}"] = p[:, 2 + c]
            out[f"mdot_in_{a.id}_{side}"] = fch[:, c]
            out[f"mdot_exhaust_{a.id}_{side}"] = fexh[:, c]
            out[f"mdot_leak_{a.id}_{side}"] = fleak[:, c]
    out["mdot_leak_supply"] = fr[:, lay.FR_SUPPLY_LEAK]
    out["mdot_supply_line"] = fr[:, lay.FR_LINE]
    out["mdot_regulator"] = fr[:, lay.FR_REG]
    out["mdot_vacuum"] = fr[:, lay.FR_VAC]
    out["stored_mass"] = _cat(chunks, "mass")
    cum = _cat(chunks, "cum")
    out["mass_regulator"] = cum[:, lay.CM_REG]
    out["mass_supplied"] = cum[:, lay.CM_LINE]
    out["mass_exhausted"] = cum[:, lay.CM_EXHAUST]
    out["mass_leaked"] = cum[:, lay.CM_LEAK]
    out["mass_vacuum"] = cum[:, lay.CM_VAC]
    out["vacuum_level"] = _cat(chunks, "vac")
    out["step"] = _cat(chunks, "step")
    return out


def simulate(
    machine: MachineLike,
    cycles: int = 1,
    leaks: LeaksLike = None,
    seed: int | None = 0,
    progress: Callable[[int, int], None] | None = None,
    max_cycle_s: float = 120.0,
    schedule: LeakSchedule | None = None,
    faults: FaultsLike = None,
    nuisances: Nuisances | None = None,
) -> Recording:
    """Simulate the machine and return what its sensors and PLC I/O record.

    Parameters
    ----------
    machine : str, Path, MachineDescription or dict
        A built-in name (``"festo-dsd"``), a TOML path or a description.
    cycles : int
        Number of complete PLC cycles.
    leaks : mapping or iterable of Leak, optional
        Location -> size; a number is turns of the GR-3/8B valve, ``"2.5mm"`` an
        orifice diameter, ``"30slpm"`` the flow at the nominal supply pressure.
    seed : int, optional
        Seed; the same seed gives identical output.
    progress : callable, optional
        ``progress(cycles_done, cycles)`` after each cycle.
    max_cycle_s : float
        A cycle longer than this is a stalled machine [s].
    schedule : LeakSchedule, optional
        Leaks that appear, grow and are repaired during the run.
    faults : FaultSchedule or iterable of Fault or str, optional
        Faults other than leaks, e.g. ``["DNC=friction:+50%"]`` (``docs/faults.md``).
    nuisances : Nuisances, optional
        Ambient temperature, payloads and header dips over the run.

    Returns
    -------
    Recording
        Analog channels at 1 kHz (SI: Pa absolute, kg/s, m), digital ``U_*``/``S_*`` at
        100 Hz; metadata holds the machine, the leaks (ground truth), seed, cycles and
        the simulator version.

    Examples
    --------
    >>> rec = simulate("festo-dsd", cycles=1, leaks={"supply": 2}, seed=1)
    >>> rec.metadata["leaks"][0]["location"], rec.metadata["seed"]
    ('supply', 1)
    """
    return run_simulation(
        machine,
        cycles,
        leaks,
        seed,
        progress,
        keep_outputs=False,
        max_cycle_s=max_cycle_s,
        schedule=schedule,
        faults=faults,
        nuisances=nuisances,
    ).recording


def as_exported(recording: Recording) -> Recording:
    """A simulated recording as a DAQ or PLC export of the machine would be.

    A simulation stores the description it ran (for a plant drawn with
    :func:`pneufdd.sim.vary_machine`: the plant's true parameters) in the recording's
    metadata; a real machine's data never carries those. This keeps the machine's
    name and drops the description, so that nothing downstream can use what a real
    plant would not tell.

    Examples
    --------
    >>> rec = as_exported(simulate("press-fit-cell", cycles=1, seed=1))
    >>> rec.metadata["machine"]
    {'name': 'press-fit-cell'}
    """
    meta = dict(recording.metadata)
    machine = meta.get("machine")
    if isinstance(machine, dict):
        meta["machine"] = {"name": machine.get("name")}
    return recording.with_metadata(meta)
