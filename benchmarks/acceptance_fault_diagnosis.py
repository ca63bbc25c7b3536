"""Issue 34 item 3 acceptance (first cut): does the diagnosis name what is wrong?

Not a benchmark (``run.py`` skips it). Per built-in machine: one plant drawn at scale 1
around the description (the plant is the truth), its reference built from two
leak-free 12-cycle recordings exported as a DAQ would (``as_exported``) with the
description as written and the default reference settings (signatures, 12 plausible
plants). Then 12-cycle runs of the plant: ``--runs`` per fault kind tested (a random
place among the hypotheses the description allows, a size drawn between the
catalogue's two sizes), ``--runs`` single leaks (30-150 SLPM at a random location),
``--runs`` leak-free runs and four nuisance-only runs (ambient 28 and 14 degC against
the reference's 20, +2 kg payload on a random actuator, header dips of 0.5 bar, 2 s,
60/h). Every run is diagnosed with the full sensor set, one thread; leak runs also
without the fault check (``faults=False``) for the time before/after (each twice,
alternating, the faster kept).

    python benchmarks/acceptance_fault_diagnosis.py --seed S [--runs N] [--machines a,b]
        [--sets full,supply-only]

Each run is judged with each sensor set's reference (built from the same recordings,
the full set's signatures selected per set, as ``campaign --sensor-sets`` does).

Seeds: plant ``S + 100,000 k`` (machine k), its reference recordings ``+1``, ``+2``,
run ``i`` ``+1,000 + i``. Prints one JSON line per run, then a summary per machine:
type in group, component (actuator, switch or supply) in group, leaks reported for
non-leak faults, leak-free runs flagged, nuisance runs flagged, diagnosis times.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict

import numpy as np

from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.isolability import component
from pneufdd.diagnosis.localisation.faults import HYPOTHESES, fault_hypotheses
from pneufdd.diagnosis.recordings import build_reference_from_recordings, run_table
from pneufdd.diagnosis.reference.sensor_sets import machine_sensor_sets
from pneufdd.sim import MachineStalledError, as_exported, load_machine, simulate, vary_machine
from pneufdd.sim.faults import FAULT_KINDS
from pneufdd.sim.nuisances import HeaderDips, Nuisances, PayloadChange, parse_temperature_profile


def _cases(machine, rng, runs):  # type: ignore[no-untyped-def]
    hyps = fault_hypotheses(machine)
    cases = []
    for kind in HYPOTHESES:
        places = [h for h in hyps if h.kind == kind]
        for _ in range(runs):
            h = places[int(rng.integers(len(places)))]
            low, high = sorted(abs(v) for v in FAULT_KINDS[kind].sizes)
            size = round(float(rng.uniform(low, high)), 2)
            truth = {"type": h.family, "kind": kind, "location": h.location}
            cases.append(("fault", truth, {"faults": [h.fault(size)]}, size))
    lines = list(machine.leak_locations)
    for _ in range(runs):
        loc = lines[int(rng.integers(len(lines)))]
        size = round(float(rng.uniform(30.0, 150.0)), 1)
        cases.append(("leak", {"type": "leak", "kind": "leak", "location": loc},
                      {"leaks": {loc: f"{size}slpm"}}, size))  # fmt: skip
    for _ in range(runs):
        cases.append(("none", {"type": "none"}, {}, 0.0))
    act = machine.actuator_ids[int(rng.integers(len(machine.actuator_ids)))]
    for label, nuisances in (
        ("ambient 28C", Nuisances(ambient=parse_temperature_profile("28C"))),
        ("ambient 14C", Nuisances(ambient=parse_temperature_profile("14C"))),
        (f"payload {act} +2kg", Nuisances(payloads=(PayloadChange(act, 2.0, 0.0),))),
        ("header dips 0.5bar 2s 60/h", Nuisances(header_dips=HeaderDips(0.5e5, 2.0, 60 / 3600))),
    ):
        cases.append(("nuisance", {"type": "none", "nuisance": label},
                      {"nuisances": nuisances}, 0.0))  # fmt: skip
    return cases


def _moves(reference, result) -> float:  # type: ignore[no-untyped-def]
    """Largest relative change of a step duration or a step's mean supply flow [-]."""
    names = reference.feature_names
    mean = reference.detector.mean_
    keep = [i for i, n in enumerate(names) if n.startswith(("duration@", "Q_In.mean@"))]
    base = np.abs(mean[keep])
    floor = np.where([names[i].startswith("duration@") for i in keep], 0.05, 1e-5)
    return float(np.max(np.abs(result.observed_change[keep]) / np.maximum(base, floor)))


