"""Leaks that change over time: appear, grow and are repaired during a simulated run.

The twin runs cycle by cycle (:func:`pneufdd.sim.run_simulation`); between cycles the
plant's leak areas are set from the schedule **at the cycle's start time**. A leak
that appears at ``t`` therefore takes effect in the first cycle starting at or after
``t``, grows in steps of one cycle, and a repair at ``t`` removes it from the first
cycle starting at or after ``t``. Within a cycle the leak area is constant (a real
leak grows over days, not within a 15 s cycle). The schedule and the size of every
leak in every cycle are stored in the recording's metadata as ground truth
(``leak_schedule`` and ``leak_timeline``).

A size grows linearly from its size at ``start_s`` at ``growth_per_s`` (size unit per
second), capped at ``max_size`` (6 turns of the GR-3/8B valve, Table 3.3, for sizes in
turns).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from pneufdd.errors import InputError, describe
from pneufdd.sim import layout as lay
from pneufdd.sim.compile import Plant
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import MAX_TURNS, Leak, LeakSpec, parse_leak_size, resolve_leaks

__all__ = [
    "LeakSchedule",
    "ScheduledLeak",
    "apply_leak_schedule",
    "check_life",
    "check_unique",
    "parse_duration",
    "parse_rate",
    "parse_scheduled_leak",
    "schedule_from_options",
]

_TIME = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(s|min|h)?\s*$", re.I)
_RATE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*/\s*(s|min|h)\s*$", re.I)
_SECONDS = {"s": 1.0, "min": 60.0, "h": 3600.0}


def check_life(where: str, start_s: float, repair_s: float | None) -> None:
    """A scheduled leak's or fault's onset (>= 0) and repair (after the onset) [s].

    Raises
    ------
    InputError
        Naming ``where`` and the time refused.
    """
    if not (math.isfinite(start_s) and start_s >= 0):
        raise InputError(describe(f"start time of {where} [s]", start_s, ">= 0"))
    if repair_s is not None and not (math.isfinite(repair_s) and repair_s > start_s):
        raise InputError(describe(f"repair time of {where} [s]", repair_s, f"> {start_s}"))


def check_unique(
    items: Sequence[Any], kind: type, key: Callable[[Any], Any], names: tuple[str, str, str]
) -> None:
    """Every item is a ``kind`` and no two share a ``key`` (a schedule's leaks, faults).

    ``names``: what an item is called, what is allowed, what a repeated key is called.

    Raises
    ------
    InputError
        Naming the item of another type, or the key given twice.
    """
    seen: set[Any] = set()
    for item in items:
        if not isinstance(item, kind):
            raise InputError(describe(names[0], item, names[1]))
        if key(item) in seen:
            raise InputError(describe(names[2], key(item), "once"))
        seen.add(key(item))


def parse_duration(text: str, where: str) -> float:
    """Parse ``"120s"``, ``"2min"``, ``"1.5h"`` or a bare number of seconds [s].

    Examples
    --------
    >>> parse_duration("2min", "t"), parse_duration("30", "t")
    (120.0, 30.0)
    """
    match = _TIME.match(text)
    if match is None:
        raise InputError(describe(where, text, "a time such as '120s', '2min' or '1.5h'"))
    return float(match.group(1)) * _SECONDS[(match.group(2) or "s").lower()]


def parse_rate(text: str, where: str) -> float:
    """Parse a growth rate ``"0.5/h"``, ``"0.01/s"`` into size units per second.

    Examples
    --------
    >>> parse_rate("3.6/h", "g")
    0.001
    """
    match = _RATE.match(text)
    if match is None:
        raise InputError(describe(where, text, "a rate such as '0.5/h' or '0.01/s'"))
    return float(match.group(1)) / _SECONDS[match.group(2).lower()]


@dataclass(frozen=True)
class ScheduledLeak:
    """A leak with a life: it appears, may grow and may be repaired.

    Attributes
    ----------
    location : str
        ``supply``, ``<ACT>_A`` or ``<ACT>_B``.
    size : float
        Size when it appears, in ``unit``.
    unit : str
        ``"turns"``, ``"mm"`` or ``"SLPM"`` (as :class:`~pneufdd.sim.Leak`).
    start_s : float
        Time it appears, from the run's start [s].
    growth_per_s : float
        Growth of the size [unit/s].
    repair_s : float or None
        Time it is repaired [s]; None: never.
    """

    location: str
    size: float
    unit: str = "turns"
    start_s: float = 0.0
    growth_per_s: float = 0.0
    repair_s: float | None = None

    def __post_init__(self) -> None:
        where = f"scheduled leak {self.location!r}"
        check_life(where, self.start_s, self.repair_s)
        if not (math.isfinite(self.growth_per_s) and self.growth_per_s >= 0):
            raise InputError(describe(f"growth of {where} [unit/s]", self.growth_per_s, ">= 0"))
        parse_leak_size(f"{self.size}{self.unit}" if self.unit != "turns" else self.size, where)

    def size_at(self, time_s: float) -> float:
        """Size at ``time_s`` (0 before it appears and after its repair) [unit]."""
        if time_s < self.start_s or (self.repair_s is not None and time_s >= self.repair_s):
            return 0.0
        size = self.size + self.growth_per_s * (time_s - self.start_s)
        return min(size, MAX_TURNS) if self.unit == "turns" else size

    def as_metadata(self) -> dict[str, Any]:
        """JSON-ready form (ground truth)."""
        return {
            "location": self.location,
            "size": self.size,
            "unit": self.unit,
            "start_s": self.start_s,
            "growth_per_s": self.growth_per_s,
            "repair_s": self.repair_s,
        }


def parse_scheduled_leak(
    text: str, growth: str | None = None, repair: str | None = None
) -> ScheduledLeak:
    """Parse ``LOCATION=SIZE@TIME`` with an optional growth rate and repair time.

    Examples
    --------
    >>> leak = parse_scheduled_leak("DNC_B=3@120s", growth="0.6/min", repair="10min")
    >>> leak.location, leak.size, leak.start_s, leak.growth_per_s, leak.repair_s
    ('DNC_B', 3.0, 120.0, 0.01, 600.0)
    """
    location, sep, rest = text.partition("=")
    size_text, at, time_text = rest.partition("@")
    if not sep or not location.strip() or not size_text.strip():
        raise InputError(describe("--leak", text, "LOCATION=SIZE or LOCATION=SIZE@TIME"))
    size, unit = parse_leak_size(size_text.strip(), f"size of leak {location.strip()!r}")
    start = parse_duration(time_text, f"time of --leak {text!r}") if at else 0.0
    return ScheduledLeak(
        location.strip(),
        size,
        unit,
        start,
        parse_rate(growth, f"growth of leak {location!r}") if growth else 0.0,
        parse_duration(repair, f"repair time of leak {location!r}") if repair else None,
    )


class LeakSchedule:
    """The leaks of a run over time.

    Parameters
    ----------
    leaks : iterable of ScheduledLeak
        At most one per location.

    Examples
    --------
    >>> s = LeakSchedule([ScheduledLeak("supply", 2.0, start_s=30.0, repair_s=90.0)])
    >>> [leak.size for leak in s.leaks_at(10.0)], [leak.size for leak in s.leaks_at(30.0)]
    ([], [2.0])
    """

    def __init__(self, leaks: Iterable[ScheduledLeak]) -> None:
        self.leaks: tuple[ScheduledLeak, ...] = tuple(leaks)
        check_unique(
            self.leaks, ScheduledLeak, lambda leak: leak.location,
            ("scheduled leak", "ScheduledLeak objects", "scheduled leak location given twice"),
        )  # fmt: skip

    @property
    def locations(self) -> tuple[str, ...]:
        """Locations of the scheduled leaks."""
        return tuple(leak.location for leak in self.leaks)

    def leaks_at(self, time_s: float) -> list[Leak]:
        """The leaks present at ``time_s``, with their sizes then."""
        out = []
        for leak in self.leaks:
            size = leak.size_at(time_s)
            if size > 0.0:
                out.append(Leak(leak.location, size, leak.unit))
        return out

    def resolve(self, machine: MachineDescription, time_s: float) -> list[LeakSpec]:
        """Resolved leaks (areas) present at ``time_s`` on ``machine``."""
        return resolve_leaks(machine, self.leaks_at(time_s))

    def check(self, machine: MachineDescription, static: Sequence[LeakSpec]) -> None:
        """Locations must exist and not also carry a constant leak."""
        valid = machine.leak_locations
        fixed = {spec.location for spec in static}
        for leak in self.leaks:
            if leak.location not in valid:
                raise InputError(describe("scheduled leak location", leak.location, valid))
            if leak.location in fixed:
                raise InputError(
                    describe(
                        "leak location both constant and scheduled", leak.location, "one of them"
                    )
                )

    def as_metadata(self) -> list[dict[str, Any]]:
        """JSON-ready ground truth of the schedule."""
        return [leak.as_metadata() for leak in self.leaks]


def schedule_from_options(
    timed: Sequence[str], growth: Sequence[str], repair: Sequence[str]
) -> LeakSchedule | None:
    """The schedule of ``--leak LOC=SIZE@TIME``, ``--leak-growth``, ``--leak-repair``.

    Growth and repair refer to a timed leak; None when there is no timed leak.

    Examples
    --------
    >>> s = schedule_from_options(["supply=2@60s"], ["supply=1/h"], ["supply@5min"])
    >>> s.leaks[0].repair_s, round(s.leaks[0].size_at(3600.0 + 60.0), 3)
    (300.0, 0.0)
    """
    rates: dict[str, str] = {}
    for item in growth:
        loc, sep, rate = item.partition("=")
        if not sep or not rate.strip():
            raise InputError(describe("--leak-growth", item, "LOCATION=RATE, e.g. DNC_B=0.5/min"))
        rates[loc.strip()] = rate.strip()
    repairs: dict[str, str] = {}
    for item in repair:
        loc, sep, when = item.partition("@")
        if not sep or not when.strip():
            raise InputError(describe("--leak-repair", item, "LOCATION@TIME, e.g. DNC_B@10min"))
        repairs[loc.strip()] = when.strip()
    leaks = []
    for item in timed:
        location = item.partition("=")[0].strip()
        leaks.append(
            parse_scheduled_leak(item, rates.pop(location, None), repairs.pop(location, None))
        )
    orphans = sorted(set(rates) | set(repairs))
    if orphans:
        raise InputError(
            describe(
                "--leak-growth/--leak-repair location", orphans, "a leak given as LOC=SIZE@TIME"
            )
        )
    return LeakSchedule(leaks) if leaks else None


def apply_leak_schedule(
    plant: Plant,
    desc: MachineDescription,
    static: list[LeakSpec],
    schedule: LeakSchedule,
    time_s: float,
    cycle: int,
) -> list[dict[str, Any]]:
    """Set the plant's leak areas for the cycle starting at ``time_s``; its ground truth."""
    present = schedule.resolve(desc, time_s)
    areas = {spec.location: spec.area_m2 for spec in [*static, *present]}
    plant.sp[lay.SP_SUPPLY_LEAK] = areas.get("supply", 0.0)
    for i, a in enumerate(desc.actuators):
        for side in (0, 1):
            plant.cp[2 * i + side, lay.CP_LEAK] = areas.get(f"{a.id}_{'AB'[side]}", 0.0)
    return [
        {
            "cycle": cycle,
            "cycle_start_s": time_s,
            "location": spec.location,
            "size": spec.size,
            "unit": spec.unit,
            "slpm": spec.nominal_slpm,
        }
        for spec in present
    ]
