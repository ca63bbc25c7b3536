"""Faults other than leaks: the typed catalogue, a fault's size and its life over a run.

Issue 34 (the dissertation's future work, section 6.2): internal leakage across a
piston seal or a valve spool, a meter-out throttle that changed, friction that grew,
a slow or starving valve, end-position cushioning set wrong, faulty switches and a
drifting regulator. :data:`FAULT_KINDS` is the catalogue a diagnosis consumes: each
:class:`FaultKind` names where it sits (``target``), its size's unit and scale, what
it changes physically and the law the twin evaluates (:mod:`pneufdd.physics.faults`).
``docs/faults.md`` lists it with the figures each fault moves.

A :class:`Fault` is scheduled like a leak (:mod:`pneufdd.sim.schedule`): it appears
in the first cycle starting at or after ``start_s``, may grow by ``growth_per_s``
(size unit per second) and is repaired from the first cycle starting at or after
``repair_s``. Written ``LOC=KIND[:SIZE][@TIME]`` on the command line
(:func:`parse_fault`), e.g. ``DNC=friction:+50%@2min``, ``DNC_A=throttle:-40%``,
``S_DNC_B=late:30ms``, ``supply=regulator:-0.4bar``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from pneufdd.errors import InputError, describe
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.schedule import check_life, check_unique, parse_duration

__all__ = [
    "FAULT_KINDS",
    "MAX_FAULTS",
    "Fault",
    "FaultKind",
    "FaultSchedule",
    "fault_schedule_from_options",
    "parse_fault",
    "parse_fault_rate",
    "parse_fault_size",
]

MAX_FAULTS = 1000
"""Most faults one run may schedule (``docs/limits.md``)."""


@dataclass(frozen=True)
class FaultKind:
    """One kind of fault: where it sits, how its size is given, what it changes.

    Attributes
    ----------
    name : str
        The kind as written after ``LOC=`` (``"piston-leak"``).
    family : str
        The fault type a diagnosis reports: ``internal-leak``, ``throttle``,
        ``friction``, ``valve``, ``cushion``, ``switch`` or ``supply``.
    target : str
        What ``LOC`` names: ``actuator`` (``DNC``), ``line`` (``DNC_A``), ``switch``
        (``S_DNC_B``) or ``supply``.
    unit : str
        The size's canonical unit (``""``: the kind has no size).
    units : tuple of str
        Units a size may be given in, the canonical one first.
    low, high : float
        Accepted sizes in the canonical unit.
    sizes : tuple of float
        A small and a large size in the canonical unit: the scale, and the two sizes
        ``docs/faults.md`` measures.
    changes : str
        What the fault changes in the machine (and in the twin).
    law : str
        The law the twin evaluates.
    source : str
        Where the model comes from.
    """

    name: str
    family: str
    target: str
    unit: str
    units: tuple[str, ...]
    low: float
    high: float
    sizes: tuple[float, float]
    changes: str
    law: str
    source: str

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form (the catalogue row)."""
        out = asdict(self)
        out["units"] = list(self.units)
        out["sizes"] = list(self.sizes)
        return out


_LEAK_SIZE = (
    "the flow it passes from the nominal supply pressure (regulator set point) to the "
    "atmosphere at 20 degC, like a leak (docs/twin.md, Leaks); or an equivalent "
    "sharp-edged hole in mm (Cd 0.61)"
)

