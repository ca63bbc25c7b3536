"""Leak signatures computed with the digital twin (:mod:`pneufdd.sim`).

For every candidate location of the machine (``supply`` and both lines of every
actuator) and a ladder of leak sizes, the machine is simulated with that single leak
and, with the same seed, without it (common random numbers: the house-air
fluctuation and sensor noise are the same in both, so their difference is mostly the
leak's effect). The runs are segmented with the reference's PLC sequence and
summarised per step exactly like measured runs; the mean feature change is the
signature point. Sizes are given as the leak's flow at the machine's nominal supply
pressure (the ground-truth convention of :mod:`pneufdd.sim`); the stored size is the
simulator's resolved nominal mass flow.

A leak so large that the machine stalls (or no longer completes a cycle) is retried
at a smaller size; any other error is an error and propagates.

Everything here is computed from the machine *description* it is given (the one the
reference carries), never from a machine looked up by name.

The same simulations also give the air each leak really loses: the simulator's
cumulative leaked mass over the judged cycles divided by their duration (the mean
leaked mass flow per cycle, stored as :attr:`SignatureSet.mean_flow`), which prices a
leak by eq. 1.1 (:mod:`pneufdd.diagnosis.cost`) without extra simulations.
"""

from __future__ import annotations

import copy
import math
import os
import threading
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.integrate import cumulative_trapezoid

from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.errors import InputError, NoCompleteCycleError, describe
from pneufdd.features.step_summaries import build_step_table, segment_cycles
from pneufdd.limits import MAX_SIGNATURE_CYCLES, MAX_UNCERTAINTY_PLANTS, check_count
from pneufdd.location import SUPPLY, Location, locations_of
from pneufdd.physics.units import kg_s_to_slpm, slpm_to_kg_s
from pneufdd.progress import Progress, counter
from pneufdd.signals.segmentation import StepSpec
from pneufdd.sim import (
    MachineDescription,
    MachineStalledError,
    load_machine,
    run_simulation,
    vary_machine,
)
from pneufdd.sim.faults import Fault
from pneufdd.sim.variation import noise_free

__all__ = [
    "SIGNATURE_SEED",
    "SIGNATURE_SIZES_SLPM",
    "UNCERTAINTY_PLANTS",
    "TwinLeakEffect",
    "candidate_locations",
    "compute_signatures",
    "mean_leak_flow",
    "signature_spread",
]

SIGNATURE_SIZES_SLPM: tuple[float, ...] = (3.0, 8.0, 15.0, 30.0, 50.0, 80.0, 120.0, 170.0, 230.0)
"""Leak sizes simulated per location, as flow at nominal supply pressure [SLPM]."""

INTERACTION_SIZES_SLPM: tuple[float, float] = (50.0, 30.0)
"""Line and supply leak sizes at which the supply interaction is simulated [SLPM]."""

SIGNATURE_SEED = 5_300_001
"""Seed of the signature simulations (section number 5.3 + 1; never used elsewhere)."""


MACHINE_CANNOT_RUN = (MachineStalledError, NoCompleteCycleError)
"""What a leak too large for the machine causes: a stall, or no complete cycle."""

_LADDER_TRIES = 12
"""Sizes tried per signature point, each 0.6 of the way from the last size that ran to
the one that stalled (the last is 0.2 % of that gap above it) [-]."""


UNCERTAINTY_PLANTS = 12
"""Plausible plants whose leak effects sample the signatures' model uncertainty [-]."""

UNCERTAINTY_SCALE = 1.0
"""Their variation scale: a plausible real machine (``docs/plant-variation.md``) [-]."""

DRAFTED_UNCERTAINTY_SCALE = 3.0
"""Variation scale of a *drafted* actuator's parameters in the plausible plants [-].

A drafted actuator's mass, friction, dead volumes, tube, valve and the split of its
air between them are assumed defaults; calibration fits only its size and throttles
to the supply air and the step durations (``docs/calibration.md``). They are known no
better than a factor ``(1 + T)^3`` of the plant tolerances ``T``: mass +-33 %,
friction x/÷ 2.2, dead volumes and tube x/÷ 1.7, throttles x/÷ 3.4, valve +-52 %."""

