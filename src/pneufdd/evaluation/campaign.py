"""Acceptance campaigns: diagnosis accuracy on plants that differ from their twin.

Testing an inversion on data made by the very model it inverts is the "inverse
crime": the model error that dominates in the field is absent. A campaign therefore
judges **plants** (:func:`pneufdd.sim.vary_machine`: every physical parameter drawn
around the description's value, at a ``plant scale``), never the twin itself:

1. **Signatures** are computed once per machine from its description *as written*
   (the twin), like a user's ``pneufdd reference build --machine DESCRIPTION``.
2. For every plant, the **reference** is built from the plant's own leak-free
   recordings, with the description as written (the recordings' metadata, which a
   simulation fills with the plant's true parameters, is stripped to the machine
   name, as in a real DAQ export).
3. **Runs** of the plant (``run_cycles`` complete cycles each): single leaks at every
   location and size, leak-free runs, random pairs of leaks; each is diagnosed with
   every sensor set's reference. The true size of a leak is its orifice's flow at
   the *description's* nominal supply pressure (what the diagnosis estimates).

Every seed is derived from ``seed_offset`` and written to the manifest: a campaign
uses the seeds ``[seed_offset, seed_offset + 10,000,000)``. Plant scale 0 is the twin
itself (the regression check against earlier campaigns).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.effects.twin import (
    UNCERTAINTY_PLANTS,
    compute_signatures,
    signature_spread,
)
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.recordings import build_reference_from_recordings
from pneufdd.diagnosis.reference.file import load_reference, save_reference
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.diagnosis.reference.sensor_sets import (
    SENSOR_SETS,
    check_sensor_set_names,
    machine_sensor_sets,
)
from pneufdd.errors import InputError, NoCompleteCycleError, describe
from pneufdd.evaluation.captures import (
    CaptureDesign,
    reference_recordings,
    run_recordings,
    run_step_table,
)
from pneufdd.evaluation.multi_leak import (
    MULTI_TARGETS,
    check_multi_design,
    multi_record,
    plan_multi_runs,
)
from pneufdd.evaluation.scoring import Tally, outcome_from_record
from pneufdd.features.step_summaries import machine_sequence
from pneufdd.features.step_table import feature_names
from pneufdd.files import safe_name, write_text_atomic
from pneufdd.limits import (
    MAX_CAMPAIGN_COUNT,
    MAX_CYCLES,
    MAX_RUN_CYCLES,
    MAX_SIGNATURE_CYCLES,
    MAX_UNCERTAINTY_PLANTS,
    check_count,
)
from pneufdd.location import locations_of
from pneufdd.parallel import available_cores, executor, map_unordered, resolve_workers
from pneufdd.physics.leaks import leak_mass_flow
from pneufdd.physics.units import psig_to_pa
from pneufdd.progress import Progress, counter
from pneufdd.recording.model import Recording
from pneufdd.sim import (
    MachineDescription,
    MachineStalledError,
    load_machine,
    parse_leak_size,
)
from pneufdd.sim.variation import machine_to_toml, vary_machine

__all__ = [
    "SENSOR_SETS",
    "TARGETS",
    "CampaignDesign",
    "CampaignResult",
    "campaign_files",
    "rescore",
    "run_campaign",
]

_COMMON_TARGETS = {
    "in_group": 0.98,
    "size_error_median": 0.10,
    "size_error_p90": 0.25,
    "spurious_second_leak": 0.03,
    "leak_free_flagged": 0.005,
    "pairs_both": 0.90,
    "confident_true": 0.97,
}
TARGETS: dict[str, dict[str, float]] = {
    "full": {**_COMMON_TARGETS, "mean_group": 1.2},
    "supply-only": {**_COMMON_TARGETS, "mean_group": 1.5},
}
"""Issue 9's acceptance targets, judged on plants at scale 1."""

SEED_SPAN = 10_000_000
"""Seeds a campaign uses: ``[seed_offset, seed_offset + SEED_SPAN)``."""