FAULT_KINDS: dict[str, FaultKind] = {
    kind.name: kind
    for kind in (
        FaultKind(
            "piston-leak", "internal-leak", "actuator", "SLPM", ("SLPM", "mm"), 0.0, 2000.0,
            (10.0, 40.0),
            "an orifice across the piston seal joins chambers A and B: the pressurised "
            "chamber loses air to the other, which the valve exhausts or refills; size: "
            + _LEAK_SIZE,
            "pneufdd.physics.faults.seal_leak_mass_flow (eq. 4.3 between the chambers)",
            "section 6.2 (1); eq. 4.3; section 4.2.2 assumption (iv) dropped",
        ),
        FaultKind(
            "valve-leak-in", "internal-leak", "line", "SLPM", ("SLPM", "mm"), 0.0, 2000.0,
            (5.0, 20.0),
            "a worn spool seal passes supply air to the line's port (ISO 5599 port 1 -> "
            "2/4) whatever the spool's position: while the line is exhausted the air "
            "goes through it to the exhaust (the supply meter sees it, the line keeps a "
            "back pressure); size: " + _LEAK_SIZE,
            "pneufdd.physics.faults.seal_leak_mass_flow (manifold -> chamber)",
            "section 6.2 (1); eq. 4.3",
        ),
        FaultKind(
            "valve-leak-out", "internal-leak", "line", "SLPM", ("SLPM", "mm"), 0.0, 2000.0,
            (5.0, 20.0),
            "a worn spool seal passes the line's air to the exhaust (port 2/4 -> 3/5) "
            "whatever the spool's position: a pressurised or held line leaks through "
            "the valve, upstream of a line flow meter (which reads 0 in reverse); size: "
            + _LEAK_SIZE,
            "pneufdd.physics.faults.seal_leak_mass_flow (chamber -> atmosphere)",
            "section 6.2 (1); eq. 4.3",
        ),
        FaultKind(
            "throttle", "throttle", "line", "%", ("%", "Cv"), -95.0, 400.0, (-30.0, -60.0),
            "the line's meter-out throttle (one-way flow control, section 3.2.3) passes "
            "(1 + size/100) times its commissioned Cv (or is set to size Cv): a screw "
            "turned in or a clogged needle (< 0), turned out (> 0); the exhaust path "
            "follows the series rule, filling is unchanged (the check valve)",
            "pneufdd.physics.faults.throttled_cv, pneufdd.physics.flow.series_cv (eq. 4.6)",
            "section 3.2.3; eq. 4.6 (linear in Cv)",
        ),
        FaultKind(
            "friction", "friction", "actuator", "%", ("%", "N"), -50.0, 500.0, (30.0, 80.0),
            "the breakaway and Coulomb friction of eq. 4.14 grow by size % (or by size N): "
            "a worn seal, lost lubrication; the viscous term stays",
            "pneufdd.physics.faults.worn_friction",
            "eq. 4.14-4.16 (F_sf, F_cf)",
        ),
        FaultKind(
            "valve-delay", "valve", "actuator", "ms", ("ms",), 0.0, 1000.0, (20.0, 80.0),
            "the valve's switching times (20/42 ms on/off for the CPE14, Fig. 4.3) grow by "
            "size ms: a sticking spool, a weak coil, a clogged pilot",
            "the kernel's solenoid -> spool delay (pneufdd.sim.kernel)",
            "Fig. 4.3 (switching time on/off 20/42 ms)",
        ),
        FaultKind(
            "valve-pilot", "valve", "actuator", "bar", ("bar", "psi"), 0.0, 10.0, (4.0, 4.6),
            "the valve's pilot needs size bar(g) to shift the spool instead of its "
            "datasheet 3 bar (Fig. 4.3; a stiff or sticking spool): it switches on later "
            "the less the supply exceeds that, not at all below it",
            "pneufdd.physics.faults.pilot_delay_factor_kernel",
            "Fig. 4.3 (operating pressure 3-8 bar, switching time on 20 ms)",
        ),
        FaultKind(
            "cushion", "cushion", "line", "Cv", ("Cv", "%"), 1e-4, 50.0, (0.03, 0.012),
            "the end-position cushion at the line's end (A: home, B: extended) is set to a "
            "screw of size Cv (or by size % from the described one): over the cushioning "
            "length the exhaust leaves through that screw only, in series with the valve, "
            "tube and throttle; set too tight the piston crawls into its end",
            "pneufdd.physics.faults.cushion_engaged_kernel, cushioned_exhaust_cv",
            "Festo PPV cushioning (docs/faults.md); cushioning length 20 mm of the DNC-32",
        ),
        FaultKind(
            "stuck-on", "switch", "switch", "", ("",), 0.0, 0.0, (0.0, 0.0),
            "the proximity switch reads 1 whatever the piston does (welded reed contact): "
            "the PLC ends the step waiting for it at once and releases its solenoid",
            "the kernel's switch rule (pneufdd.sim.kernel)",
            "section 3.2.4 (SME-8 reed switches)",
        ),
        FaultKind(
            "stuck-off", "switch", "switch", "", ("",), 0.0, 0.0, (0.0, 0.0),
            "the switch reads 0 whatever the piston does (broken wire): the PLC waits and "
            "the machine stops (MachineStalledError) at the first step that waits for it",
            "the kernel's switch rule (pneufdd.sim.kernel)",
            "section 3.2.3 (a step waits for its switch)",
        ),
        FaultKind(
            "late", "switch", "switch", "ms", ("ms",), 0.0, 10_000.0, (20.0, 100.0),
            "the switch closes size ms after the piston reaches it (a switch moved along "
            "its slot, a slow input filter) and opens at once: every step waiting for it "
            "lasts size ms longer",
            "the kernel's switch rule (pneufdd.sim.kernel)",
            "section 3.2.3",
        ),
        FaultKind(
            "missing-edge", "switch", "switch", "%", ("%",), 0.0, 100.0, (1.0, 10.0),
            "in each cycle, with probability size %, the switch misses its closing edge "
            "(a weak magnet, a contact that does not close): the PLC waits and the "
            "machine stops (MachineStalledError naming the switch)",
            "the kernel's switch rule, drawn per cycle from the run's seed",
            "section 3.2.3",
        ),
        FaultKind(
            "regulator", "supply", "supply", "bar", ("bar", "psi"), -10.0, 10.0, (-0.3, -0.8),
            "the regulator's set point drifts by size bar (a relaxed spring, a turned knob): "
            "the supply pressure and every chamber's pressure follow",
            "pneufdd.physics.faults.regulator_outlet_pressure_kernel",
            "section 4.4.1 (the supply path, eq. 4.20)",
        ),
    )
}  # fmt: skip
"""The fault catalogue, by kind name."""

