"""End of the last step of a recording, made comparable with the other cycles' steps.

A step ends when the PLC fires the next one (section 5.3.1.1), i.e. when all the
switches it awaits are satisfied, plus the step's dwell and a scan time. The last
step of a recording has no next step; ending it with the data would make it as long
as the idle tail the recording happens to contain (0.3 s on the simulator, minutes on
a rig stopped at the end of a shift), which skews its per-step features (air per
step, step duration, anything integrated over the step). Instead:

* the step is **settled** at the time its last awaited switch edge occurs (the first
  edge of each awaited switch after the step start); a step without awaited switches
  is settled at its start;
* its end is the settling time plus the **median gap** between settling and the next
  step's start of the same step (same position in the cycle, same valves) in the
  other cycles of the recording; the median keeps the dwell timers of the machine
  and the typical scan delay;
* when no other cycle of the recording has the step (a triggered capture of one
  cycle, followed by the machine idling until the next part), the gap is the step's
  ``end_gap_s`` from the machine description (its dwell timer plus half a PLC scan,
  :class:`~pneufdd.signals.events.StepSpec`): the step then ends where the twin's
  would, whatever idle time the capture holds after it;
* it never lies beyond the end of the data. When an awaited switch never changes
  (truncated recording), or no other cycle has the step and the sequence knows no
  ``end_gap_s`` (a learned sequence), the end of the data stays the end.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pneufdd.array_types import FloatArray

if TYPE_CHECKING:
    from pneufdd.signals.segmentation import Cycle, StepSpec

__all__ = ["close_final_step", "settled_at"]


def settled_at(
    spec: StepSpec,
    start_s: float,
    end_s: float,
    rise: Mapping[str, FloatArray],
    fall: Mapping[str, FloatArray],
) -> float | None:
    """Time all awaited switches of ``spec`` are satisfied in ``(start_s, end_s]`` [s].

    Parameters
    ----------
    spec : StepSpec
        The step's valves and awaited switch edges.
    start_s, end_s : float
        The step's window [s].
    rise, fall : mapping of str to ndarray
        Debounced rising / falling edge times of every switch channel [s].

    Returns
    -------
    float or None
        The latest of the first awaited edges [s]; ``start_s`` without awaited
        switches; None when an awaited edge is missing.
    """
    settled = start_s
    tol = 1e-9
    for switch, state in spec.switches:
        times = (rise if state == 1 else fall).get(switch)
        if times is None:
            continue
        k = int(np.searchsorted(times, start_s + tol, side="right"))
        if k >= times.size or times[k] > end_s + tol:
            return None
        settled = max(settled, float(times[k]))
    return settled


def close_final_step(
    cycles: Sequence[Cycle],
    specs: Sequence[StepSpec],
    data_end_s: float,
    rise: Mapping[str, FloatArray],
    fall: Mapping[str, FloatArray],
) -> list[Cycle]:
    """Replace the end of the recording's last step by its settling time + median gap.

    Parameters
    ----------
    cycles : sequence of Cycle
        The cycles in time order; the last step of the last cycle ends with the data.
    specs : sequence of StepSpec
        The sequence the cycles were matched against (with awaited switches).
    data_end_s : float
        End of the digital data [s].
    rise, fall : mapping of str to ndarray
        Debounced switch edge times [s].

    Returns
    -------
    list of Cycle
        ``cycles`` with the last step's ``end_s`` replaced where it can be defined
        (see the module docstring).
    """
    out = list(cycles)
    if not out or not out[-1].steps:
        return out
    last = out[-1]
    j = len(last.steps) - 1
    step = last.steps[j]
    if j >= len(specs) or frozenset(step.valves) != specs[j].valves:
        return out
    spec = specs[j]
    settled = settled_at(spec, step.start_s, data_end_s, rise, fall)
    if settled is None:
        return out
    gaps = []
    for cycle in out[:-1]:
        if len(cycle.steps) <= j or frozenset(cycle.steps[j].valves) != spec.valves:
            continue
        other = cycle.steps[j]
        t = settled_at(spec, other.start_s, other.end_s, rise, fall)
        if t is not None:
            gaps.append(other.end_s - t)
    if not gaps and spec.end_gap_s is None:
        return out
    gap = float(np.median(gaps)) if gaps else float(spec.end_gap_s or 0.0)
    end = min(settled + gap, data_end_s)
    steps = (*last.steps[:j], replace(step, end_s=max(end, settled)))
    out[-1] = replace(last, steps=steps)
    return out