UNCERTAINTY_SIZES_SLPM: tuple[float, ...] = (8.0, 30.0, 80.0, 200.0)
"""Leak sizes at which the plants' effects are compared with the signatures [SLPM]."""

UNCERTAINTY_PLANT_SEED = 5_300_100
"""Plant ``k`` of the uncertainty ensemble is varied with seed ``5_300_101 + k``."""


def plausible_plant(machine: MachineDescription, scale: float, seed: int) -> MachineDescription:
    """A plant drawn around ``machine``: :func:`pneufdd.sim.vary_machine` at ``scale``,
    its drafted actuators at :data:`DRAFTED_UNCERTAINTY_SCALE` (the same draws, further).

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> press = load_machine("press-fit-cell")
    >>> plausible_plant(press, 1.0, 7).raw == vary_machine(press, 1.0, 7).raw
    True
    """
    plant = vary_machine(machine, scale, seed)
    drafted = {a.id for a in machine.actuators if a.drafted}
    if not drafted or scale >= DRAFTED_UNCERTAINTY_SCALE:
        return plant
    wide = {
        t["id"]: t for t in vary_machine(machine, DRAFTED_UNCERTAINTY_SCALE, seed).raw["actuator"]
    }
    raw = copy.deepcopy(plant.raw)
    raw["actuator"] = [wide[t["id"]] if t["id"] in drafted else t for t in raw["actuator"]]
    return load_machine(raw)


def candidate_locations(machine: MachineDescription) -> tuple[Location, ...]:
    """``supply`` and both lines of every actuator of ``machine``."""
    return locations_of(machine.actuator_ids)


def mean_leak_flow(
    time: npt.NDArray[np.float64],
    mass_leaked: npt.NDArray[np.float64],
    cycle_start: npt.NDArray[np.float64],
    first: int,
    last: int,
) -> float:
    """Mean leaked mass flow over whole machine cycles ``first`` .. ``last - 1``.

    Parameters
    ----------
    time : ndarray
        Sample times [s].
    mass_leaked : ndarray
        Cumulative mass lost through the leak(s) at ``time`` [kg].
    cycle_start : ndarray
        Start time of every cycle [s].
    first, last : int
        Cycles averaged: from the start of ``first`` to the start of ``last``.

    Returns
    -------
    float
        Leaked mass per cycle time [kg/s].

    Examples
    --------
    >>> t = np.linspace(0.0, 30.0, 3001)
    >>> round(mean_leak_flow(t, 2e-3 * t, np.array([0.0, 10.0, 20.0]), 1, 2), 12)
    0.002
    """
    if not 0 <= first < last < cycle_start.size:
        raise InputError(
            describe("cycles averaged", (first, last), f"0 <= first < last < {cycle_start.size}")
        )
    t0, t1 = float(cycle_start[first]), float(cycle_start[last])
    m0, m1 = np.interp([t0, t1], time, mass_leaked)
    return float((m1 - m0) / (t1 - t0))


def _leak_sizes(leaks: Mapping[Location, float]) -> dict[str, str]:
    """Leaks as the simulator takes them: ``{"DNC_B": "55.0slpm"}`` [SLPM]."""
    return {str(loc): f"{slpm}slpm" for loc, slpm in leaks.items()}