_RATE = re.compile(
    r"^\s*([+-]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z%]*)\s*/\s*(s|min|h)\s*$", re.I
)
_SECONDS = {"s": 1.0, "min": 60.0, "h": 3600.0}
_SIZE = re.compile(r"^\s*([+-]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z%]*)\s*$")
_UNIT_WORDS = {
    "slpm": "SLPM", "mm": "mm", "%": "%", "n": "N", "ms": "ms", "bar": "bar",
    "psi": "psi", "cv": "Cv",
}  # fmt: skip


def parse_fault_size(kind: str, text: str | float | None, where: str) -> tuple[float, str]:
    """A fault's size as ``(value, unit)``; a bare number is in the kind's canonical unit.

    Examples
    --------
    >>> parse_fault_size("friction", "+50%", "f"), parse_fault_size("piston-leak", "1.2mm", "f")
    ((50.0, '%'), (1.2, 'mm'))
    >>> parse_fault_size("stuck-on", None, "f")
    (0.0, '')
    """
    spec = FAULT_KINDS.get(kind)
    if spec is None:
        raise InputError(describe(f"{where}: fault kind", kind, sorted(FAULT_KINDS)))
    if not spec.unit:
        if text not in (None, ""):
            raise InputError(describe(f"{where}: size of a {kind} fault", text, "no size"))
        return 0.0, ""
    if text is None or isinstance(text, bool) or text == "":
        raise InputError(
            describe(f"{where}: size of a {kind} fault", text, f"a size in {list(spec.units)}")
        )
    if isinstance(text, int | float):
        value, unit = float(text), spec.unit
    else:
        match = _SIZE.match(text)
        word = _UNIT_WORDS.get(match.group(2).lower(), "?") if match else "?"
        if match is None or (match.group(2) and word not in spec.units):
            raise InputError(
                describe(
                    f"{where}: size of a {kind} fault", text, f"a number in {list(spec.units)}"
                )
            )
        value, unit = float(match.group(1)), word if match.group(2) else spec.unit
    low, high = _range(spec, unit)
    if not (math.isfinite(value) and low <= value <= high):
        raise InputError(
            describe(f"{where}: size of a {kind} fault", text, f"{low:g} to {high:g} {unit}")
        )
    return value, unit


def parse_fault_rate(kind: str, unit: str, text: str, where: str) -> float:
    """A fault's growth rate, ``"+10%/h"``, ``"-0.1/min"``, in ``unit`` per second.

    Examples
    --------
    >>> parse_fault_rate("throttle", "%", "-10%/h", "g") * 3600
    -10.0
    """
    match = _RATE.match(text)
    word = _UNIT_WORDS.get(match.group(2).lower(), "?") if match else "?"
    if match is None or (match.group(2) and word != unit):
        raise InputError(
            describe(where, text, f"a rate such as '+10{unit}/h' or '-0.5/min' (in {unit or '-'})")
        )
    return float(match.group(1)) / _SECONDS[match.group(3).lower()]


def _range(spec: FaultKind, unit: str) -> tuple[float, float]:
    """Accepted sizes of ``spec`` in ``unit``."""
    if unit == "psi":
        return spec.low * 14.5038, spec.high * 14.5038
    if unit == "mm":
        return 0.0, 20.0  # a 20 mm hole: as leaks (pneufdd.sim.leaks.MAX_SIZE)
    if unit == "N":
        return -1e6, 1e6
    if spec.name == "cushion" and unit == "%":
        return -95.0, 400.0
    if spec.name == "throttle" and unit == "Cv":
        return 1e-4, 50.0
    return spec.low, spec.high