@dataclass(frozen=True)
class CampaignDesign:
    """What a campaign simulates and judges.

    Attributes
    ----------
    machines : tuple of str
        Built-in machine names or TOML paths (each a description as written).
    plant_scales : tuple of float
        Plant variation scales (0: the twin itself; 1: a plausible real machine;
        2: a badly documented one) [-].
    plants : int
        Plants per machine and scale [-].
    sensor_sets : tuple of str
        Of :data:`SENSOR_SETS`; a set the machine does not have is skipped, and
        ``full`` is skipped when it equals ``supply-only``.
    leak_sizes : tuple of str
        Single-leak sizes as the simulator takes them: turns of the GR-3/8B leak valve
        (``"3"``), ``"2.5mm"`` or ``"30slpm"``.
    reps : int
        Runs per location and size and plant (0: no single-leak runs) [-].
    leak_free_runs : int
        Leak-free runs per plant [-].
    pairs : int
        Runs with two leaks (random locations and sizes) per plant [-].
    run_cycles : int
        Complete cycles judged per run [-].
    reference_cycles : int
        Leak-free cycles simulated for each plant's reference, start-up cycles not
        counted [-].
    reference_recordings : int
        Recordings the reference cycles are split into (each with its own house-air
        state and seed) [-].
    signature_cycles : int
        Simulated cycles per signature point [-].
    uncertainty_plants : int
        Plausible plants measuring the signatures' model uncertainty (0: none) [-].
    seed_offset : int
        First seed; the campaign uses ``[seed_offset, seed_offset + 10,000,000)``.
    calibrate : bool
        Calibrate the description to each plant's leak-free reference recordings
        (:func:`~pneufdd.calibration.calibrate.calibrate_machine`, issue 10) and compute
        that plant's signatures from the calibrated description, as
        ``pneufdd reference build --calibrate`` does; otherwise the signatures come
        once per machine from the description as written.
    capture : CaptureDesign, optional
        Triggered captures instead of continuous recordings (:mod:`.captures`).
    leaks_per_run : tuple of int
        Designs with that many simultaneous leaks at random locations and sizes
        (:mod:`~pneufdd.evaluation.multi_leak`; empty: none) [-].
    multi_leak_runs : int
        Runs per plant of each of those designs [-].
    """

    machines: tuple[str, ...]
    plant_scales: tuple[float, ...] = (1.0,)
    plants: int = 3
    sensor_sets: tuple[str, ...] = ("full", "supply-only")
    leak_sizes: tuple[str, ...] = ("1", "2", "3", "4", "5", "6")
    reps: int = 1
    leak_free_runs: int = 70
    pairs: int = 20
    run_cycles: int = 10
    reference_cycles: int = 100
    reference_recordings: int = 4
    signature_cycles: int = 2
    uncertainty_plants: int = UNCERTAINTY_PLANTS
    seed_offset: int = 100_000_000
    calibrate: bool = False
    capture: CaptureDesign | None = None
    leaks_per_run: tuple[int, ...] = ()
    multi_leak_runs: int = 20

    def __post_init__(self) -> None:
        if not self.machines:
            raise InputError(describe("campaign machines", [], "at least one machine"))
        check_sensor_set_names(self.sensor_sets, "campaign sensor sets")
        for name in ("plants", "run_cycles", "signature_cycles"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(describe(f"campaign {name}", value, "an integer >= 1"))
        for name, limit, low in (
            ("run_cycles", MAX_RUN_CYCLES, 1),
            ("signature_cycles", MAX_SIGNATURE_CYCLES, 1),
            ("uncertainty_plants", MAX_UNCERTAINTY_PLANTS, 0),
            ("reference_cycles", MAX_CYCLES, 10),
            *(
                (name, MAX_CAMPAIGN_COUNT, 0)
                for name in ("plants", "reps", "leak_free_runs", "pairs")
            ),
        ):
            option = f"campaign {name} (--{name.replace('_', '-')})"
            check_count(option, getattr(self, name), limit, low)
        for name in ("reps", "leak_free_runs", "pairs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InputError(describe(f"campaign {name}", value, "an integer >= 0"))
        if self.reference_cycles < 10:
            raise InputError(describe("campaign reference_cycles", self.reference_cycles, ">= 10"))
        if (
            isinstance(self.reference_recordings, bool)
            or not isinstance(self.reference_recordings, int)
            or not 1 <= self.reference_recordings <= 9
            or self.reference_cycles < 5 * self.reference_recordings
        ):
            raise InputError(
                describe(
                    "campaign reference_recordings",
                    self.reference_recordings,
                    "an integer from 1 to 9 with at least 5 reference cycles each",
                )
            )
        if any(not (0.0 <= s <= 5.0) for s in self.plant_scales) or not self.plant_scales:
            raise InputError(
                describe("campaign plant scales", list(self.plant_scales), "numbers from 0 to 5")
            )
        for size in self.leak_sizes:
            parse_leak_size(size, "campaign leak size")
        if not self.leak_sizes:
            raise InputError(describe("campaign leak sizes", [], "at least one size"))
        if self.seed_offset < 0:
            raise InputError(describe("campaign seed_offset", self.seed_offset, ">= 0"))
        if self.plants > 9 or len(self.plant_scales) > 9 or len(self.machines) > 9:
            raise InputError(
                describe(
                    "campaign size",
                    f"{len(self.machines)} machines x {len(self.plant_scales)} scales x "
                    f"{self.plants} plants",
                    "at most 9 of each (the seed layout)",
                )
            )
        runs = (
            self.reps * len(self.leak_sizes) * 60
            + self.leak_free_runs
            + self.pairs
            + check_multi_design(self.leaks_per_run, self.multi_leak_runs)
        )  # at most 29 actuators
        if runs >= 9_000:
            raise InputError(describe("campaign runs per plant", runs, "< 9000"))


@dataclass(frozen=True)
class Job:
    """One run to simulate on a plant and diagnose with each sensor set's reference."""

    machine: str
    scale: float
    plant: int
    kind: str
    leaks: dict[str, str]
    seed: int
    plant_file: str
    references: dict[str, str]
    nominal_pressure_pa: float
    run_cycles: int
    threads: int = 1
    """Threads of each diagnosis's check by simulation: the cores left to one worker."""
    capture: CaptureDesign | None = None
    """Triggered captures instead of one continuous recording per run."""


@dataclass
class CampaignResult:
    """Tallies per (machine, plant scale, sensor set) and where everything was written."""

    tallies: dict[tuple[str, float, str], Tally] = field(default_factory=dict)
    stalled: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0
    out: Path = Path(".")

    def lines(self) -> list[str]:
        """The campaign's figures as printable lines."""
        out: list[str] = []
        for (machine, scale, sensors), t in sorted(self.tallies.items()):
            targets = TARGETS.get(sensors) if scale == 1.0 else None
            multi = MULTI_TARGETS.get(sensors) if scale == 1.0 else None
            out.append("")
            out.append(f"=== {machine}, plant scale {scale:g}, sensor set {sensors} ===")
            out.extend(t.lines(targets, multi))
        out.append("")
        out.append(
            "runs not judged (the plant stalled, or completed no cycle, with these leaks): "
            f"{len(self.stalled)}"
        )
        out.extend(f"  {s}" for s in self.stalled[:20])
        out.append(f"campaign wall time {self.seconds:.0f} s; outputs in {self.out}")
        return out


def _seed(design: CampaignDesign, machine: int, scale: int, plant: int, k: int) -> int:
    return design.seed_offset + 1_000_000 * machine + 100_000 * scale + 10_000 * plant + k


def channel_sets(machine: MachineDescription, names: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """Analog channels of each named sensor set the machine has
    (:func:`~pneufdd.diagnosis.reference.sensor_sets.machine_sensor_sets`)."""
    return machine_sensor_sets(tuple(s.channel for s in machine.sensors), names)


def _signatures(
    machine: MachineDescription,
    channels: tuple[str, ...],
    design: CampaignDesign,
    progress: Progress | None,
    workers: int,
    pool: Executor | None,
) -> SignatureSet:
    if pool is None and available_cores() > 1:
        # in this process the signature simulations share the cores on threads (the
        # twin's kernel releases the GIL); each is the same as on its own
        with ThreadPoolExecutor(available_cores()) as threads:
            return _signatures(machine, channels, design, progress, workers, threads)
    sequence = machine_sequence(machine)
    if sequence is None:  # pragma: no cover - a description always has a sequence
        raise InputError(describe("machine sequence", None, "a PLC sequence"))
    names = feature_names(channels, len(sequence))
    signatures = compute_signatures(
        machine,
        names,
        sequence,
        cycles=design.signature_cycles,
        channels=channels,
        progress=progress,
        workers=workers,
        executor=pool,
    )
    if design.uncertainty_plants == 0:
        return signatures
    return signatures.with_plant_deviations(
        *signature_spread(
            machine,
            signatures,
            sequence,
            channels,
            cycles=design.signature_cycles,
            plants=design.uncertainty_plants,
            workers=workers,
            progress=progress,
            executor=pool,
        )
    )


def _calibrated_twin(
    machine: MachineDescription,
    recordings: Sequence[Recording],
    plant_file: Path,
    seed: int,
    say: Callable[[str], None],
) -> tuple[MachineDescription, dict[str, Any]]:
    """The description calibrated to a plant's leak-free recordings, saved beside it."""
    from pneufdd.calibration.calibrate import calibrate_machine

    t0 = time.perf_counter()
    result = calibrate_machine(machine, recordings, seed=seed)
    twin = result.calibrated_description(f"{len(recordings)} leak-free recordings of the plant")
    path = _calibrated_file(plant_file)
    write_text_atomic(path, machine_to_toml(twin, str(twin.raw["machine"]["title"])))
    fit = result.fit_summary()
    seconds = time.perf_counter() - t0
    say(f"{machine.name}: {plant_file.stem} calibrated in {seconds:.0f} s; {result.fit_line()}")
    misfit = result.weighted_misfit()
    return twin, {"file": str(path), "seconds": seconds, "fit": fit, "weighted_misfit": misfit}


def _reference(
    machine: MachineDescription,
    channels: tuple[str, ...],
    recordings: Sequence[Recording],
    signatures: SignatureSet,
) -> ReferenceModel:
    model = build_reference_from_recordings(
        recordings,
        channels,
        [f"plant leak-free recording {i + 1}" for i in range(len(recordings))],
        machine=machine,
        with_signatures=False,
    )
    return model.with_signatures(signatures)


_REFERENCES: dict[str, ReferenceModel] = {}
_PLANTS: dict[str, MachineDescription] = {}


def _cached_reference(path: str) -> ReferenceModel:
    if path not in _REFERENCES:
        _REFERENCES[path] = load_reference(path)
    return _REFERENCES[path]


def _cached_plant(path: str) -> MachineDescription:
    if path not in _PLANTS:
        _PLANTS[path] = load_machine(Path(path))
    return _PLANTS[path]


def _stall_entry(record: Mapping[str, Any]) -> dict[str, Any]:
    """What the campaign prints of a run it could not judge."""
    entry = {k: record[k] for k in ("machine", "leaks", "seed")}
    if "reason" in record:
        entry["reason"] = record["reason"]
    return entry


def run_job(job: Job) -> list[dict[str, Any]]:
    """Simulate one run on its plant and diagnose it with every reference (a worker)."""
    plant = _cached_plant(job.plant_file)
    base = {
        "machine": job.machine,
        "scale": job.scale,
        "plant": job.plant,
        "kind": job.kind,
        "seed": job.seed,
        "leaks": job.leaks,
    }
    try:
        recordings, leaks = run_recordings(job.capture, plant, job.run_cycles, job.leaks, job.seed)
    except MachineStalledError:
        return [{**base, "stalled": True}]
    truth = {
        leak["location"]: float(
            leak_mass_flow(job.nominal_pressure_pa, float(leak["effective_area_m2"]))
        )
        for leak in leaks
    }
    records = []
    for sensors, path in job.references.items():
        model = _cached_reference(path)
        try:
            table = run_step_table(
                model,
                recordings,
                job.run_cycles,
                f"campaign run seed {job.seed}",
                pooled=job.capture is not None,
            )
        except NoCompleteCycleError as exc:
            # the leaks keep the machine from completing its sequence as the PLC
            # expects (a vacuum switch that never falls): a plant failure like a stall,
            # not a run to judge
            return [{**base, "stalled": True, "reason": str(exc)}]
        start = time.perf_counter()
        result = diagnose(model, table, threads=job.threads)
        seconds = time.perf_counter() - start
        loc = result.localisation
        records.append(
            {
                **base,
                "sensors": sensors,
                "truth": truth,
                "detected": result.detected,
                "cycles": int(result.cycle_scores.size),
                "cycles_flagged": int(np.sum(result.cycle_scores > result.cycle_threshold)),
                "leaks": [
                    {
                        "location": str(leak.location),
                        "group": [str(x) for x in leak.ambiguity_group],
                        "group_flows": list(leak.group_mass_flows),
                        "confidence": leak.confidence,
                    }
                    for leak in (loc.leaks if loc is not None else ())
                ],
                "alternatives": []
                if loc is None
                else [[str(x) for x in alt.locations] for alt in loc.alternatives],
                "seconds": seconds,
                "simulated": bool(loc is not None and loc.checked_by_simulation),
                **multi_record(result),
            }
        )
    return records


def _run_jobs(
    jobs: Sequence[Job], pool: Executor | None, progress: Progress | None
) -> Iterator[tuple[int, list[dict[str, Any]]]]:
    """(job index, records) of every job, as each finishes (on ``pool`` when given)."""
    advance = counter(progress, "diagnosing campaign runs", len(jobs))
    for index, records in map_unordered(run_job, jobs, pool):
        yield index, records
        advance()


def _plan_runs(
    design: CampaignDesign,
    machine: MachineDescription,
    m: int,
    s: int,
    k: int,
) -> list[tuple[str, dict[str, str], int]]:
    """(kind, leaks, seed) of every run of one plant, in a fixed order."""
    locations = [str(x) for x in locations_of(machine.actuator_ids)]
    runs: list[tuple[str, dict[str, str], int]] = []
    index = 100
    for loc in locations:
        for size in design.leak_sizes:
            for _ in range(design.reps):
                runs.append(("single", {loc: size}, _seed(design, m, s, k, index)))
                index += 1
    for _ in range(design.leak_free_runs):
        runs.append(("free", {}, _seed(design, m, s, k, index)))
        index += 1
    rng = np.random.default_rng(_seed(design, m, s, k, 99))
    for _ in range(design.pairs):
        a, b = rng.choice(len(locations), size=2, replace=False)
        leaks = {
            locations[int(a)]: str(rng.choice(design.leak_sizes)),
            locations[int(b)]: str(rng.choice(design.leak_sizes)),
        }
        runs.append(("pair", leaks, _seed(design, m, s, k, index)))
        index += 1
    return runs + plan_multi_runs(design, locations, lambda i: _seed(design, m, s, k, i), index)


def _plant_file(folder: Path, machine_name: str, scale: float, k: int) -> Path:
    """Where plant ``k`` (0-based) of a machine at a scale is saved; always in ``folder``.

    The machine's name comes from its file: it is made a safe file-name component
    (:func:`pneufdd.files.safe_name`), so ``name = "../../x"`` cannot leave ``folder``.
    """
    return folder / "plants" / f"{safe_name(machine_name)}-s{scale:g}-p{k + 1}.toml"


def _calibrated_file(plant_file: Path) -> Path:
    return plant_file.with_name(f"{plant_file.stem}-calibrated.toml")


def _reference_file(plant_file: Path, sensors: str) -> Path:
    return plant_file.parent.parent / "references" / f"{plant_file.stem}-{safe_name(sensors)}.pnref"


def campaign_files(design: CampaignDesign, out: str | Path) -> dict[str, Path]:
    """Every file :func:`run_campaign` writes under ``out``, by a label naming it.

    For checking before any work that no output is one of the campaign's inputs (a
    machine file inside ``out``) and that no two share a path (two machines of one
    name); every path lies inside ``out``.

    Parameters
    ----------
    design : CampaignDesign
        The campaign (its machines are loaded to read their names).
    out : str or Path
        The campaign folder.

    Returns
    -------
    dict of str to Path
    """
    folder = Path(out).absolute()
    files = {f"--out {n}": folder / n for n in ("manifest.json", "runs.jsonl", "summary.json")}
    for m, name in enumerate(design.machines):
        machine = load_machine(name)
        sets = channel_sets(machine, design.sensor_sets)
        for scale in design.plant_scales:
            for k in range(design.plants):
                plant = _plant_file(folder, machine.name, scale, k)
                paths = [plant, *(_reference_file(plant, sensors) for sensors in sets)]
                if design.calibrate:
                    paths.append(_calibrated_file(plant))
                for path in paths:
                    files[f"--out file {path.relative_to(folder)} (machine {m + 1})"] = path
    return files


def run_campaign(
    design: CampaignDesign,
    out: str | Path,
    workers: int | None = None,
    progress: Progress | None = None,
    log: Callable[[str], None] | None = None,
    scheduler: str | None = None,
) -> CampaignResult:
    """Run a campaign; write its manifest, plants, references and run records under ``out``.

    Parameters
    ----------
    design : CampaignDesign
        What to simulate and judge.
    out : str or Path
        Output folder (created); ``manifest.json`` (design and every seed),
        ``plants/*.toml``, ``references/*.pnref``, ``runs.jsonl`` (one record per run
        and sensor set, in the order runs finish; ``run`` is its place in the plan)
        and ``summary.json``. An existing ``runs.jsonl`` is never
        overwritten: pick a new folder.
    workers : int, optional
        Worker processes of the local Dask cluster the campaign runs on (default: one
        per CPU; 1: everything in this process). See :func:`pneufdd.parallel.executor`.
    progress : callable, optional
        ``progress(task, done, total)``.
    log : callable, optional
        Receives one line per stage (e.g. ``print``).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) to run on instead of
        a local cluster; its workers must read ``out`` at the same path (a shared
        folder). The figures are the same wherever the runs are simulated.

    Returns
    -------
    CampaignResult
    """
    start = time.perf_counter()
    folder = Path(out).absolute()  # workers may run elsewhere (another cwd)
    if (folder / "runs.jsonl").exists():
        raise InputError(
            describe(f"campaign folder {str(folder)!r}", "holds a campaign", "a new folder")
        )
    (folder / "plants").mkdir(parents=True, exist_ok=True)
    (folder / "references").mkdir(parents=True, exist_ok=True)
    workers = resolve_workers(workers)
    say = log or (lambda _line: None)
    with executor(workers, scheduler) as pool:
        where = f"Dask scheduler {scheduler}" if scheduler else f"{workers} worker(s)"
        say(f"running on {where}")
        return _run_campaign(design, folder, workers, pool, progress, say, where, start)


def _run_campaign(
    design: CampaignDesign,
    folder: Path,
    workers: int,
    pool: Executor | None,
    progress: Progress | None,
    say: Callable[[str], None],
    where: str,
    start: float,
) -> CampaignResult:
    manifest: dict[str, Any] = {"design": asdict(design), "machines": []}
    jobs: list[Job] = []
    # in this process, a diagnosis's simulations may use every core; a cluster's
    # workers already share them
    threads = available_cores() if pool is None else 1
    for m, name in enumerate(design.machines):
        machine = load_machine(name)
        sets = channel_sets(machine, design.sensor_sets)
        if not sets:
            raise InputError(
                describe(
                    f"sensor sets of machine {machine.name!r}",
                    list(design.sensor_sets),
                    "a set the machine has",
                )
            )
        # signatures of every channel any set uses, in the machine's order; each set's
        # reference takes its own features from them
        used = {c for channels in sets.values() for c in channels}
        all_channels = tuple(s.channel for s in machine.sensors if s.channel in used)
        signatures: SignatureSet | None = None
        if not design.calibrate:
            t0 = time.perf_counter()
            signatures = _signatures(machine, all_channels, design, progress, workers, pool)
            say(
                f"{machine.name}: signatures of {len(signatures.locations)} locations from "
                f"the description in {time.perf_counter() - t0:.0f} s; sensor sets {list(sets)}"
            )
        nominal = float(psig_to_pa(machine.nominal_supply_psig))
        entry: dict[str, Any] = {"machine": machine.name, "source": str(name), "plants": []}
        per_recording = -(-design.reference_cycles // design.reference_recordings)
        for s, scale in enumerate(design.plant_scales):
            for k in range(design.plants):
                plant_seed = _seed(design, m, s, k, 0)
                plant = machine if scale == 0 else vary_machine(machine, scale, plant_seed)
                plant_file = _plant_file(folder, machine.name, scale, k)
                write_text_atomic(
                    plant_file,
                    machine_to_toml(
                        plant,
                        f"plant {k + 1} of {machine.name} at scale {scale:g}, seed {plant_seed}",
                    ),
                )
                ref_seeds = [
                    _seed(design, m, s, k, 1 + r) for r in range(design.reference_recordings)
                ]
                recordings = reference_recordings(design.capture, plant, ref_seeds, per_recording)
                twin, plant_signatures, calibration = machine, signatures, None
                if plant_signatures is None:
                    twin, calibration = _calibrated_twin(
                        machine, recordings, plant_file, plant_seed, say
                    )
                    plant_signatures = _signatures(
                        twin, all_channels, design, progress, workers, pool
                    )
                references = {}
                for sensors, channels in sets.items():
                    model = _reference(
                        twin,
                        channels,
                        recordings,
                        plant_signatures.select(feature_names(channels, len(machine.steps))),
                    )
                    path = _reference_file(plant_file, sensors)
                    save_reference(model, path, overwrite=True)
                    references[sensors] = str(path)
                runs = _plan_runs(design, machine, m, s, k)
                entry["plants"].append(
                    {
                        "scale": scale,
                        "plant": k + 1,
                        "plant_seed": plant_seed,
                        "plant_file": str(plant_file),
                        "reference_seeds": ref_seeds,
                        "references": references,
                        **({"calibration": calibration} if calibration else {}),
                        "runs": [
                            {"kind": kind, "leaks": leaks, "seed": seed}
                            for kind, leaks, seed in runs
                        ],
                    }
                )
                jobs.extend(
                    Job(
                        machine.name,
                        float(scale),
                        k + 1,
                        kind,
                        leaks,
                        seed,
                        str(plant_file),
                        references,
                        nominal,
                        design.run_cycles if design.capture is None else design.capture.run_cycles,
                        threads,
                        design.capture,
                    )
                    for kind, leaks, seed in runs
                )
                say(
                    f"{machine.name}: plant {k + 1} at scale {scale:g} (seed {plant_seed}): "
                    f"references of {model.n_cycles} cycles, {len(runs)} runs planned"
                )
        manifest["machines"].append(entry)
    write_text_atomic(folder / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    say(f"{len(jobs)} runs on {where}")
    result = CampaignResult(out=folder)
    finished: dict[int, list[dict[str, Any]]] = {}
    with open(folder / "runs.jsonl", "x", encoding="utf-8") as handle:
        for index, records in _run_jobs(jobs, pool, progress):
            for record in records:  # saved as each run finishes: nothing lost on a crash
                record["run"] = index  # its place in the plan (rescore tallies in it)
                handle.write(json.dumps(record) + "\n")
                handle.flush()
            finished[index] = records
    # tallied in the planned order, not the order runs finished: a float sum depends
    # on its order, and a cluster must give the serial path's figures to the last bit
    _tally((record for index in sorted(finished) for record in finished[index]), result)
    result.seconds = time.perf_counter() - start
    summary = {
        f"{machine} | scale {scale:g} | {sensors}": {
            "figures": t.figures(),
            "multi_leaks": t.multi_figures(),
            "reliability": t.reliability(),
        }
        for (machine, scale, sensors), t in result.tallies.items()
    }
    write_text_atomic(folder / "summary.json", json.dumps(summary, indent=1) + "\n")
    return result


def rescore(folder: str | Path) -> CampaignResult:
    """Tallies of a finished campaign from its ``runs.jsonl`` (no simulation)."""
    path = Path(folder) / "runs.jsonl"
    if not path.is_file():
        raise InputError(describe("campaign runs file", str(path), "an existing runs.jsonl"))
    result = CampaignResult(out=Path(folder))
    records = [json.loads(line) for line in path.read_text("utf-8").splitlines()]
    # in the planned order, as run_campaign tallies (files written before the "run"
    # field keep their line order)
    records.sort(key=lambda r: int(r.get("run", 0)))
    _tally(records, result)
    return result


def _tally(records: Iterable[Mapping[str, Any]], result: CampaignResult) -> None:
    """Count ``records`` in the order given into ``result``'s tallies per (machine,
    scale, sensor set); runs where the plant stalled are listed apart."""
    for record in records:
        if record.get("stalled"):
            result.stalled.append(_stall_entry(record))
            continue
        key = (record["machine"], float(record["scale"]), record["sensors"])
        result.tallies.setdefault(key, Tally()).add(outcome_from_record(record))