def _mean_features(
    machine: MachineDescription,
    leaks: Mapping[Location, float],
    cycles: int,
    seed: int,
    sequence: Sequence[StepSpec],
    channels: Sequence[str],
    leak_flows: bool = True,
    faults: Sequence[Fault] = (),
) -> tuple[npt.NDArray[np.float64], list[dict[str, Any]], tuple[str, ...], dict[Location, float]]:
    """Mean features, leak ground truth, feature names and mean flow of each leak [kg/s].

    ``leaks`` maps each location to its size [SLPM at nominal supply pressure];
    ``faults`` are faults other than leaks present from the start
    (:mod:`pneufdd.sim.faults`). Without ``leak_flows`` the simulator keeps no
    internal states (faster) and the mean flows are not computed (empty dict).

    Raises
    ------
    MachineStalledError, NoCompleteCycleError
        When the machine cannot run with these leaks.
    """
    # ``cycles + 2`` cycles are simulated and every one that segments as complete
    # (all of them: the run ends with an idle tail) is averaged; the leaked air is
    # averaged over the inner ``cycles`` (the first starts from rest)
    sizes = _leak_sizes(leaks)
    sim = run_simulation(
        machine,
        cycles=cycles + 2,
        leaks=sizes,
        seed=seed,
        keep_outputs=leak_flows,
        channels=channels,
        faults=list(faults) or None,
    )
    rec = sim.recording
    found, _, _ = segment_cycles(rec, sequence, f"simulated run with leaks {sizes}")
    table = build_step_table(rec, found, machine.name, channels)
    leaked = {
        loc: mean_leak_flow(
            sim.time,
            cumulative_trapezoid(sim.outputs[f"mdot_leak_{loc}"], sim.time, initial=0.0),
            sim.cycle_start,
            1,
            cycles + 1,
        )
        for loc in (leaks if leak_flows else {})
    }
    return (
        np.mean(table.features(), axis=0),
        rec.metadata["leaks"],
        table.feature_names(),
        leaked,
    )


LadderJob = tuple[
    MachineDescription,
    Location,
    tuple[float, ...],
    int,
    int,
    tuple[StepSpec, ...],
    tuple[str, ...],
]


LadderPoints = tuple[
    npt.NDArray[np.float64], list[npt.NDArray[np.float64]], float, npt.NDArray[np.float64]
]
"""One ladder's sizes [kg/s], mean features, nominal pressure [Pa] and leaked flows [kg/s]."""


class _LadderStalledError(Exception):
    """The machine stalled at every size tried for one ladder point."""

    def __init__(self, error: InputError, largest_run: float) -> None:
        super().__init__(str(error))
        self.error = error
        self.largest_run = largest_run


def _ladder_points(
    machine: MachineDescription,
    loc: Location,
    ladder: Sequence[float],
    cycles: int,
    seed: int,
    sequence: Sequence[StepSpec],
    channels: Sequence[str],
) -> LadderPoints:
    """Sizes [kg/s], mean features, nominal pressure [Pa] and leaked flows [kg/s] of
    one location's ladder; raises :class:`_LadderStalledError` (with the largest size that
    ran [SLPM]) when no size on the way down to the last one that ran runs."""
    sizes = np.zeros(len(ladder))
    leaked = np.zeros(len(ladder))
    means: list[npt.NDArray[np.float64]] = []
    pressure = float("nan")
    previous = 0.0
    ceiling = math.inf  # smallest size found to stall the machine [SLPM]
    for k, slpm in enumerate(ladder):
        # a size at or above one that stalled is searched for below that one
        trial = float(slpm) if slpm < ceiling else previous + 0.6 * (ceiling - previous)
        for _ in range(_LADDER_TRIES):
            try:
                mean, truth, _, flows = _mean_features(
                    machine, {loc: trial}, cycles, seed, sequence, channels
                )
                leaked[k] = flows[loc]
                break
            except MACHINE_CANNOT_RUN:
                ceiling = min(ceiling, trial)
                trial = previous + 0.6 * (trial - previous)
        else:
            error = InputError(
                describe(
                    f"leak signature of machine {machine.name!r} at {loc}",
                    f"{slpm:.4g} SLPM",
                    "a size the machine runs with (it stalls even at "
                    f"{ceiling:.3g} SLPM; give smaller --signature-sizes)",
                )
            )
            raise _LadderStalledError(error, previous)
        sizes[k] = float(truth[0]["mass_flow_kg_s"])
        pressure = float(truth[0]["at_pressure_pa"])
        means.append(mean)
        previous = trial
    return sizes, means, pressure, leaked


