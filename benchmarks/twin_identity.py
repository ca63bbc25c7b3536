"""Hashes of the twin's output for runs without faults: to compare two versions of the twin.

Not a benchmark (``run.py`` skips it). Five runs of the three built-in machines, with
and without leaks, one with a scheduled leak; for each, a SHA-256 over every recorded
channel (times and values), every internal output (``run_simulation(...).outputs``,
except the piston-leak flows a twin without issue 34's faults does not have) and the
strokes, and one over the written Parquet file. Run it on two checkouts (e.g. main and
a branch) and compare the lines: equal hashes mean the same numbers bit for bit.

    python benchmarks/twin_identity.py
    PYTHONPATH=/path/to/other/checkout/src python benchmarks/twin_identity.py
"""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path

import numpy as np

from pneufdd.sim import run_simulation

CASES = (
    ("festo-dsd", 3, 11, {}),
    ("festo-dsd", 2, 5, {"DNC_B": 4, "supply": 2}),
    ("press-fit-cell", 3, 1, {}),
    ("carton-sorter", 3, 2, {"PUSH_L_A": "20slpm"}),
    ("press-fit-cell", 4, 3, {"schedule": "EJECT_B=3@5s"}),
)


def main() -> int:
    from pneufdd.sim.schedule import schedule_from_options

    for machine, cycles, seed, leaks in CASES:
        timed = [leaks.pop("schedule")] if "schedule" in leaks else []
        schedule = schedule_from_options(timed, [], [])
        result = run_simulation(
            machine, cycles=cycles, leaks=leaks or None, seed=seed, schedule=schedule
        )
        digest = hashlib.sha256()
        for name in result.recording.channels:
            time, values = result.recording.channel(name)
            digest.update(name.encode())
            digest.update(np.ascontiguousarray(time).tobytes())
            digest.update(np.ascontiguousarray(values).tobytes())
        for name, values in sorted(result.outputs.items()):
            if not name.startswith("mdot_piston_leak"):
                digest.update(name.encode())
                digest.update(np.ascontiguousarray(values).tobytes())
        digest.update(repr(result.strokes).encode())
        with tempfile.TemporaryDirectory() as folder:
            path = result.recording.write(Path(folder) / "run.parquet")
            parquet = hashlib.sha256(path.read_bytes()).hexdigest()
        print(
            f"{machine} cycles={cycles} seed={seed} leaks={leaks} {timed}: "
            f"run {digest.hexdigest()[:16]}, parquet {parquet[:16]}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
