"""Honest axes: one rule for every figure of the report, ``history`` and the dashboard.

A chart's axis must not turn a small change into a steep one. The rules (``docs/dashboard.md``,
section Figures):

- **Ratio quantities start at zero**: leak flow [SLPM], cost [$/yr], air per cycle, a
  step's mean flow. A bar or line's height then reads as the size itself, and a 3 %
  drift of a leak looks like 3 %. The top is the larger of 1.15 times the largest value
  and a physical floor (:data:`FLOW_FLOOR_SLPM`, :data:`COST_FLOOR`), so a machine
  with tiny leaks is not drawn as if they filled the chart.
- **Differences are centred on zero** and span at least three reference standard
  deviations each way (:func:`difference_range`): a run that differs from its reference
  by its own noise stays near the middle, a real change reaches the edge.
- **Scores** (the per-cycle statistic, positive and spread over decades) use a log
  axis that always shows the threshold; the CUSUM a linear axis from zero that always
  shows its decision threshold.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = [
    "COST_FLOOR",
    "FLOW_FLOOR_SLPM",
    "HEADROOM",
    "difference_range",
    "ratio_range",
    "score_range",
]

HEADROOM = 1.15
"""Top of a ratio axis over its largest value [-]."""
FLOW_FLOOR_SLPM = 10.0
"""Smallest top of a leak-flow axis [SLPM]: about a 0.3 mm hole at 6 bar(g)."""
COST_FLOOR = 100.0
"""Smallest top of a cost axis [$/yr]."""


def _finite(values: Iterable[float | None]) -> list[float]:
    return [float(v) for v in values if v is not None and math.isfinite(float(v))]


def ratio_range(values: Iterable[float | None], floor: float) -> tuple[float, float]:
    """Axis of a ratio quantity: from zero to the larger of 1.15 x max and ``floor``.

    Examples
    --------
    A leak drifting from 50 to 48.5 SLPM (3 %) on its axis: the fall is 3 % of the
    height, not the whole chart.

    >>> ratio_range([50.0, 49.2, 48.5], floor=10.0)
    (0.0, 57.5)
    >>> ratio_range([], floor=10.0)
    (0.0, 10.0)
    """
    found = _finite(values)
    top = max([HEADROOM * max(found)] if found else [0.0])
    return 0.0, round(float(max(top, floor)), 9)


def difference_range(
    values: Iterable[float | None], reference_std: Iterable[float | None] = ()
) -> tuple[float, float]:
    """Symmetric axis of a difference: at least 3 reference standard deviations each way.

    Examples
    --------
    >>> difference_range([0.2, -0.1], reference_std=[0.5])
    (-1.5, 1.5)
    >>> difference_range([4.0, -1.0], reference_std=[0.5])
    (-4.6, 4.6)
    """
    found = [abs(v) for v in _finite(values)]
    spread = _finite(reference_std)
    half = max(
        HEADROOM * max(found) if found else 0.0,
        3.0 * max(spread) if spread else 0.0,
    )
    if half <= 0.0:
        half = 1.0
    return -round(half, 12), round(half, 12)


def score_range(scores: Iterable[float | None], threshold: float) -> tuple[float, float]:
    """Log10 range of a score axis that shows the scores and the threshold.

    Examples
    --------
    >>> score_range([0.5, 2.0], threshold=10.0)
    (-1.0, 1.5)
    """
    found = [v for v in _finite(scores) if v > 0.0]
    pool = [*found, threshold] if math.isfinite(threshold) and threshold > 0 else found
    if not pool:
        return -1.0, 1.0
    low = math.floor(2.0 * float(np.log10(min(pool))) - 1.0) / 2.0
    high = math.ceil(2.0 * float(np.log10(max(pool))) + 1.0) / 2.0
    return low, high
