"""End of a recording's last step (signals/final_step.py) on hand-built cycles."""

from __future__ import annotations

import numpy as np
import pytest

from pneufdd.signals.final_step import close_final_step, settled_at
from pneufdd.signals.segmentation import Cycle, RecordedStep, StepSpec

SPECS = (
    StepSpec(frozenset({"U_X_A"}), frozenset({("S_X_B", 1)})),
    StepSpec(frozenset({"U_X_B"}), frozenset({("S_X_A", 1)})),
)


def _cycles(data_end: float) -> list[Cycle]:
    # Three cycles of two steps; the next step fires 0.05 s (cycle 1) and 0.07 s
    # (cycle 2) after the awaited switch, 0.06 s in the median with cycle 3's step 1.
    starts = [(0.0, 1.0), (2.0, 3.0), (4.0, 5.0)]
    ends = [(1.0, 2.0), (3.0, 4.0), (5.0, data_end)]
    return [
        Cycle(k + 1, tuple(RecordedStep(j + 1, s[j], e[j], (f"U_X_{'AB'[j]}",)) for j in range(2)))
        for k, (s, e) in enumerate(zip(starts, ends, strict=True))
    ]


RISE = {
    "S_X_B": np.array([0.5, 2.5, 4.5]),  # step 1 settles 0.5 s after its start
    "S_X_A": np.array([1.95, 3.93, 5.4]),  # step 2: gaps 0.05, 0.07 -> median 0.06
}
FALL: dict[str, np.ndarray] = {}


def test_last_step_ends_at_settling_plus_median_gap() -> None:
    out = close_final_step(_cycles(9.0), SPECS, 9.0, RISE, FALL)
    assert out[-1].steps[-1].end_s == pytest.approx(5.4 + 0.06)
    assert out[-1].steps[0] == _cycles(9.0)[-1].steps[0]  # only the last step changes
    assert out[:-1] == _cycles(9.0)[:-1]


def test_last_step_never_beyond_the_data() -> None:
    out = close_final_step(_cycles(5.43), SPECS, 5.43, RISE, FALL)
    assert out[-1].steps[-1].end_s == pytest.approx(5.43)


def test_unsatisfied_switch_keeps_the_end_of_the_data() -> None:
    rise = {"S_X_B": RISE["S_X_B"], "S_X_A": RISE["S_X_A"][:2]}
    out = close_final_step(_cycles(5.3), SPECS, 5.3, rise, FALL)
    assert out[-1].steps[-1].end_s == 5.3
    assert settled_at(SPECS[1], 5.0, 5.3, rise, FALL) is None


def test_step_without_awaited_switches_uses_the_median_duration() -> None:
    specs = (SPECS[0], StepSpec(frozenset({"U_X_B"}), frozenset()))
    out = close_final_step(_cycles(9.0), specs, 9.0, RISE, FALL)
    assert out[-1].steps[-1].end_s == pytest.approx(5.0 + 1.0)