@dataclass(frozen=True)
class Fault:
    """A fault with a life: it appears, may grow and may be repaired.

    Attributes
    ----------
    location : str
        An actuator (``DNC``), a line (``DNC_A``), a switch (``S_DNC_B``) or
        ``supply``, as the kind's ``target`` asks.
    kind : str
        A name of :data:`FAULT_KINDS`.
    size : float
        Size when it appears, in ``unit`` (0 for kinds without a size).
    unit : str
        Unit of ``size``; ``""`` means the kind's canonical unit.
    start_s : float
        Time it appears, from the run's start [s].
    growth_per_s : float
        Change of the size per second [unit/s] (may be negative, e.g. a throttle
        clogging); the size stays within the kind's range.
    repair_s : float or None
        Time it is repaired [s]; None: never.

    Examples
    --------
    >>> f = Fault("DNC", "friction", 30.0, "%", start_s=60.0, growth_per_s=0.01)
    >>> f.size_at(30.0), f.size_at(160.0)
    (None, 31.0)
    """

    location: str
    kind: str
    size: float = 0.0
    unit: str = ""
    start_s: float = 0.0
    growth_per_s: float = 0.0
    repair_s: float | None = None

    def __post_init__(self) -> None:
        where = f"fault {self.location}={self.kind}"
        spec = FAULT_KINDS.get(self.kind)
        if spec is None:
            raise InputError(describe(f"{where}: fault kind", self.kind, sorted(FAULT_KINDS)))
        if not spec.unit and (self.size != 0.0 or self.unit):
            raise InputError(
                describe(f"{where}: size", f"{self.size}{self.unit}", "none (a kind without size)")
            )
        text = f"{self.size!r}{self.unit or spec.unit}" if spec.unit else None
        value, unit = parse_fault_size(self.kind, text, where)
        object.__setattr__(self, "size", value)
        object.__setattr__(self, "unit", unit)
        check_life(where, self.start_s, self.repair_s)
        if not math.isfinite(self.growth_per_s) or (not unit and self.growth_per_s != 0.0):
            raise InputError(
                describe(f"growth of {where} [{unit or '-'}/s]", self.growth_per_s, "finite")
            )

    @property
    def key(self) -> tuple[str, str]:
        """``(location, kind)``: one fault of a kind per location."""
        return self.location, self.kind

    def size_at(self, time_s: float) -> float | None:
        """Size at ``time_s`` (None before it appears and after its repair) [unit]."""
        if time_s < self.start_s or (self.repair_s is not None and time_s >= self.repair_s):
            return None
        low, high = _range(FAULT_KINDS[self.kind], self.unit)
        return min(max(self.size + self.growth_per_s * (time_s - self.start_s), low), high)

    def as_metadata(self) -> dict[str, Any]:
        """JSON-ready ground truth, with the kind's family and target."""
        spec = FAULT_KINDS[self.kind]
        return {
            "location": self.location,
            "kind": self.kind,
            "family": spec.family,
            "target": spec.target,
            "size": self.size,
            "unit": self.unit,
            "start_s": self.start_s,
            "growth_per_s": self.growth_per_s,
            "repair_s": self.repair_s,
        }


def parse_fault(text: str, growth: str | None = None, repair: str | None = None) -> Fault:
    """Parse ``LOC=KIND[:SIZE][@TIME]`` with an optional growth rate and repair time.

    Examples
    --------
    >>> f = parse_fault("DNC=friction:+50%@2min", growth="10/h", repair="1h")
    >>> f.location, f.kind, f.size, f.unit, f.start_s, round(f.growth_per_s * 3600, 6), f.repair_s
    ('DNC', 'friction', 50.0, '%', 120.0, 10.0, 3600.0)
    >>> parse_fault("S_DNC_B=stuck-on").kind
    'stuck-on'
    """
    location, sep, rest = text.partition("=")
    body, at, when = rest.partition("@")
    kind, _, size = body.partition(":")
    if not sep or not location.strip() or not kind.strip():
        raise InputError(
            describe("--fault", text, "LOC=KIND[:SIZE][@TIME], e.g. DNC=friction:+50%@2min")
        )
    where = f"--fault {text!r}"
    value, unit = parse_fault_size(kind.strip(), size.strip() or None, where)
    return Fault(
        location.strip(),
        kind.strip(),
        value,
        unit,
        parse_duration(when, f"time of {where}") if at else 0.0,
        parse_fault_rate(kind.strip(), unit, growth, f"growth of {where}") if growth else 0.0,
        parse_duration(repair, f"repair time of {where}") if repair else None,
    )