def _location_ladder(
    job: LadderJob,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    float,
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
    npt.NDArray[np.float64],
]:
    """Mean features of one location at every size of the ladder (one worker's job).

    Also returns ``M(loc + supply) - M(loc)`` at :data:`INTERACTION_SIZES_SLPM` (NaN
    for the supply itself), from which the supply interaction is formed, the mean
    leaked mass flow per cycle at every size [kg/s], and, at the interaction sizes,
    the line leak's mean flow alone, with the supply leak, and the supply leak's mean
    flow with the line leak [kg/s] (NaN for the supply itself).

    A size the machine cannot run with (the leak stalls it, or leaves it no complete
    cycle) is replaced by the largest that runs on the way down to the last size that
    ran; later sizes are then searched below the smallest that stalled, so the ladder
    of a weak machine ends just below its stall limit instead of failing (a drafted
    festo-dsd stalled at 154 SLPM on DNC_B where the default ladder asks 230 SLPM).
    """
    machine, loc, ladder, cycles, seed, sequence, channels = job

    def points(slpm: Sequence[float]) -> LadderPoints:
        return _ladder_points(machine, loc, slpm, cycles, seed, sequence, channels)

    try:
        sizes, means, pressure, leaked = points(ladder)
    except _LadderStalledError as stalled:
        if stalled.largest_run <= 0.0:
            raise stalled.error from None
        # the machine stalls just above a size that ran, with ladder points left:
        # the whole ladder, scaled to end at the largest size that ran
        scale = stalled.largest_run / float(ladder[-1])
        try:
            sizes, means, pressure, leaked = points(tuple(scale * float(x) for x in ladder))
        except _LadderStalledError as again:
            raise again.error from None
    pair = np.full_like(means[0], np.nan)
    pair_flows = np.full(3, np.nan)
    if not loc.is_supply:
        line, supply = INTERACTION_SIZES_SLPM
        both, _, _, both_flows = _mean_features(
            machine, {loc: line, SUPPLY: supply}, cycles, seed, sequence, channels
        )
        alone, _, _, alone_flows = _mean_features(
            machine, {loc: line}, cycles, seed, sequence, channels
        )
        pair = both - alone
        pair_flows[:] = (alone_flows[loc], both_flows[loc], both_flows[SUPPLY])
    return sizes, np.stack(means), pressure, pair, leaked, pair_flows


