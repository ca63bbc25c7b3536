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
        [--signature-sizes 3,8,...] [--every-location] [--quick]

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


def _one(
    machine: str, seed: int, out: Path, ladder: str | None, every: bool, quick: bool
) -> list[dict[str, object]]:
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
    ref = out / "ref.pnref"
    began = time.perf_counter()
    steps = [
        ["import", csvs[0], "--map", str(tags), "--out", str(imported), "--overwrite"],
        ["machine", "draft", str(imported), "--out", str(draft), "--name", "plant", "--overwrite"],
        ["reference", "build", *csvs, "--map", str(tags), "--machine", str(draft),
         "--calibrate", "--out", str(ref), "--overwrite",
         *(["--uncertainty-plants", "1", "--signature-cycles", "1"] if quick else []),
         *(["--signature-sizes", ladder] if ladder else [])],
    ]  # fmt: skip
    for args in steps:
        code = main(args)
        if code != 0:
            return [{"machine": machine, "failed": args[0], "exit": code}]
    built = time.perf_counter() - began
    rows: list[dict[str, object]] = []
    where = [str(x) for x in locations_of(plant.actuator_ids)] if every else LEAKS[machine]
    for j, location in enumerate(where):
        run = out / f"run-{location}.csv"
        leaky = simulate(plant, cycles=10, leaks={location: "60slpm"}, seed=seed + 10 + j)
        write_plc_csv(leaky, run, tags, overwrite=True)
        result = out / f"d-{location}.json"
        code = main(
            ["diagnose", str(run), "--map", str(tags), "--reference", str(ref),
             "--json", str(result), "--overwrite"]
        )  # fmt: skip
        found = json.loads(result.read_text()).get("leaks", []) if result.exists() else []
        rows.append(
            {
                "machine": machine,
                "true": location,
                "exit": code,
                "found": [
                    (leak["location"], leak["ambiguity_group"], round(leak["flow_slpm"], 1))
                    for leak in found
                ],
                "in_group": any(location in leak["ambiguity_group"] for leak in found),
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
        )
    return rows


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
    args = parser.parse_args()
    for machine in args.machines.split(","):
        seed = args.seed + 1000 * list(LEAKS).index(machine)
        rows = _one(
            machine, seed, args.out / machine, args.signature_sizes, args.every_location, args.quick
        )
        for row in rows:
            print(json.dumps(row), flush=True)
        judged = [r for r in rows if "in_group" in r]
        errors = [float(str(r["size_error"])) for r in judged if r["size_error"] is not None]
        if judged:
            print(
                json.dumps(
                    {
                        "machine": machine,
                        "runs": len(judged),
                        "in_group": sum(bool(r["in_group"]) for r in judged) / len(judged),
                        "size_error_median": float(np.median(errors)) if errors else None,
                        "size_error_p90": float(np.percentile(errors, 90)) if errors else None,
                    }
                ),
                flush=True,
            )


if __name__ == "__main__":
    main()
