"""Issue 35 item 2 acceptance: sizing before and after commissioning with a test leak.

Not a benchmark (``run.py`` skips it). For each machine: a plant varied at scale 2
(seed ``S + 1000 k``), two leak-free recordings of 12 cycles, a reference built with the
machine's NOMINAL description (the built-in one, not the plant's) with the defaults of
``reference build``; the commissioning plan (every location, the test orifice, 20
cycles) run on the plant (one recording per port), then ``commission``; then a single
leak of each size at each port (10 cycles) diagnosed by both references. Prints per
machine the located share and the size error median and p90 before and after, and
writes every run's record to OUT/commissioning.json.

With ``--second-orifice 1.5mm`` the plant is also recorded with the second, larger
orifice at every port and a third reference is commissioned with both sizes (the
two-size plan, gains interpolated in size); every leak run is diagnosed by all three
(labels ``before``, ``after`` (one size) and ``two``).

    nice -n 10 python benchmarks/acceptance_commissioning.py OUT --seed 875000000 \\
        [--machines press-fit-cell,festo-dsd] [--sizes 20,45,90] [--orifice 1.0mm] \\
        [--second-orifice 1.5mm]

The commands a user runs are ``reference build``, ``commission plan``, ``commission
apply`` and ``diagnose``; this script calls the library functions behind them (the
same code) to keep one process's caches.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np


def _size_at(result: Any, port: str) -> float:
    from pneufdd.diagnosis.commissioning import _size_at

    return _size_at(result, port)[0]


def _machine(name: str, seed: int, args: argparse.Namespace) -> list[dict[str, Any]]:
    from pneufdd.diagnosis.commission_plan import plan_commissioning
    from pneufdd.diagnosis.engine import diagnose
    from pneufdd.diagnosis.recordings import build_reference_from_recordings, run_table
    from pneufdd.errors import PneufddError
    from pneufdd.physics.leaks import leak_mass_flow
    from pneufdd.physics.units import psig_to_pa
    from pneufdd.sim import MachineStalledError, load_machine, simulate, vary_machine

    nominal = load_machine(name)
    plant = vary_machine(nominal, scale=2.0, seed=seed)
    t0 = time.perf_counter()
    free = [simulate(plant, cycles=12, seed=seed + k) for k in (1, 2)]
    reference = build_reference_from_recordings(
        free, None, ["free1", "free2"], machine=nominal, workers=1
    )
    print(f"{name}: reference built in {time.perf_counter() - t0:.0f} s", flush=True)
    plan = plan_commissioning(reference, None, args.orifice, 20)
    runs = {}
    for j, port in enumerate(plan.ports):
        try:
            runs[port] = (f"{port}.test", simulate(plant, 22, {port: args.orifice}, seed + 100 + j))
        except MachineStalledError:
            print(f"{name}: {port} stalls with the test orifice: not commissioned", flush=True)
    one = _commissioned(name, reference, plan, runs)
    models = {"before": reference, "after": one.reference}
    if args.second_orifice:
        plan2 = plan_commissioning(reference, None, args.orifice, 20, args.second_orifice)
        runs2 = dict(runs)
        for j, port in enumerate(plan.ports):
            try:
                rec = simulate(plant, 22, {port: args.second_orifice}, seed + 200 + j)
                runs2[port + "@2"] = (f"{port}@2.test", rec)
            except MachineStalledError:
                print(f"{name}: {port} stalls with the second orifice", flush=True)
        models["two"] = _commissioned(name, reference, plan2, runs2).reference
    done_status = {p.port: p.status for p in one.ports}
    p_nom = float(psig_to_pa(nominal.nominal_supply_psig))
    rows: list[dict[str, Any]] = []
    for j, port in enumerate(plan.ports):
        for i, size in enumerate(args.sizes):
            run_seed = seed + 300 + 10 * j + i
            try:
                rec = simulate(plant, 12, {port: f"{size}slpm"}, run_seed)
            except MachineStalledError:
                rows.append({"machine": name, "port": port, "slpm": size, "stalled": True})
                continue
            area = float(rec.metadata["leaks"][0]["effective_area_m2"])
            truth = float(leak_mass_flow(p_nom, area))
            row: dict[str, Any] = {
                "machine": name,
                "port": port,
                "slpm": size,
                "seed": run_seed,
                "commissioned": done_status[port],
            }
            for label, model in models.items():
                try:
                    result = diagnose(model, run_table(model, rec, "run"), threads=1)
                except PneufddError as exc:
                    row[label] = {"error": str(exc)}
                    continue
                est = _size_at(result, port)
                row[label] = {
                    "detected": result.detected,
                    "found": [str(leak.location) for leak in result.leaks],
                    "size_error": None if est != est else abs(est - truth) / truth,
                }
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows


def _commissioned(name: str, reference: Any, plan: Any, runs: dict[str, Any]) -> Any:
    """``commission`` (the code of ``commission apply``) with its per-port lines printed."""
    from pneufdd.diagnosis.commissioning import commission

    t0 = time.perf_counter()
    done = commission(reference, plan, runs)
    print(f"{name}: commissioned in {time.perf_counter() - t0:.0f} s", flush=True)
    for p in done.ports:
        gain = "-" if p.fit is None else f"{p.fit.overall_gain:.3f}"
        print(f"  {p.port:10s} {p.orifice:7s} {p.status:12s} gain {gain} {p.reason}", flush=True)
    return done


def _summary(rows: list[dict[str, Any]]) -> None:
    for name in sorted({r["machine"] for r in rows}):
        mine = [r for r in rows if r["machine"] == name and not r.get("stalled")]
        for label in ("before", "after", "two"):
            if not any(label in r for r in mine):
                continue
            errors = [
                r[label]["size_error"] for r in mine if r[label].get("size_error") is not None
            ]
            located = len(errors)
            e = np.array(errors) * 100
            print(
                f"{name} {label}: at port or in group {located}/{len(mine)}, size error "
                f"median {np.median(e):.1f} %, p90 {np.percentile(e, 90):.1f} %"
                if errors
                else f"{name} {label}: nothing located",
                flush=True,
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out", type=Path)
    parser.add_argument("--seed", type=int, default=875_000_000)
    parser.add_argument("--machines", default="press-fit-cell,festo-dsd")
    parser.add_argument("--sizes", default="20,45,90")
    parser.add_argument("--orifice", default="1.0mm")
    parser.add_argument("--second-orifice", default="", help="e.g. 1.5mm: also the two-size plan")
    args = parser.parse_args()
    args.sizes = [float(x) for x in args.sizes.split(",")]
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    for k, name in enumerate(args.machines.split(",")):
        rows += _machine(name, args.seed + 1000 * k, args)
        (args.out / "commissioning.json").write_text(json.dumps(rows, indent=1))
    _summary(rows)


if __name__ == "__main__":
    main()