class FaultSchedule:
    """The faults of a run over time.

    Parameters
    ----------
    faults : iterable of Fault or str
        At most one of a kind per location; a string is parsed by :func:`parse_fault`.

    Examples
    --------
    >>> s = FaultSchedule(["DNC=friction:+50%@1min", "S_DNC_B=late:30ms"])
    >>> [(f.kind, size) for f, size in s.active(0.0)], [f.kind for f, _ in s.active(60.0)]
    ([('late', 30.0)], ['friction', 'late'])
    """

    def __init__(self, faults: Iterable[Fault | str]) -> None:
        items = list(faults)
        if len(items) > MAX_FAULTS:
            raise InputError(describe("faults (count)", len(items), f"at most {MAX_FAULTS:,}"))
        self.faults: tuple[Fault, ...] = tuple(
            parse_fault(f) if isinstance(f, str) else f for f in items
        )
        names = ("fault", "Fault objects or 'LOC=KIND:SIZE' text", "fault given twice")
        check_unique(self.faults, Fault, lambda fault: fault.key, names)

    def active(self, time_s: float) -> list[tuple[Fault, float]]:
        """The faults present at ``time_s``, each with its size then."""
        out = []
        for fault in self.faults:
            size = fault.size_at(time_s)
            if size is not None:
                out.append((fault, size))
        return out

    def check(self, machine: MachineDescription) -> None:
        """Every fault's location must be of its kind's target on ``machine``.

        Raises
        ------
        InputError
            Naming the fault, the location and the locations allowed.
        """
        for fault in self.faults:
            spec = FAULT_KINDS[fault.kind]
            allowed = _targets(machine, spec.target)
            if fault.location not in allowed:
                raise InputError(
                    describe(f"location of a {fault.kind} fault ({spec.target})", fault.location,
                             allowed)
                )  # fmt: skip
            if spec.name == "cushion" and fault.unit == "%":
                act = machine.actuators[machine.actuator_ids.index(fault.location[:-2])]
                if act.cushion_length_mm <= 0.0:
                    raise InputError(
                        describe(f"cushion fault on {fault.location} in %", fault.size,
                                 "a size in Cv: the description gives this actuator no "
                                 "cushioning (cushion_length_mm) to change")
                    )  # fmt: skip

    def as_metadata(self) -> list[dict[str, Any]]:
        """JSON-ready ground truth of the schedule."""
        return [fault.as_metadata() for fault in self.faults]


def _targets(machine: MachineDescription, target: str) -> list[str]:
    """The locations of ``machine`` a fault of ``target`` may sit at."""
    if target == "actuator":
        return list(machine.actuator_ids)
    if target == "line":
        return [loc for loc in machine.leak_locations if loc != "supply"]
    if target == "switch":
        return list(machine.switches)
    return ["supply"]


def _keyed(items: Sequence[str], mark: str, option: str, form: str) -> dict[tuple[str, str], str]:
    """``LOC=KIND<mark>VALUE`` options by ``(LOC, KIND)``."""
    out: dict[tuple[str, str], str] = {}
    for item in items:
        loc, sep, rest = item.partition("=")
        kind, marked, value = rest.rpartition(mark) if mark == "@" else rest.partition(mark)
        if not sep or not marked or not value.strip() or not kind.strip():
            raise InputError(describe(option, item, form))
        out[(loc.strip(), kind.strip())] = value.strip()
    return out


def fault_schedule_from_options(
    faults: Sequence[str], growth: Sequence[str], repair: Sequence[str]
) -> FaultSchedule | None:
    """The schedule of ``--fault``, ``--fault-growth LOC=KIND:RATE``, ``--fault-repair``.

    Examples
    --------
    >>> s = fault_schedule_from_options(
    ...     ["DNC_A=throttle:-20%"], ["DNC_A=throttle:-10/h"], ["DNC_A=throttle@2h"])
    >>> f = s.faults[0]
    >>> round(f.size_at(3600.0), 6), f.size_at(7200.0)
    (-30.0, None)
    """
    rates = _keyed(growth, ":", "--fault-growth", "LOC=KIND:RATE, e.g. DNC=friction:10/h")
    repairs = _keyed(repair, "@", "--fault-repair", "LOC=KIND@TIME, e.g. DNC=friction@2h")
    parsed = []
    for item in faults:
        location, _, rest = item.partition("=")
        key = (location.strip(), rest.partition("@")[0].partition(":")[0].strip())
        parsed.append(parse_fault(item, rates.pop(key, None), repairs.pop(key, None)))
    orphans = sorted(set(rates) | set(repairs))
    if orphans:
        raise InputError(
            describe("--fault-growth/--fault-repair fault", orphans, "a fault given with --fault")
        )
    return FaultSchedule(parsed) if parsed else None
