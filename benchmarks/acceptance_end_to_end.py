"""Issue 10 acceptance: from a plant's PLC export to a located leak, on every built-in machine.

Not a benchmark (``run.py`` skips it). For each machine: a plant varied at scale 2, two
leak-free PLC CSV exports (tag names, bar(g), l/min ANR, no metadata) of 8 cycles,
then the user's commands::

    pneufdd import free1.csv --map tags.toml --out free1.parquet
    pneufdd machine draft free1.parquet --out draft.toml --name plant
    pneufdd reference build free1.csv free2.csv --map tags.toml --machine draft.toml \\
        --calibrate --out ref.pnref
    pneufdd diagnose run.csv --map tags.toml --reference ref.pnref --json d.json

with a 60 SLPM leak at one line location (and one supply-leak run), or with
``--every-location`` at every location of the machine, and prints where and how large
each leak was found, then per machine the share located in group and the size errors.

    python benchmarks/acceptance_end_to_end.py OUT_DIR [--seed S] [--machines a,b]
        [--signature-sizes 3,8,...] [--every-location] [--quick] [--codes]
        [--supply-only] [--leak-free N]

``--codes`` drafts with the order codes of every actuator and valve (the built-in
description's ``catalogue`` keys: what the nameplates say, issue 35); ``--supply-only``
builds a second reference on ``P_In`` and ``Q_In`` alone and diagnoses every run with
both; ``--leak-free N`` adds N leak-free runs (the share flagged). Per machine and set:
in group, size error median and p90, spurious second leaks, leak-free runs flagged.

``--quick`` builds the reference with ``--uncertainty-plants 1 --signature-cycles 1``
(the figures of stop 22 and before); without it the reference is built with the
command's defaults, as a user would.

Seeds: plant ``S + 1000 k`` (k: the machine's place in ``LEAKS``), its runs following
(S >= 290,000,000 for acceptance numbers: never used while developing).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

LEAKS = {
    "festo-dsd": ("DNC_B", "supply"),
    "press-fit-cell": ("EJECT_B", "supply"),
    "carton-sorter": ("PUSH_L_B", "supply"),
}


def _codes(machine: str) -> list[str]:
    """``--actuator ID=CODE`` and ``--valve ID=CODE`` for every actuator of a built-in
    machine, from its description's ``catalogue`` keys (its nameplates)."""
    from pneufdd.sim import load_machine

    out: list[str] = []
    for a in load_machine(machine).actuators:
        if a.catalogue:
            out += ["--actuator", f"{a.id}={a.catalogue}"]
        if a.valve.catalogue:
            out += ["--valve", f"{a.id}={a.valve.catalogue}"]
    return out


def _diagnosed(
    machine: str, location: str, result: Path, code: int, built: float, label: str
) -> dict[str, object]:
    found = json.loads(result.read_text()).get("leaks", []) if result.exists() else []
    truth = [] if location == "leak-free" else [location]
    return {
        "machine": machine,
        "set": label,
        "true": location,
        "exit": code,
        "found": [
            (leak["location"], leak["ambiguity_group"], round(leak["flow_slpm"], 1))
            for leak in found
        ],
        "in_group": any(t in leak["ambiguity_group"] for t in truth for leak in found),
        "spurious": len(found) > len(truth),
        "size_error": next(
            (
                abs(leak["flow_slpm"] / 60.0 - 1.0)  # the leak's reported flow
                for leak in found
                if location in leak["ambiguity_group"]
            ),
            None,
        ),
        "reference_build_s": round(built, 1),
    }