def _machine(name: str, seed: int, args: argparse.Namespace) -> list[dict[str, object]]:
    twin = load_machine(name)
    plant = vary_machine(twin, 1.0, seed)
    t0 = time.perf_counter()
    recs = [as_exported(simulate(plant, cycles=12, seed=seed + k)) for k in (1, 2)]
    full = build_reference_from_recordings(recs, None, ["ref1", "ref2"], machine=twin,
                                           workers=1)  # fmt: skip
    sets = machine_sensor_sets(recs[0].analog_channels, args.sets.split(","))
    references = {
        label: full if label == "full" else build_reference_from_recordings(
            recs, list(channels), ["ref1", "ref2"], machine=twin, with_signatures=False,
            workers=1).with_signatures(full.signatures)
        for label, channels in sets.items()
    }  # fmt: skip
    print(json.dumps({"machine": name, "reference_s": round(time.perf_counter() - t0, 1)}))
    rng = np.random.default_rng(seed)
    rows = []
    for i, (group, truth, options, size) in enumerate(_cases(twin, rng, args.runs)):
        try:
            rec = as_exported(simulate(plant, cycles=12, seed=seed + 1000 + i, **options))
        except MachineStalledError as error:  # the machine stops: nothing to diagnose
            row = {"machine": f"{name} all sets", "group": "stalled", "truth": truth, "size": size,
                   "error": str(error)[:120]}  # fmt: skip
            print(json.dumps(row), flush=True)
            rows.append(row)
            continue
        for label, reference in references.items():
            row = _judge(name, label, reference, rec, group, truth, size)
            print(json.dumps(row), flush=True)
            rows.append(row)
    return rows


def _judge(name, label, reference, rec, group, truth, size):  # type: ignore[no-untyped-def]
    """Diagnose one run with one sensor set's reference: the row of the run."""
    table = run_table(reference, rec)
    walls: dict[bool, list[float]] = {False: [], True: []}
    order = (False, True, False, True) if group == "leak" else (True,)
    for faults in order:  # a leak run both ways, twice: the faster of each
        t1 = time.perf_counter()
        result = diagnose(reference, table, threads=1, faults=faults)
        walls[faults].append(time.perf_counter() - t1)
    wall = min(walls[True])
    before = min(walls[False]) if walls[False] else None
    first = result.findings[0] if result.findings else None
    members = first.ambiguity_group if first else ()
    types = {m.fault_type for m in members} | ({first.fault_type} if first else set())
    places = {component(m.location) for m in members}
    if first:
        places.add(component(first.location))
    return {
        "machine": f"{name} {label}", "group": group, "truth": truth, "size": size,
        "moves": round(_moves(reference, result), 4), "detected": result.detected,
        "findings": [f.describe() for f in result.findings],
        "first_type": None if first is None else first.fault_type,
        "type_in_group": bool(first and truth["type"] in types),
        "component_in_group": bool(
            first and "location" in truth and component(str(truth["location"])) in places
        ),
        "leak_reported": bool(result.leaks),
        "leak_claimed": any(f.claims_leak for f in result.findings),
        "faults_tested": result.faults_tested,
        "confidence": None if first is None else round(first.confidence, 3),
        "wall_s": round(wall, 3), "wall_without_faults_s": None if before is None
        else round(before, 3),
    }  # fmt: skip


