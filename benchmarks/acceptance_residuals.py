"""Issue 12 acceptance: the physics-residual detector on plants, with a calibrated twin.

Not a benchmark (``run.py`` skips it). For each plant (festo-dsd varied at scale 1):

1. four leak-free recordings of 25 cycles (what a user records for a reference);
2. the description calibrated to them (:func:`calibrate_machine`, twin in the loop);
3. :class:`ResidualDetector` (1 % design false-alarm rate) fitted on the residuals of
   those recordings against the calibrated twin's replay (eq. 4.1, per step);
4. judged on new runs (every complete cycle of 12-cycle runs): leak-free cycles
   flagged, and cycles of a 2-turn ``DNC_A`` leak flagged (with the eq. 4.21
   consistency check).

The same is printed with the twin as written (uncalibrated), for comparison.

    python benchmarks/acceptance_residuals.py [--plants N] [--seed S] [--free-runs R]
        [--leak-runs L] [--workers W]

Seeds: plant ``S + 10,000 k``; its recordings and runs follow it (S >= 275,000,000 for
acceptance numbers: never used while developing).
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

CYCLES = 10  # judged cycles per test run


def _plant(job: tuple[int, int, int]) -> dict[str, Any]:
    from pneufdd.calibration.calibrate import calibrate_machine
    from pneufdd.diagnosis.detection.residuals import ResidualDetector, TwinReplay
    from pneufdd.sim import as_exported, load_machine, simulate, vary_machine

    seed, free_runs, leak_runs = job
    began = time.perf_counter()
    machine = load_machine("festo-dsd")
    plant = vary_machine(machine, 1.0, seed)
    references = [as_exported(simulate(plant, cycles=27, seed=seed + 1 + j)) for j in range(4)]
    calibrated = calibrate_machine(machine, references, seed=0).calibrated_description(
        f"plant seed {seed}"
    )
    free = [
        as_exported(simulate(plant, cycles=CYCLES + 2, seed=seed + 100 + j))
        for j in range(free_runs)
    ]
    leaky = [
        as_exported(simulate(plant, cycles=CYCLES + 2, leaks={"DNC_A": "2"}, seed=seed + 200 + j))
        for j in range(leak_runs)
    ]
    out: dict[str, Any] = {"seed": seed}
    for label, twin in (("calibrated", calibrated), ("as written", machine)):
        replay = TwinReplay.of(twin, cycles=4, seed=seed + 300)
        train = np.vstack([replay.residuals(r, machine) for r in references])
        detector = ResidualDetector(false_alarm_rate=0.01).fit(train)
        on_free = np.concatenate([detector.predict(replay.residuals(r, machine)) for r in free])
        on_leak = np.concatenate([detector.predict(replay.residuals(r, machine)) for r in leaky])
        out[label] = {
            "reference_cycles": int(train.shape[0]),
            "free_flagged": int(on_free.sum()),
            "free_cycles": int(on_free.size),
            "leak_flagged": int(on_leak.sum()),
            "leak_cycles": int(on_leak.size),
        }
    out["seconds"] = time.perf_counter() - began
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--plants", type=int, default=2)
    parser.add_argument("--seed", type=int, default=275_000_000)
    parser.add_argument("--free-runs", type=int, default=20)
    parser.add_argument("--leak-runs", type=int, default=4)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [(args.seed + 10_000 * k, args.free_runs, args.leak_runs) for k in range(args.plants)]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        results = list(pool.map(_plant, jobs))
    for label in ("calibrated", "as written"):
        free = sum(r[label]["free_flagged"] for r in results)
        free_n = sum(r[label]["free_cycles"] for r in results)
        leak = sum(r[label]["leak_flagged"] for r in results)
        leak_n = sum(r[label]["leak_cycles"] for r in results)
        print(
            f"twin {label}: leak-free cycles flagged {free}/{free_n} "
            f"({100 * free / max(free_n, 1):.2f} %, target <= 1 %); 2-turn DNC_A cycles "
            f"flagged {leak}/{leak_n} ({100 * leak / max(leak_n, 1):.2f} %, target >= 95 %)"
        )
    for r in results:
        print(r)


if __name__ == "__main__":
    main()