def compute_signatures(
    machine: MachineDescription,
    feature_names: Sequence[str],
    sequence: Sequence[StepSpec],
    cycles: int = 2,
    channels: Sequence[str] = (),
    sizes_slpm: Sequence[float] = SIGNATURE_SIZES_SLPM,
    seed: int = SIGNATURE_SEED,
    progress: Progress | None = None,
    workers: int | None = None,
    locations: Sequence[Location] | None = None,
    executor: Executor | None = None,
) -> SignatureSet:
    """Simulate single leaks at every candidate location and size; return the signatures.

    Parameters
    ----------
    machine : MachineDescription
        The machine's description (its digital twin is simulated).
    feature_names : sequence of str
        Features of the reference the signatures must cover.
    sequence : sequence of StepSpec
        The reference's PLC step sequence.
    cycles : int
        Simulated cycles per signature point.
    channels : sequence of str
        Analog channels of the sensor set.
    sizes_slpm : sequence of float
        Leak sizes at nominal supply pressure [SLPM].
    seed : int
        Seed of the simulations.
    progress : callable, optional
        ``progress(task, done, total)`` (:mod:`pneufdd.progress`).
    workers : int, optional
        Processes simulating in parallel (default: one per CPU).
    locations : sequence of Location, optional
        Candidate locations (default: all of the machine's).
    executor : concurrent.futures.Executor, optional
        Runs the locations instead of a pool of ``workers`` processes (e.g. a Dask
        cluster's, :func:`pneufdd.parallel.executor`); left open.

    Returns
    -------
    SignatureSet
    """
    known = candidate_locations(machine)
    locations = known if locations is None else tuple(locations)
    unknown = [str(loc) for loc in locations if loc not in known]
    if unknown:
        raise InputError(
            describe(f"leak locations of {machine.name!r}", unknown, [str(k) for k in known])
        )
    check_count("signature cycles (--signature-cycles)", cycles, MAX_SIGNATURE_CYCLES, low=1)
    advance = counter(progress, "simulating leak signatures", 1 + len(locations))
    base, _, names, _ = _mean_features(machine, {}, cycles, seed, sequence, channels)
    advance()
    index = {n: i for i, n in enumerate(names)}
    missing = [n for n in feature_names if n not in index]
    if missing:
        raise InputError(
            describe(
                f"reference features the twin of {machine.name!r} cannot produce",
                missing[:5],
                names[:5],
            )
            + " (the recordings and the description differ in steps or channels)"
        )
    cols = np.array([index[n] for n in feature_names], dtype=np.int64)
    sizes = np.zeros((len(locations), len(sizes_slpm)))
    deltas = np.zeros((len(locations), len(sizes_slpm), len(feature_names)))
    pressure = np.zeros(len(locations))
    mean_flow = np.zeros((len(locations), len(sizes_slpm)))
    flow_interaction = np.zeros((len(locations), 2))
    jobs: list[LadderJob] = [
        (
            machine,
            loc,
            tuple(float(x) for x in sizes_slpm),
            cycles,
            seed,
            tuple(sequence),
            tuple(channels),
        )
        for loc in locations
    ]
    interaction = np.zeros((len(locations), len(feature_names)))
    supply_alone, _, _, supply_alone_flows = _mean_features(
        machine, {SUPPLY: INTERACTION_SIZES_SLPM[1]}, cycles, seed, sequence, channels
    )
    workers = max(1, min(workers or (os.cpu_count() or 1), len(jobs)))
    own = executor is None and workers > 1
    pool = ProcessPoolExecutor(max_workers=workers) if own else executor
    try:
        results = pool.map(_location_ladder, jobs) if pool else map(_location_ladder, jobs)
        for i, (loc_sizes, loc_means, p, pair, loc_leaked, pair_flows) in enumerate(results):
            sizes[i], deltas[i], pressure[i] = loc_sizes, loc_means[:, cols] - base[cols], p
            mean_flow[i] = loc_leaked
            if not locations[i].is_supply:
                # M(l+s) - M(l) - M(s) + M(0)
                interaction[i] = (pair - supply_alone + base)[cols]
                # each leak's mean flow with the other minus without it
                flow_interaction[i] = (
                    pair_flows[1] - pair_flows[0],
                    pair_flows[2] - supply_alone_flows[SUPPLY],
                )
            advance()
    finally:
        if own and pool is not None:
            pool.shutdown()
    return SignatureSet(
        locations,
        sizes,
        deltas,
        tuple(feature_names),
        pressure,
        interaction,
        np.asarray(slpm_to_kg_s(np.asarray(INTERACTION_SIZES_SLPM, dtype=np.float64))),
        mean_flow,
        flow_interaction,
        baseline=base[cols],
        baseline_run=(cycles, seed),
    )


