"""Stepwise Voronoi search (section 5.3.5) against brute force and scikit-learn's KDTree.

Features: the vectorized map's two axes (air of the DNC's extend and retract
strokes, normalised by the leak-free value) of simulated ``festo-dsd`` cycles:
leak-free and both DNC lines at 1-6 turns, 8 cycles each (104 training vectors).
Queries: 10,000 training vectors jittered by their cluster's spread. All three
searches return the same neighbour (checked). Figures: distance computations per
query and time per query, as ratios against the brute-force search (numpy,
vectorised over the training set).
"""

from __future__ import annotations

import time

import numpy as np
from sklearn.neighbors import KDTree

from common import BenchResult
from pneufdd.classifiers import VoronoiSearch
from pneufdd.features import feature_matrix
from pneufdd.sim import simulate

QUERIES = 10_000


def _features() -> np.ndarray:
    rows = []
    runs = [{}] + [{f"DNC_{s}": t} for s in "AB" for t in range(1, 7)]
    for k, leaks in enumerate(runs):
        rec = simulate("festo-dsd", cycles=10, leaks=leaks, seed=1000 + k)
        df = feature_matrix(rec, ("DNC",), ("air",))
        rows.append(df[["DNC.air_extend_SL", "DNC.air_retract_SL"]].to_numpy()[:8])
    data = np.vstack(rows)
    return data / data[:8].mean(axis=0)


def run() -> list[BenchResult]:
    train = _features()
    rng = np.random.default_rng(7)
    spread = np.std(train[:8], axis=0)
    queries = train[rng.integers(0, len(train), QUERIES)] + rng.normal(size=(QUERIES, 2)) * spread

    start = time.perf_counter()
    d2 = ((queries[:, None, :] - train[None, :, :]) ** 2).sum(axis=2)
    brute = np.argmin(d2, axis=1)
    t_brute = time.perf_counter() - start

    search = VoronoiSearch().fit(train)
    start = time.perf_counter()
    _, voronoi = search.query(queries)
    t_voronoi = time.perf_counter() - start

    tree = KDTree(train)
    tree.reset_n_calls()
    start = time.perf_counter()
    _, kd = tree.query(queries, k=1)
    t_kd = time.perf_counter() - start
    kd_calls = tree.get_n_calls()

    if not (np.array_equal(brute, voronoi) and np.array_equal(brute, kd[:, 0])):
        raise AssertionError("the three searches disagree on the nearest neighbour")
    n = len(train)
    return [
        BenchResult(
            "Voronoi distance computations / query",
            search.n_distance_computations_ / QUERIES,
            "distances",
            "brute force",
            float(n),
        ),
        BenchResult(
            "KDTree distance computations / query",
            kd_calls / QUERIES,
            "distances",
            "brute force",
            float(n),
        ),
        BenchResult(
            "Voronoi time / query",
            t_voronoi / QUERIES * 1e6,
            "us",
            "brute force (numpy)",
            t_brute / QUERIES * 1e6,
        ),
        BenchResult(
            "KDTree time / query",
            t_kd / QUERIES * 1e6,
            "us",
            "brute force (numpy)",
            t_brute / QUERIES * 1e6,
        ),
    ]
