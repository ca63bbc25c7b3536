"""Leak history: one JSON line per diagnosed run, and per-location trends.

A plant engineer diagnoses a machine every shift; the history shows whether a leak
is new, growing or fixed. Each line of the history file is the JSON summary of one
:class:`~pneufdd.diagnosis.findings.Diagnosis` with the time and the run's name.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.errors import FileFormatError, describe

__all__ = ["HistoryEntry", "append_history", "location_trends", "read_history"]


@dataclass(frozen=True)
class HistoryEntry:
    """One diagnosed run.

    Attributes
    ----------
    time : datetime
        When the run was diagnosed (timezone-aware).
    run : str
        Name of the run (e.g. its file).
    detected : bool
        Whether a leak was detected.
    total_annual_cost : float
        Sum of the leaks' annual costs [$].
    leaks : tuple of dict
        The leaks as in the ``--json`` output (location, flow_slpm, ...).
    """

    time: datetime
    run: str
    detected: bool
    total_annual_cost: float
    leaks: tuple[Mapping[str, Any], ...]


def append_history(
    path: str | Path, diagnosis: Diagnosis, run: str, time: datetime | None = None
) -> Path:
    """Append one diagnosis to the history file ``path`` (created if missing)."""
    when = (time or datetime.now(UTC)).astimezone(UTC)
    data = diagnosis.to_dict()
    line = {
        "time": when.isoformat(),
        "run": run,
        "detected": data["detected"],
        "total_annual_cost": data["total_annual_cost"],
        "leaks": data["leaks"],
    }
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    with open(target, "a", encoding="utf-8") as handle:
        handle.write(json.dumps(line, allow_nan=False) + "\n")
    return target


def read_history(path: str | Path) -> list[HistoryEntry]:
    """Read a history file; errors name the file and the line.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = Path(d) / "h.jsonl"
    ...     _ = p.write_text('{"time": "2026-01-01T00:00:00+00:00", "run": "a", '
    ...                      '"detected": false, "total_annual_cost": 0, "leaks": []}\\n')
    ...     [e.run for e in read_history(p)]
    ['a']
    """
    source = Path(path)
    entries = []
    with open(source, encoding="utf-8") as handle:
        for number, text in enumerate(handle, start=1):
            if not text.strip():
                continue
            try:
                raw = json.loads(text)
                entries.append(
                    HistoryEntry(
                        time=datetime.fromisoformat(raw["time"]),
                        run=str(raw["run"]),
                        detected=bool(raw["detected"]),
                        total_annual_cost=float(raw["total_annual_cost"] or 0.0),
                        leaks=tuple(raw["leaks"]),
                    )
                )
            except (ValueError, KeyError, TypeError) as exc:
                raise FileFormatError(
                    describe(
                        f"history file {str(source)!r} line {number}",
                        text.strip()[:60],
                        "a JSON diagnosis summary",
                    )
                ) from exc
    return entries


def location_trends(entries: list[HistoryEntry]) -> dict[str, list[tuple[datetime, float]]]:
    """Per location: the leak flow of every run it was reported in, in time order [SLPM]."""
    trends: dict[str, list[tuple[datetime, float]]] = {}
    for entry in sorted(entries, key=lambda e: e.time):
        for leak in entry.leaks:
            trends.setdefault(str(leak["location"]), []).append(
                (entry.time, float(leak["flow_slpm"]))
            )
    return trends
