"""Names of a machine's PLC steps, with the actuators they move, for axes and tables."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["step_labels"]

_MOVE = {"A": "+", "B": "-"}


def _short(valves: Sequence[str]) -> str:
    """``U_DNC_A`` -> ``DNC+`` (the A solenoid extends/advances), ``U_VAC`` -> ``VAC``."""
    parts = []
    for valve in sorted(valves):
        name = valve[2:] if valve.startswith("U_") else valve
        actuator, _, side = name.rpartition("_")
        parts.append(f"{actuator}{_MOVE[side]}" if actuator and side in _MOVE else name)
    return " ".join(parts) or "dwell"


def step_labels(
    sequence: Sequence[Mapping[str, Any]], names: Sequence[str] = (), n_steps: int | None = None
) -> list[str]:
    """A label per step: ``"3 DRQD+ SLT+"`` (number, then the actuators it moves).

    Parameters
    ----------
    sequence : sequence of mapping
        The reference's PLC sequence records (``{"valves": [...], ...}`` per step).
    names : sequence of str
        The description's step names; used when there is no sequence.
    n_steps : int, optional
        Steps per cycle (labels ``"3"`` when neither sequence nor names fit).

    Examples
    --------
    >>> step_labels([{"valves": ["U_DRQD_A", "U_SLT_A"]}, {"valves": ["U_VAC"]}])
    ['1 DRQD+ SLT+', '2 VAC']
    """
    n = len(sequence) if n_steps is None else n_steps
    if sequence and len(sequence) == n:
        return [f"{i} {_short(step.get('valves', []))}" for i, step in enumerate(sequence, 1)]
    if names and len(names) == n:
        return [f"{i} {name[:24]}" for i, name in enumerate(names, 1)]
    return [str(i) for i in range(1, n + 1)]
