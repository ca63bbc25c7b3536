"""Throughput of the physics flow kernels, against a plain numpy square root baseline."""

from __future__ import annotations

import numba
import numpy as np

from common import BenchResult, best_time
from pneufdd.physics import isa_mass_flow, orifice_mass_flow, orifice_mass_flow_kernel

N = 1_000_000


@numba.njit(cache=True)
def _kernel_loop(p1: np.ndarray, p2: np.ndarray) -> float:
    total = 0.0
    for i in range(p1.size):
        total += orifice_mass_flow_kernel(p1[i], p2[i], 1e-6, 0.8, 293.15)
    return total


def run() -> list[BenchResult]:
    rng = np.random.default_rng(0)
    p1 = rng.uniform(1e5, 8e5, N)
    p2 = rng.uniform(1e5, 8e5, N)
    _kernel_loop(p1[:10], p2[:10])
    orifice_mass_flow(p1[:10], p2[:10], 1e-6)
    baseline = best_time(lambda: np.sqrt(p1 * p2))
    return [
        BenchResult(
            "orifice_mass_flow, 1e6 elements",
            best_time(lambda: orifice_mass_flow(p1, p2, 1e-6)),
            "s",
            "np.sqrt(p1 * p2)",
            baseline,
        ),
        BenchResult(
            "isa_mass_flow, 1e6 elements",
            best_time(lambda: isa_mass_flow(p1, p2, 0.4, 0.7)),
            "s",
            "np.sqrt(p1 * p2)",
            baseline,
        ),
        BenchResult(
            "orifice kernel in a compiled loop, 1e6 calls",
            best_time(lambda: _kernel_loop(p1, p2)),
            "s",
            "np.sqrt(p1 * p2)",
            baseline,
        ),
    ]
