"""Issue 10 acceptance (small): diagnosis on scale-2 plants with and without calibration.

For each machine: one plant at scale 2, two leak-free recordings of it (``--ref-cycles``
each, as the campaign's 40 in all; as a DAQ exports them), a reference from those
recordings with the description as written and one with the description calibrated to
them (signatures from each), then single leaks of
``--size`` SLPM at every location and leak-free runs, each diagnosed with both.
Prints location-in-group rate, size error median and p90, spurious second leaks and
false alarms. The true size is the requested flow at the plant's own nominal pressure
(within a few % of the described pressure's).

    python benchmarks/acceptance_diagnosis_calibrated.py [--seed S] [--machines a,b]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pneufdd.calibration.calibrate import calibrate_machine
from pneufdd.diagnosis.recordings import build_reference_from_recordings, diagnose_recording
from pneufdd.sim import as_exported, builtin_machines, load_machine, simulate, vary_machine


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seed", type=int, default=96_200_000)
    parser.add_argument("--machines", default=",".join(builtin_machines()))
    parser.add_argument("--size", type=float, default=60.0)
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--ref-cycles", type=int, default=20)
    parser.add_argument("--free-runs", type=int, default=10)
    parser.add_argument("--channels", default="")
    args = parser.parse_args()
    for m, name in enumerate(args.machines.split(",")):
        seed = args.seed + 1000 * m
        twin = load_machine(name)
        plant = vary_machine(twin, scale=2.0, seed=seed)
        recs = [as_exported(simulate(plant, cycles=args.ref_cycles, seed=seed + j)) for j in (1, 2)]
        t0 = time.perf_counter()
        calibrated = calibrate_machine(twin, recs).calibrated_description("plant")
        t_cal = time.perf_counter() - t0
        channels = tuple(args.channels.split(",")) if args.channels else None
        models = {}
        for label, description in (("as written", twin), ("calibrated", calibrated)):
            models[label] = build_reference_from_recordings(
                recs, channels, machine=description, uncertainty_plants=2, workers=1
            )
        runs = [(loc, args.size) for loc in twin.leak_locations]
        runs += [(None, 0.0)] * args.free_runs
        stats: dict[str, dict[str, list[float]]] = {
            k: {"hit": [], "err": [], "second": [], "alarm": []} for k in models
        }
        for r, (loc, size) in enumerate(runs):
            leaks = {} if loc is None else {loc: f"{size}slpm"}
            run = as_exported(simulate(plant, cycles=args.cycles, leaks=leaks, seed=seed + 10 + r))
            for label, model in models.items():
                _, result = diagnose_recording(model, run)
                s = stats[label]
                if loc is None:
                    s["alarm"].append(float(result.detected))
                    continue
                if not result.leaks:
                    s["hit"].append(0.0)
                    continue
                first = result.leaks[0]
                group = {str(first.location), *(str(x) for x in first.ambiguity_group)}
                s["hit"].append(float(loc in group))
                s["err"].append(abs(first.flow_slpm - size) / size)
                s["second"].append(float(len(result.leaks) > 1))
        for label, s in stats.items():
            err = np.array(s["err"]) if s["err"] else np.array([np.nan])
            print(
                f"{name} plant seed {seed} ({label}; calibration {t_cal:.0f} s): located in "
                f"group {100 * np.mean(s['hit']):.1f} % of {len(s['hit'])}, size error median "
                f"{100 * np.nanmedian(err):.1f} %, p90 {100 * np.nanpercentile(err, 90):.1f} %, "
                f"second leaks {100 * np.mean(s['second'] or [0]):.1f} %, false alarms "
                f"{100 * np.mean(s['alarm'] or [0]):.1f} % of {len(s['alarm'])}",
                flush=True,
            )


if __name__ == "__main__":
    main()
