"""``make bench`` for scale-out (issue 13): a tiny campaign on Dask against the serial path.

The same campaign (press-fit-cell, one plant at scale 1, every location at one size,
leak-free runs and pairs, both sensor sets) runs in this process (``workers=1``) and
on a ``LocalCluster`` of 2 worker processes (the machine's 2 cores); the figure is
campaign runs per second on the cluster against the serial path, with the check that
both give the same figures. The campaign's diagnosis time per run (median / max, the
simulation check included) is printed from its records.
"""

from __future__ import annotations

import json
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from common import BenchResult

SEED_OFFSET = 9_400_000  # a benchmark's seeds (below the development and campaign ranges)


def _design() -> Any:
    from pneufdd.evaluation import CampaignDesign

    return CampaignDesign(
        machines=("press-fit-cell",),
        plants=1,
        leak_sizes=("60slpm",),
        leak_free_runs=4,
        pairs=4,
        run_cycles=4,
        reference_cycles=14,
        reference_recordings=2,
        uncertainty_plants=1,
        seed_offset=SEED_OFFSET,
    )


def _accuracy(result: Any) -> dict[Any, Any]:
    return {
        key: {k: v for k, v in t.figures().items() if not k.startswith("seconds")}
        for key, t in result.tallies.items()
    }


def run() -> list[BenchResult]:
    from pneufdd.evaluation import run_campaign

    design = _design()
    with tempfile.TemporaryDirectory() as tmp:
        run_campaign(design, Path(tmp) / "warm-up", workers=1)  # numba cache, imports
        start = time.perf_counter()
        serial = run_campaign(design, Path(tmp) / "serial", workers=1)
        serial_s = time.perf_counter() - start
        start = time.perf_counter()
        cluster = run_campaign(design, Path(tmp) / "dask", workers=2)
        cluster_s = time.perf_counter() - start
        records = [
            json.loads(line)
            for line in (Path(tmp) / "serial" / "runs.jsonl").read_text().splitlines()
        ]
    runs = len({r["seed"] for r in records})
    seconds = [r["seconds"] for r in records if "seconds" in r]
    same = _accuracy(serial) == _accuracy(cluster)
    print(
        f"tiny campaign ({runs} runs x 2 sensor sets): serial {serial_s:.1f} s, "
        f"2-worker LocalCluster {cluster_s:.1f} s (cluster start-up included); "
        f"same figures: {same}",
        flush=True,
    )
    print(
        f"diagnosis time per run (serial path): median {statistics.median(seconds):.3f} s, "
        f"max {max(seconds):.3f} s, "
        f"{sum(r.get('simulated', False) for r in records)} of {len(seconds)} "
        "checked by simulation",
        flush=True,
    )
    return [
        BenchResult(
            "tiny campaign on a 2-worker Dask LocalCluster",
            runs / cluster_s,
            "runs/s",
            "the same campaign in one process",
            runs / serial_s,
        )
    ]


if __name__ == "__main__":
    for r in run():
        print(r.line())
