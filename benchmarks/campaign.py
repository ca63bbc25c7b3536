"""Acceptance campaign of issue 5: detection, location, size and false alarms on festo-dsd.

Not part of ``make test`` or ``make bench`` (it takes tens of minutes). Run::

    .venv/bin/python benchmarks/campaign.py [--reps 1] [--leak-free-runs 200] [--pairs 60]

Seeds: every seed is ``SEED_OFFSET + k`` with ``SEED_OFFSET = 92_000_000``. No seed at
or above 90,000,000 is used anywhere else in pneufdd (tests and development use seeds
below 10,000,000; the leak signatures use 5,300,001; the demo 4,200,000 + k), so the
campaign never sees data the methods were tuned on. (Offset 91,000,000 served one run
on a pre-merge simulator; only its summary was looked at, and it is retired. 92,000,000
measured main after issue 5's merge; ``--seed-offset 93000000`` measured the ``pairs``
branch once; 94,000,000 measured the explanations checked by simulation. A new
measurement takes a new offset.)

A run is 10 consecutive complete cycles (12 are simulated: the first starts from rest
mid-sequence and the last has no successor to close its last step). Single leaks: every
candidate location, 1 to 6 turns of the GR-3/8B leak valve. Both first-class sensor
sets (full rig; ``P_In, Q_In`` + PLC digital signals) and the digital-only set
(measured, no target) are judged on the same simulated runs. Printed figures:

- detection rate of leak runs; false-alarm rate of leak-free runs (run level);
- true location inside the reported ambiguity group; mean group size;
- median (and 90th percentile) relative size error of the true location's estimate;
- per-cycle detection and false-alarm rates (each cycle judged alone);
- two simultaneous leaks: both locations found (in the ambiguity groups; separately, in
  the groups or one listed alternative explanation), mean group size on pair runs;
- single-leak runs that list an alternative explanation, and that report a second
  (spurious) leak; diagnosis time per run;
- cross-validated per-cycle false-alarm rate of each reference;
- runs the simulator could not complete (the machine stalls with some pairs of large
  leaks: no cycle to diagnose), listed and excluded.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

SEED_OFFSET = 92_000_000  # default; --seed-offset picks a fresh range (93,000,000: pairs branch)
SENSOR_SETS: dict[str, tuple[str, ...] | None] = {
    "full": None,
    "supply-only (P_In, Q_In)": ("P_In", "Q_In"),
    "digital only": (),
}
TARGETS = {
    "full": {"group": 1.2},
    "supply-only (P_In, Q_In)": {"group": 1.5},
}
RUN_CYCLES = 10


@dataclass
class Tally:
    """Outcome counts of one sensor set."""

    leak_runs: int = 0
    detected: int = 0
    inside: int = 0
    group_sizes: list[int] = field(default_factory=list)
    size_errors: list[float] = field(default_factory=list)
    free_runs: int = 0
    free_flagged: int = 0
    cycle_leak: int = 0
    cycle_leak_flagged: int = 0
    cycle_free: int = 0
    cycle_free_flagged: int = 0
    pairs: int = 0
    pairs_both: int = 0
    pairs_both_alt: int = 0
    pair_group_sizes: list[int] = field(default_factory=list)
    single_with_alternatives: int = 0
    single_extra_leak: int = 0
    diagnosis_seconds: list[float] = field(default_factory=list)
    by_location: dict[str, list[bool]] = field(default_factory=dict)


_MODELS: dict[str, Any] = {}


def _init(paths: dict[str, str]) -> None:
    from pneufdd.diagnosis.pnref import load_reference

    for name, path in paths.items():
        _MODELS[name] = load_reference(path)


def _job(
    job: tuple[str, dict[str, float], int],
) -> tuple[str, list[dict[str, Any]], dict[str, Any]]:
    """Simulate one run and diagnose it with every reference."""
    from pneufdd.diagnosis.engine import diagnose
    from pneufdd.diagnosis.pipeline import run_table
    from pneufdd.sim import MachineStalledError, simulate

    kind, leaks, seed = job
    try:
        rec = simulate("festo-dsd", cycles=RUN_CYCLES + 2, leaks=leaks, seed=seed)
    except MachineStalledError:
        return "stalled", [{"location": loc, "size": size} for loc, size in leaks.items()], {}
    truth = rec.metadata["leaks"]
    out: dict[str, Any] = {}
    for name, model in _MODELS.items():
        table = run_table(model, rec, f"campaign run seed {seed}")
        table = table.take(np.arange(min(RUN_CYCLES, table.n_cycles)))
        t0 = time.perf_counter()
        result = diagnose(model, table)
        seconds = time.perf_counter() - t0
        det = model.detector
        scores = result.cycle_scores
        out[name] = {
            "detected": result.detected,
            "seconds": seconds,
            "alternatives": []
            if result.localisation is None
            else [[str(x) for x in a.locations] for a in result.localisation.alternatives],
            "cycles": int(scores.size),
            "cycles_flagged": int(np.sum(scores > det.threshold_)),
            "leaks": [
                {
                    "location": str(leak.location),
                    "group": [str(x) for x in leak.ambiguity_group],
                    "group_flows": [],
                    "mass_flow": leak.mass_flow,
                }
                for leak in result.leaks
            ],
            "fits": None
            if result.localisation is None
            else [
                ([str(x) for x in e.ambiguity_group], list(e.group_mass_flows))
                for e in result.localisation.leaks
            ],
        }
    return kind, truth, out


def _score(
    tallies: dict[str, Tally], kind: str, truth: list[dict[str, Any]], out: dict[str, Any]
) -> None:
    for name, res in out.items():
        t = tallies[name]
        fits = res["fits"] or []
        t.diagnosis_seconds.append(res["seconds"])
        if kind == "free":
            t.free_runs += 1
            t.free_flagged += int(res["detected"])
            t.cycle_free += res["cycles"]
            t.cycle_free_flagged += res["cycles_flagged"]
            continue
        t.cycle_leak += res["cycles"]
        t.cycle_leak_flagged += res["cycles_flagged"]
        if kind == "single":
            loc = truth[0]["location"]
            t.leak_runs += 1
            t.detected += int(res["detected"])
            hit = [(g, f) for g, f in fits if loc in g]
            ok = bool(res["detected"] and hit)
            t.inside += int(ok)
            t.by_location.setdefault(loc, []).append(ok)
            t.single_with_alternatives += int(bool(res["alternatives"]))
            t.single_extra_leak += int(len(fits) > 1)
            if hit:
                group, flows = hit[0]
                t.group_sizes.append(len(group))
                est = flows[group.index(loc)]
                t.size_errors.append(abs(est / truth[0]["mass_flow_kg_s"] - 1.0))
            elif fits:
                t.group_sizes.append(len(fits[0][0]))
        else:
            t.pairs += 1
            locs = {leak["location"] for leak in truth}
            found = [set(g) for g, _ in fits]
            both = res["detected"] and all(any(loc in g for g in found) for loc in locs)
            t.pairs_both += int(both)
            t.pair_group_sizes.extend(len(g) for g in found)
            alt = any(locs <= set(a) for a in res["alternatives"])
            t.pairs_both_alt += int(both or (res["detected"] and alt))


def _pct(a: float, b: float) -> str:
    return "n/a" if b == 0 else f"{100.0 * a / b:.2f} % ({a}/{b})"


def report(tallies: dict[str, Tally], models: dict[str, Any]) -> None:
    for name, t in tallies.items():
        print(f"\n=== sensor set: {name} ===")
        print(
            f"reference: {models[name].n_cycles} cycles; cross-validated per-cycle "
            f"false-alarm rate {100 * models[name].detector.reference_false_alarm_rate_:.2f} %"
        )
        print(f"single-leak runs detected:            {_pct(t.detected, t.leak_runs)}")
        print(f"true location inside group:           {_pct(t.inside, t.leak_runs)}")
        gs = np.mean(t.group_sizes) if t.group_sizes else float("nan")
        print(f"mean ambiguity-group size:            {gs:.3f}")
        if t.size_errors:
            e = np.asarray(t.size_errors)
            print(
                f"size error (true location): median {100 * np.median(e):.1f} %, "
                f"90th percentile {100 * np.percentile(e, 90):.1f} %"
            )
        print(f"leak-free runs flagged:               {_pct(t.free_flagged, t.free_runs)}")
        print(f"per cycle: leak cycles flagged        {_pct(t.cycle_leak_flagged, t.cycle_leak)}")
        print(f"per cycle: leak-free cycles flagged   {_pct(t.cycle_free_flagged, t.cycle_free)}")
        print(f"two simultaneous leaks, both found:   {_pct(t.pairs_both, t.pairs)}")
        print(f"  ... in groups or an alternative explanation: {_pct(t.pairs_both_alt, t.pairs)}")
        pg = np.mean(t.pair_group_sizes) if t.pair_group_sizes else float("nan")
        print(f"  mean group size on pair runs:       {pg:.3f}")
        print(
            "single-leak runs listing an alternative explanation: "
            f"{_pct(t.single_with_alternatives, t.leak_runs)}"
        )
        print(
            "single-leak runs reporting a second (spurious) leak: "
            f"{_pct(t.single_extra_leak, t.leak_runs)}"
        )
        if t.diagnosis_seconds:
            d = np.asarray(t.diagnosis_seconds)
            print(f"diagnosis time per run: mean {d.mean():.2f} s, max {d.max():.2f} s")
        worst = sorted(t.by_location.items(), key=lambda kv: np.mean(kv[1]))[:5]
        print(
            "lowest location accuracy: "
            + ", ".join(f"{loc} {100 * np.mean(v):.0f} %" for loc, v in worst)
        )
        target = TARGETS.get(name)
        if target is not None:
            checks = {
                "detection >= 99 %": t.leak_runs and t.detected / t.leak_runs >= 0.99,
                "inside group >= 98 %": t.leak_runs and t.inside / t.leak_runs >= 0.98,
                "median size error <= 10 %": bool(t.size_errors)
                and np.median(t.size_errors) <= 0.10,
                "leak-free flagged <= 0.5 %": t.free_runs and t.free_flagged / t.free_runs <= 0.005,
                f"mean group <= {target['group']}": bool(t.group_sizes) and gs <= target["group"],
                "two leaks both found >= 95 %": t.pairs and t.pairs_both / t.pairs >= 0.95,
            }
            print(
                "targets: "
                + "; ".join(f"{k}: {'PASS' if v else 'FAIL'}" for k, v in checks.items())
            )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=1, help="runs per location and size")
    parser.add_argument("--turns", default="1,2,3,4,5,6")
    parser.add_argument("--leak-free-runs", type=int, default=200)
    parser.add_argument("--pairs", type=int, default=60)
    parser.add_argument("--reference-cycles", type=int, default=40)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--out", default="build/campaign")
    parser.add_argument("--seed-offset", type=int, default=SEED_OFFSET)
    args = parser.parse_args(argv)
    offset = args.seed_offset

    from pneufdd.diagnosis.pipeline import build_reference_from_recordings
    from pneufdd.diagnosis.pnref import save_reference
    from pneufdd.diagnosis.twin_effects import candidate_locations
    from pneufdd.sim import load_machine, simulate

    start = time.perf_counter()
    os.makedirs(args.out, exist_ok=True)
    half = args.reference_cycles // 2
    refs = [simulate("festo-dsd", cycles=half + 2, seed=offset + k) for k in (1, 2)]
    paths: dict[str, str] = {}
    models: dict[str, Any] = {}
    for name, channels in SENSOR_SETS.items():
        t0 = time.perf_counter()
        model = build_reference_from_recordings(refs, channels=channels)
        path = os.path.join(args.out, f"ref-{len(paths)}.pnref")
        save_reference(model, path, overwrite=True)
        paths[name], models[name] = path, model
        print(
            f"reference {name!r}: {model.n_cycles} cycles, {len(model.feature_names)} "
            f"features, built in {time.perf_counter() - t0:.1f} s",
            flush=True,
        )
    locations = [str(x) for x in candidate_locations(load_machine("festo-dsd"))]
    turns = [float(x) for x in args.turns.split(",")]
    rng = np.random.default_rng(offset)
    seed = offset + 1000
    jobs: list[tuple[str, dict[str, float], int]] = []
    for loc, turn, _ in itertools.product(locations, turns, range(args.reps)):
        seed += 1
        jobs.append(("single", {loc: turn}, seed))
    for _ in range(args.leak_free_runs):
        seed += 1
        jobs.append(("free", {}, seed))
    for _ in range(args.pairs):
        seed += 1
        a, b = rng.choice(len(locations), size=2, replace=False)
        jobs.append(
            (
                "pair",
                {locations[a]: float(rng.choice(turns)), locations[b]: float(rng.choice(turns))},
                seed,
            )
        )
    tallies = {name: Tally() for name in SENSOR_SETS}
    print(f"{len(jobs)} runs of {RUN_CYCLES} cycles on {args.workers} worker(s)", flush=True)
    done = 0
    stalled: list[list[dict[str, Any]]] = []
    with ProcessPoolExecutor(args.workers, initializer=_init, initargs=(paths,)) as pool:
        for kind, truth, out in pool.map(_job, jobs, chunksize=2):
            if kind == "stalled":
                stalled.append(truth)
                continue
            _score(tallies, kind, truth, out)
            done += 1
            if done % 25 == 0:
                print(f"  {done}/{len(jobs)} runs, {time.perf_counter() - start:.0f} s", flush=True)
    report(tallies, models)
    print(f"\nruns not judged because the machine stalled (leaks too large to run): {len(stalled)}")
    for leaks in stalled:
        print("  ", leaks)
    print(f"\ncampaign wall time {time.perf_counter() - start:.0f} s; seeds from {offset}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
