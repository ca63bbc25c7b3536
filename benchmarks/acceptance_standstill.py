"""Issue 35 acceptance: the standstill leak test on plants at scale 2 of every machine.

Not a benchmark (``run.py`` skips it). For each built-in machine and plant: the plan
comes from the description as written (``plan_standstill``), the plant is drawn at
scale 2 (``vary_machine``: the plant is the truth), the test is run on the plant
(``simulate_standstill``: recordings as a DAQ exports them) and analysed
(``measure_states``, ``estimate_leaks``), in the flow mode (supply flow meter) and the
decay mode (supply pressure, shut-off valve closed). Per plant and mode: one 60 SLPM
leak at every location in turn, pairs of leaks the plan says it separates (60 + 40
SLPM, at most ``--pairs`` of them, drawn with the plant's seed) and a leak-free test.

    python benchmarks/acceptance_standstill.py [--seed S] [--plants N] [--pairs P]
        [--machines a,b] [--modes flow,decay]

Seeds: plant ``S + 1000 k + 100 j`` (machine k, plant j), its runs following. Prints
one JSON line per test and a summary per machine and mode: single leaks found at
their line, sizes within 10 % (flow) or 20 % (decay), pairs separated, leak-free
tests flagged.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from pneufdd.sim import builtin_machines, load_machine, vary_machine
from pneufdd.standstill import plan_standstill
from pneufdd.standstill.analyse import measure_states
from pneufdd.standstill.estimate import estimate_leaks
from pneufdd.standstill.twin import simulate_standstill

TOLERANCE = {"flow": 0.10, "decay": 0.20}


def _run(plant, plan, leaks, seed):  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    recs = simulate_standstill(plant, plan, leaks, seed=seed)
    result = estimate_leaks(plan, measure_states(recs, plan))
    return result, time.perf_counter() - t0


def _plant(name: str, seed: int, args: argparse.Namespace) -> list[dict[str, object]]:
    twin = load_machine(name)
    plant = vary_machine(twin, scale=2.0, seed=seed)
    rows: list[dict[str, object]] = []
    for mode in args.modes.split(","):
        plan = plan_standstill(twin, mode=mode)
        run_seed = seed + (1 if mode == "flow" else 50)
        for k, location in enumerate(plan.locations):
            result, wall = _run(plant, plan, {location: "60slpm"}, run_seed + k)
            top = result.leaks[0] if result.leaks else None
            rows.append(
                {"machine": name, "plant": seed, "mode": mode, "kind": "single",
                 "true": [location], "found": [(x.location, round(x.flow_slpm, 2),
                 round(x.std_slpm, 2)) for x in result.leaks],
                 "alternatives": [list(a) for a in top.alternatives] if top else [],
                 "line_found": bool(top and top.location == location and len(result.leaks) == 1),
                 "size_error": (top.flow_slpm / 60.0 - 1.0) if top and top.location == location
                 else None, "wall_s": round(wall, 2)}
            )  # fmt: skip
        rng = np.random.default_rng(seed)
        pairs = list(plan.pairs_separable)
        picked = rng.choice(len(pairs), size=min(args.pairs, len(pairs)), replace=False)
        for j, index in enumerate(sorted(picked)):
            first, second = pairs[index]
            leaks = {first: "60slpm", second: "40slpm"}
            result, wall = _run(plant, plan, leaks, run_seed + 100 + j)
            found = {x.location: x.flow_slpm for x in result.leaks}
            errors = [found[a] / s - 1.0 for a, s in ((first, 60.0), (second, 40.0)) if a in found]
            rows.append(
                {"machine": name, "plant": seed, "mode": mode, "kind": "pair",
                 "true": [first, second], "found": sorted(found.items()),
                 "separated": set(found) == {first, second},
                 "size_errors": [round(e, 4) for e in errors], "wall_s": round(wall, 2)}
            )  # fmt: skip
        result, wall = _run(plant, plan, {}, run_seed + 99)
        rows.append(
            {"machine": name, "plant": seed, "mode": mode, "kind": "free",
             "found": [(x.location, round(x.flow_slpm, 2)) for x in result.leaks],
             "flagged": result.leak_found, "wall_s": round(wall, 2)}
        )  # fmt: skip
    return rows


def _summary(rows: list[dict[str, object]]) -> dict[str, object]:
    single = [r for r in rows if r["kind"] == "single"]
    mode = str(rows[0]["mode"])
    errors = [abs(float(str(r["size_error"]))) for r in single if r["size_error"] is not None]
    pairs = [r for r in rows if r["kind"] == "pair"]
    pair_errors = [abs(e) for r in pairs for e in r["size_errors"]]  # type: ignore[attr-defined]
    free = [r for r in rows if r["kind"] == "free"]
    return {
        "machine": rows[0]["machine"],
        "mode": mode,
        "single_runs": len(single),
        "line_found": sum(bool(r["line_found"]) for r in single) / len(single),
        "size_within_tolerance": sum(e <= TOLERANCE[mode] for e in errors) / len(single),
        "size_error_median": float(np.median(errors)) if errors else None,
        "size_error_max": float(np.max(errors)) if errors else None,
        "pairs": len(pairs),
        "pairs_separated": sum(bool(r["separated"]) for r in pairs),
        "pair_size_error_max": float(np.max(pair_errors)) if pair_errors else None,
        "leak_free_flagged": sum(bool(r["flagged"]) for r in free),
        "leak_free_runs": len(free),
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seed", type=int, default=810_000_000)
    parser.add_argument("--plants", type=int, default=3)
    parser.add_argument("--pairs", type=int, default=8)
    parser.add_argument("--machines", default=",".join(builtin_machines()))
    parser.add_argument("--modes", default="flow,decay")
    args = parser.parse_args()
    for k, name in enumerate(args.machines.split(",")):
        rows: list[dict[str, object]] = []
        for j in range(args.plants):
            for row in _plant(name, args.seed + 1000 * k + 100 * j, args):
                print(json.dumps(row), flush=True)
                rows.append(row)
        for mode in args.modes.split(","):
            print(json.dumps(_summary([r for r in rows if r["mode"] == mode])), flush=True)


if __name__ == "__main__":
    main()
