"""Shared simulated runs for the acceptance tests (cached per test process)."""

from __future__ import annotations

import copy
import functools
from typing import Any

import numpy as np

from pneufdd import Recording
from pneufdd.recording import Channel


@functools.cache
def run(cycles: int, leaks: tuple[tuple[str, float], ...] = (), seed: int = 1, both: bool = False):
    """``pneufdd.sim.run_simulation`` of festo-dsd; ``both``: bidirectional DNC meters."""
    from pneufdd.sim import load_machine, run_simulation

    machine: Any = "festo-dsd"
    if both:
        machine = copy.deepcopy(load_machine("festo-dsd").raw)
        for sensor in machine["sensor"]:
            if sensor["channel"] in ("Q_DNC_A", "Q_DNC_B"):
                sensor["direction"] = "bidirectional"
    return run_simulation(machine, cycles, dict(leaks), seed, keep_outputs=False)


def damage(
    rec: Recording, seed: int, bounce: bool, nan_fraction: float, truncate_s: float | None
) -> Recording:
    """Switch bounce (1-2 sample glitches after rising edges), NaN gaps, truncation."""
    rng = np.random.default_rng(seed)
    out = []
    for name in rec.channels:
        ch = rec.info(name)
        v = np.array(ch.values)
        if bounce and name.startswith("S_"):
            rises = np.flatnonzero(np.diff(v.astype(np.int8)) > 0) + 1
            for k in rises:
                g = int(rng.integers(1, 3))
                if k + g + 2 < v.size and np.all(v[k : k + g + 2] == 1):
                    v[k + 1 : k + 1 + g] = 0
        if nan_fraction and ch.kind == "analog":
            v = v.astype(np.float64)
            starts = rng.integers(0, v.size - 10, max(1, int(nan_fraction * v.size / 10)))
            v[(starts[:, None] + np.arange(10)).ravel()] = np.nan
        if truncate_s is not None:
            v = v[: int(truncate_s * ch.rate_hz)]
        out.append(Channel(name, v, ch.rate_hz, ch.unit, ch.kind, ch.t0))
    return Recording(out, rec.start_time, rec.metadata)