class TwinLeakEffect:
    """Mean feature change of any set of leaks, simulated with the digital twin.

    The signatures (:func:`compute_signatures`) hold single leaks on a size ladder and
    one interaction point per line; simultaneous large leaks interact far beyond that
    (a supply drawn down by one leak changes how every other line behaves). This
    callable simulates the exact set of leaks asked for, with the same seed as its
    leak-free baseline (common random numbers), and returns the mean feature change
    over the inner cycles, summarised exactly like a measured run. Results are cached
    per set of sizes (rounded to 1e-4 SLPM); the baseline is simulated once, or taken
    from the signatures that simulated it. Calls
    from several threads at once are safe (the compiled twin releases the GIL).

    Parameters
    ----------
    machine : MachineDescription
        The machine's description, as for the signatures.
    feature_names : sequence of str
        Features to return, in this order (a reference's feature names).
    sequence : sequence of StepSpec
        The reference's PLC step sequence.
    channels : sequence of str
        Analog channels of the sensor set.
    cycles : int
        Inner cycles averaged per simulation.
    seed : int
        Seed shared by every simulation (common random numbers).
    baseline : ndarray, optional
        Mean features of the leak-free run of these cycles and this seed, in the order
        of ``feature_names`` (:attr:`SignatureSet.baseline`, the same simulation): not
        simulated again [feature unit].
    """

    def __init__(
        self,
        machine: MachineDescription,
        feature_names: Sequence[str],
        sequence: Sequence[StepSpec],
        channels: Sequence[str],
        cycles: int = 2,
        seed: int = SIGNATURE_SEED,
        baseline: npt.NDArray[np.float64] | None = None,
    ) -> None:
        if cycles < 1:
            raise InputError(describe("simulated cycles per leak effect", cycles, ">= 1"))
        if baseline is not None and np.shape(baseline) != (len(feature_names),):
            raise InputError(
                describe(
                    "shape of the leak-free baseline", np.shape(baseline), [(len(feature_names),)]
                )
            )
        self.machine = machine
        self.feature_names = tuple(feature_names)
        self.sequence = tuple(sequence)
        self.channels = tuple(channels)
        self.cycles = cycles
        self.seed = seed
        self.simulations = 0
        self._lock = threading.RLock()
        self._columns: npt.NDArray[np.int64] | None = None
        self._base: npt.NDArray[np.float64] | None = (
            None if baseline is None else np.array(baseline, dtype=np.float64)
        )
        self._cache: dict[tuple[tuple[Any, ...], ...], npt.NDArray[np.float64] | None] = {}
        self._quiet: TwinLeakEffect | None = None

    def _features(
        self, leaks: Mapping[Location, float], faults: Sequence[Fault] = ()
    ) -> npt.NDArray[np.float64]:
        mean, _, names, _ = _mean_features(
            self.machine, leaks, self.cycles, self.seed, self.sequence, self.channels, False, faults
        )
        with self._lock:
            self.simulations += 1
        if self._columns is None:
            index = {n: i for i, n in enumerate(names)}
            missing = [n for n in self.feature_names if n not in index]
            if missing:
                raise InputError(
                    describe("features the simulator cannot produce", missing[:5], names[:5])
                )
            self._columns = np.array([index[n] for n in self.feature_names], dtype=np.int64)
        return np.asarray(mean[self._columns], dtype=np.float64)

    def fault_change(self, fault: Fault) -> npt.NDArray[np.float64] | None:
        """Feature change of one fault other than a leak, present from the start
        (:mod:`pneufdd.sim.faults`), against the leak-free run of the same seed, both
        without sensor noise (:func:`~pneufdd.sim.variation.noise_free`) [feature
        unit]; cached like the leaks.

        Returns None when the machine cannot run with it (it stalls, or a cycle does
        not complete). Faults the description cannot carry raise
        :class:`~pneufdd.errors.InputError` (a throttle fault on a line without a
        throttle).
        """
        key = (("fault", fault.location, fault.kind, round(fault.size, 6), fault.unit),)
        if key in self._cache:
            return self._cache[key]
        with self._lock:  # without sensor noise, baseline and fault alike: a fault that
            # shifts a step's timing decorrelates the noise (docs/faults.md)
            if self._quiet is None:
                self._quiet = TwinLeakEffect(noise_free(self.machine), self.feature_names,
                    self.sequence, self.channels, self.cycles, self.seed)  # fmt: skip
                self._quiet._base = self._quiet._features({})
        try:
            change: npt.NDArray[np.float64] | None = (
                self._quiet._features({}, (fault,)) - self._quiet._base  # type: ignore[operator]
            )
        except MACHINE_CANNOT_RUN:
            change = None
        self._cache[key] = change
        return change

    def __call__(self, leaks: Mapping[Location, float]) -> npt.NDArray[np.float64] | None:
        """Feature change of ``leaks`` (location -> nominal flow [kg/s]) [feature unit].

        Returns None when the machine cannot run with these leaks (it stalls, or a
        cycle does not complete).
        """
        flows = {loc: float(kg_s_to_slpm(size)) for loc, size in leaks.items() if size > 0}
        key = tuple(sorted((str(loc), round(slpm, 4)) for loc, slpm in flows.items()))
        if key in self._cache:
            return self._cache[key]
        with self._lock:  # the first call of several threads simulates it once
            if self._base is None:
                self._base = self._features({})
        try:
            change: npt.NDArray[np.float64] | None = (
                self._features({Location.parse(name): slpm for name, slpm in key}) - self._base
            )
        except MACHINE_CANNOT_RUN:
            change = None
        self._cache[key] = change
        return change