def _summary(rows: list[dict[str, object]]) -> None:
    by: dict[str, list[dict[str, object]]] = defaultdict(list)
    for row in rows:
        by[str(row["machine"])].append(row)
    for name, mine in by.items():
        faults = [r for r in mine if r["group"] == "fault"]
        big = [r for r in faults if float(r["moves"]) >= 0.10]  # type: ignore[arg-type]
        leaks = [r for r in mine if r["group"] == "leak"]
        none = [r for r in mine if r["group"] == "none"]
        nuis = [r for r in mine if r["group"] == "nuisance"]

        def share(items: list[dict[str, object]], key: str) -> str:
            return f"{sum(bool(r[key]) for r in items)}/{len(items)}"

        stalled = [r for r in mine if r["group"] == "stalled"]
        print(f"## {name}")
        print(
            f"fault runs whose machine stopped (not diagnosed): {len(stalled)} "
            f"{[r['truth']['kind'] for r in stalled]}"
        )  # type: ignore[index]
        print(f"fault runs: {len(faults)}; moving a step >= 10 %: {len(big)}")
        fs, bs = share, share
        print(
            f"  detected {fs(faults, 'detected')}; type in group {fs(faults, 'type_in_group')}"
            f" (>= 10 %: {bs(big, 'type_in_group')}); component in group "
            f"{fs(faults, 'component_in_group')} (>= 10 %: {bs(big, 'component_in_group')});"
            f" leak reported (costed) {fs(faults, 'leak_reported')}, claimed (no other type"
            f" in its group) {fs(faults, 'leak_claimed')}"
        )
        kinds: dict[str, list[dict[str, object]]] = defaultdict(list)
        for r in faults:
            kinds[str(r["truth"]["kind"])].append(r)  # type: ignore[index]
        for kind, items in kinds.items():
            print(
                f"  {kind}: detected {share(items, 'detected')}, "
                f"type {share(items, 'type_in_group')}, "
                f"component {share(items, 'component_in_group')}, "
                f"leak reported {share(items, 'leak_reported')}, "
                f"claimed {share(items, 'leak_claimed')}"
            )
        print(
            f"leak runs: type leak in group {share(leaks, 'type_in_group')}, component "
            f"{share(leaks, 'component_in_group')}"
        )
        flagged_none = sum(bool(r["findings"]) for r in none)
        print(
            f"leak-free flagged (a finding): {flagged_none}/{len(none)}; "
            f"detected {share(none, 'detected')}"
        )
        flagged_nuis = sum(bool(r["findings"]) for r in nuis)
        print(
            f"nuisance-only flagged (a finding): {flagged_nuis}/{len(nuis)}; "
            f"detected {share(nuis, 'detected')}"
        )
        tested = sum(bool(r["faults_tested"]) for r in leaks)
        print(f"leak runs whose fault check ran: {tested}/{len(leaks)}")
        if leaks:
            before = [float(r["wall_without_faults_s"]) for r in leaks]  # type: ignore[arg-type]
            after = [float(r["wall_s"]) for r in leaks]  # type: ignore[arg-type]
            print(f"leak-run diagnosis time, median/max: without fault check "
                  f"{np.median(before):.2f}/{max(before):.2f} s, with {np.median(after):.2f}/"
                  f"{max(after):.2f} s")  # fmt: skip
        times = [float(r["wall_s"]) for r in faults]  # type: ignore[arg-type]
        print(f"fault-run diagnosis time, median/max: {np.median(times):.2f}/{max(times):.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--machines", default="press-fit-cell,festo-dsd")
    parser.add_argument("--sets", default="full", help="sensor sets, e.g. full,supply-only")
    args = parser.parse_args()
    rows: list[dict[str, object]] = []
    for k, name in enumerate(args.machines.split(",")):
        rows += _machine(name, args.seed + 100_000 * k, args)
    _summary(rows)


if __name__ == "__main__":
    main()
