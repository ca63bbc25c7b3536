"""Shared benchmark helpers: timing and the ratio line printed by ``make bench``."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class BenchResult:
    """One benchmark figure, expressed against a baseline measured in the same run."""

    name: str
    value: float
    unit: str
    baseline_name: str
    baseline_value: float

    @property
    def ratio(self) -> float:
        return self.value / self.baseline_value if self.baseline_value else float("inf")

    def line(self) -> str:
        return (
            f"{self.name}: {self.value:.4g} {self.unit} | baseline {self.baseline_name}: "
            f"{self.baseline_value:.4g} {self.unit} | ratio {self.ratio:.2f}x"
        )


def best_time(func: Callable[[], object], repeat: int = 3) -> float:
    """Best wall time of ``repeat`` calls [s]."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best