SpreadJob = tuple[
    MachineDescription,
    tuple[Location, ...],
    tuple[float, ...],
    int,
    int,
    tuple[StepSpec, ...],
    tuple[str, ...],
    npt.NDArray[np.int64],
]


def _plant_effects(job: SpreadJob) -> npt.NDArray[np.float64] | None:
    """Leak effects on one plant: (n_locations, n_sizes, n_features); NaN where it stalls.

    Sizes are orifice diameters [mm], so the plant leaks through the same hole as the
    twin whatever its own supply pressure. None when the plant cannot run leak-free.
    """
    plant, locations, diameters, cycles, seed, sequence, channels, cols = job
    try:
        base, _, _, _ = _mean_features(plant, {}, cycles, seed, sequence, channels, False)
    except MACHINE_CANNOT_RUN:
        return None
    out = np.full((len(locations), len(diameters), cols.size), np.nan)
    for i, loc in enumerate(locations):
        for k, mm in enumerate(diameters):
            try:
                sim = run_simulation(
                    plant,
                    cycles=cycles + 2,
                    leaks={str(loc): f"{mm}mm"},
                    seed=seed,
                    keep_outputs=False,
                    channels=channels,
                )
                rec = sim.recording
                found, _, _ = segment_cycles(rec, sequence, f"plant with a leak at {loc}")
                mean = np.mean(
                    build_step_table(rec, found, plant.name, channels).features(), axis=0
                )
            except MACHINE_CANNOT_RUN:
                continue
            out[i, k] = (mean - base)[cols]
    return out


