"""Issue 10 acceptance: calibration on plants varied at scale 2 from each built-in machine.

Not a benchmark (``run.py`` skips it). For each built-in machine and plant seed: draw the
plant (``vary_machine``, scale 2), record two leak-free runs of it as a DAQ would export
them, calibrate the *unvaried* description to them, and print the median over steps of
the per-step supply-air error [%] and step-duration error [ms] of the twin against the
recordings, before and after, plus the twin runs and wall time.

    python benchmarks/acceptance_calibration.py [--plants N] [--seed S] [--cycles C]

Seeds: plant ``S + 100 k``, its recordings ``S + 100 k + 1``, ``+ 2`` (S >= 96,000,000
for acceptance numbers: never used while developing).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pneufdd.calibration.calibrate import calibrate_machine
from pneufdd.sim import as_exported, builtin_machines, load_machine, simulate, vary_machine


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--plants", type=int, default=1)
    parser.add_argument("--seed", type=int, default=96_100_000)
    parser.add_argument("--cycles", type=int, default=5)
    parser.add_argument("--machines", default=",".join(builtin_machines()))
    args = parser.parse_args()
    rows = []
    for name in args.machines.split(","):
        for k in range(args.plants):
            seed = args.seed + 100 * k
            plant = vary_machine(load_machine(name), scale=2.0, seed=seed)
            recs = [as_exported(simulate(plant, cycles=args.cycles, seed=seed + j)) for j in (1, 2)]
            t0 = time.perf_counter()
            result = calibrate_machine(name, recs)
            wall = time.perf_counter() - t0
            f = result.fit_summary()
            row = (
                name,
                seed,
                f["air_error_pct_median_before"],
                f["air_error_pct_median_after"],
                f["duration_error_ms_median_before"],
                f["duration_error_ms_median_after"],
                f["supply_pressure_error_mbar_median_after"],
                result.evaluations,
                wall,
                len(result.not_informed),
                len(result.estimates),
            )
            rows.append(row)
            print(
                "{} seed {}: air median {:.3f} % -> {:.3f} %, durations median {:.3f} ms -> "
                "{:.3f} ms, P_In {:.2f} mbar after; {} twin runs, {:.1f} s; {} of {} "
                "parameters not informed".format(*row),
                flush=True,
            )
    air = np.array([r[3] for r in rows])
    dur = np.array([r[5] for r in rows])
    print(
        f"all: air after <= 5 %: {int(np.sum(air <= 5.0))}/{air.size}; "
        f"durations after <= 10 ms: {int(np.sum(dur <= 10.0))}/{dur.size}"
    )


if __name__ == "__main__":
    main()