def _one(machine: str, seed: int, out: Path, args: argparse.Namespace) -> list[dict[str, object]]:
    from pneufdd.cli.app import main
    from pneufdd.location import locations_of
    from pneufdd.recording.plc_export import write_plc_csv
    from pneufdd.sim import load_machine, simulate, vary_machine

    out.mkdir(parents=True, exist_ok=True)
    plant = vary_machine(load_machine(machine), scale=2.0, seed=seed)
    tags = out / "tags.toml"
    csvs = []
    for k in (1, 2):
        csv = out / f"free{k}.csv"
        write_plc_csv(simulate(plant, cycles=8, seed=seed + k), csv, tags, overwrite=True)
        csvs.append(str(csv))
    imported = out / "free1.parquet"
    draft = out / "draft.toml"
    began = time.perf_counter()
    codes = _codes(machine) if args.codes else []
    code = main(["import", csvs[0], "--map", str(tags), "--out", str(imported), "--overwrite"])
    code = code or main(
        ["machine", "draft", str(imported), "--out", str(draft), "--name", "plant",
         "--overwrite", *codes]
    )  # fmt: skip
    if code != 0:
        return [{"machine": machine, "failed": "draft", "exit": code}]
    sets = (
        {"full": []}
        if not args.supply_only
        else {"full": [], "supply": ["--channels", "P_In,Q_In"]}
    )
    refs: dict[str, tuple[Path, float]] = {}
    for label, channels in sets.items():
        ref = out / f"ref-{label}.pnref"
        t0 = time.perf_counter()
        code = main(
            ["reference", "build", *csvs, "--map", str(tags), "--machine", str(draft),
             "--calibrate", "--out", str(ref), "--overwrite", *channels,
             *(["--uncertainty-plants", "1", "--signature-cycles", "1"] if args.quick else []),
             *(["--signature-sizes", args.signature_sizes] if args.signature_sizes else [])]
        )  # fmt: skip
        if code != 0:
            return [{"machine": machine, "failed": f"reference {label}", "exit": code}]
        refs[label] = (ref, time.perf_counter() - t0 + (t0 - began if label == "full" else 0.0))
    rows: list[dict[str, object]] = []
    where = (
        [str(x) for x in locations_of(plant.actuator_ids)]
        if args.every_location
        else list(LEAKS[machine])
    )
    where += ["leak-free"] * args.leak_free
    for j, location in enumerate(where):
        run = out / f"run-{j}-{location}.csv"
        leaks = {} if location == "leak-free" else {location: "60slpm"}
        leaky = simulate(plant, cycles=10, leaks=leaks, seed=seed + 10 + j)
        write_plc_csv(leaky, run, tags, overwrite=True)
        for label, (ref, built) in refs.items():
            result = out / f"d-{j}-{location}-{label}.json"
            code = main(
                ["diagnose", str(run), "--map", str(tags), "--reference", str(ref),
                 "--json", str(result), "--overwrite"]
            )  # fmt: skip
            rows.append(_diagnosed(machine, location, result, code, built, label))
    return rows


def _summary(machine: str, rows: list[dict[str, object]]) -> list[dict[str, object]]:
    out = []
    for label in sorted({str(r["set"]) for r in rows if "set" in r}):
        judged = [r for r in rows if r.get("set") == label and r["true"] != "leak-free"]
        free = [r for r in rows if r.get("set") == label and r["true"] == "leak-free"]
        errors = [float(str(r["size_error"])) for r in judged if r["size_error"] is not None]
        out.append(
            {
                "machine": machine,
                "set": label,
                "runs": len(judged),
                "in_group": sum(bool(r["in_group"]) for r in judged) / max(len(judged), 1),
                "size_error_median": float(np.median(errors)) if errors else None,
                "size_error_p90": float(np.percentile(errors, 90)) if errors else None,
                "spurious": sum(bool(r["spurious"]) for r in judged) / max(len(judged), 1),
                "leak_free_runs": len(free),
                "leak_free_flagged": sum(int(r["exit"]) == 1 for r in free),
            }
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--seed", type=int, default=290_000_000)
    parser.add_argument("--machines", default=",".join(LEAKS))
    parser.add_argument("--signature-sizes", default=None, help="passed to reference build")
    parser.add_argument("--every-location", action="store_true", help="a leak at each location")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="reference build with 1 plausible plant and 1 signature cycle (not the defaults)",
    )
    parser.add_argument(
        "--codes",
        action="store_true",
        help="draft with the order codes of the machine's parts (issue 35: its nameplates)",
    )
    parser.add_argument(
        "--supply-only", action="store_true", help="also a reference on P_In and Q_In alone"
    )
    parser.add_argument("--leak-free", type=int, default=0, help="leak-free runs diagnosed")
    args = parser.parse_args()
    for machine in args.machines.split(","):
        seed = args.seed + 1000 * list(LEAKS).index(machine)
        rows = _one(machine, seed, args.out / machine, args)
        for row in rows:
            print(json.dumps(row), flush=True)
        for summary in _summary(machine, rows):
            print(json.dumps(summary), flush=True)


if __name__ == "__main__":
    main()