def signature_spread(
    machine: MachineDescription,
    signatures: SignatureSet,
    sequence: Sequence[StepSpec],
    channels: Sequence[str],
    cycles: int = 2,
    plants: int = UNCERTAINTY_PLANTS,
    scale: float = UNCERTAINTY_SCALE,
    sizes_slpm: Sequence[float] = UNCERTAINTY_SIZES_SLPM,
    seed: int = SIGNATURE_SEED,
    workers: int | None = None,
    progress: Progress | None = None,
    executor: Executor | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    r"""Model uncertainty of the signatures: how they err on plausible plants.

    A real machine differs from its description (valve flow capacity within the
    15 % of ISO 6358, friction, throttle settings, volumes, sensor calibration:
    ``docs/plant-variation.md``), so its leak effects differ from the twin's. This
    samples how: ``plants`` plants are drawn around the description at ``scale``
    (:func:`plausible_plant`, drafted actuators further; seeds independent of any
    plant a campaign judges), single leaks of the same orifice are simulated on each
    at every location and at ``sizes_slpm``, and each plant's effect :math:`e^{(k)}` minus the
    signature's :math:`e` is returned. The deviations of one plant are coherent
    across features (a stiffer supply makes every pressure drop of a leak smaller,
    in every step), so their sample covariance

    .. math::

        \Sigma_{l}(a) = \frac{1}{K} \sum_k d^{(k)}_l(a)\, d^{(k)}_l(a)^T,
        \qquad d^{(k)}_l(a) = e^{(k)}_l(a) - e_l(a),

    not an independent error per feature, describes what the signatures may get
    wrong on a real machine (used by :func:`pneufdd.diagnosis.engine.whitener`).

    Parameters
    ----------
    machine : MachineDescription
        The description the signatures come from.
    signatures : SignatureSet
        Its signatures (same features as ``channels`` and ``sequence`` give).
    sequence : sequence of StepSpec
        The PLC sequence.
    channels : sequence of str
        Analog channels of the sensor set.
    cycles : int
        Inner cycles averaged per simulation.
    plants : int
        Plants drawn [-].
    scale : float
        Their variation scale [-].
    sizes_slpm : sequence of float
        Leak sizes compared [SLPM at the description's nominal supply pressure].
    seed : int
        Seed of the simulations (the signatures' seed).
    workers : int, optional
        Processes simulating in parallel (default: one per CPU).
    progress : callable, optional
        ``progress(task, done, total)``.
    executor : concurrent.futures.Executor, optional
        Runs the plants instead of a pool of ``workers`` processes; left open.

    Returns
    -------
    deviations : ndarray, shape (plants, n_locations, n_sizes, n_features)
        Plant effect minus signature effect [feature unit], rounded to float32
        precision (as the ``.pnref`` stores them); a plant that cannot run with a leak
        contributes zero there, and a plant that cannot run even without a leak (a
        description near its stall limit: a low calibrated supply, a heavy load) is
        left out, so there may be fewer than ``plants`` rows.
    sizes : ndarray, shape (n_sizes,)
        The sizes [kg/s].
    """
    from pneufdd.physics.leaks import SHARP_EDGE_CD, leak_area
    from pneufdd.physics.units import psig_to_pa

    check_count("uncertainty plants (--uncertainty-plants)", plants, MAX_UNCERTAINTY_PLANTS, low=1)
    p_nom = float(psig_to_pa(machine.nominal_supply_psig))
    areas = [float(leak_area(s, "SLPM", p_nom)) for s in sizes_slpm]
    diameters = tuple(1e3 * float(np.sqrt(4.0 * a / (np.pi * SHARP_EDGE_CD))) for a in areas)
    flows = np.array([float(slpm_to_kg_s(s)) for s in sizes_slpm])
    locations = signatures.locations
    twin = np.stack(
        [np.stack([signatures.effect(i, f) for f in flows]) for i in range(len(locations))]
    )
    _, _, names, _ = _mean_features(machine, {}, 1, seed, sequence, channels, False)
    index = {n: i for i, n in enumerate(names)}
    cols = np.array([index[n] for n in signatures.feature_names], dtype=np.int64)
    jobs: list[SpreadJob] = [
        (
            plausible_plant(machine, scale, UNCERTAINTY_PLANT_SEED + 1 + k),
            locations,
            diameters,
            cycles,
            seed,
            tuple(sequence),
            tuple(channels),
            cols,
        )
        for k in range(plants)
    ]
    advance = counter(progress, "simulating plausible plants (model uncertainty)", plants)
    workers = max(1, min(workers or (os.cpu_count() or 1), plants))
    own = executor is None and workers > 1
    pool = ProcessPoolExecutor(max_workers=workers) if own else executor
    deviations = []
    try:
        for effects in pool.map(_plant_effects, jobs) if pool else map(_plant_effects, jobs):
            if effects is not None:
                deviations.append(np.where(np.isfinite(effects), effects - twin, 0.0))
            advance()
    finally:
        if own and pool is not None:
            pool.shutdown()
    if not deviations:
        raise InputError(
            describe(
                f"plausible plants around {machine.name!r} (scale {scale:g})",
                f"{plants} drawn, none runs leak-free",
                "at least one that completes its cycles: check the description's supply "
                "pressure, valves and loads, or build without model uncertainty",
            )
        )
    stacked = np.stack(deviations).astype(np.float32).astype(np.float64)
    return stacked, flows
