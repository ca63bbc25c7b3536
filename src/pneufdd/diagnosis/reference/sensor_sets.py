"""Sensor sets: which analog channels a reference uses, and what they can find (issue 33).

A plant has the sensors it has. pneufdd judges any set of analog channels (the PLC's
valve and switch signals are always used: they segment the cycles and time the steps),
and names five kinds of set, each with what it can and cannot locate or size:

* ``full``: a supply flow meter (``Q_In``) and sensors on actuator lines;
* ``line-flows``: sensors on actuator lines (``Q_<ACT>_A/B``, ``P_<ACT>_A/B``,
  ``X_<ACT>``, with or without ``P_In``) and **no** supply flow meter, as on the rig
  of issue 33;
* ``supply-only``: the supply meter (``P_In`` and ``Q_In``, or ``Q_In`` alone);
* ``pressure-only``: the supply pressure ``P_In`` alone;
* ``digital-only``: no analog channel, the PLC's signals alone (step durations).

:func:`sensor_set_channels` picks a named set out of a machine's channels (the
campaign's ``--sensor-sets``; a custom set is its channels joined by ``+``);
:func:`sensor_set_kind` names the kind of a reference's channels and
:func:`sensor_set_report` says what it can and cannot do. The statements are what the
acceptance campaign measured on plants of the built-in machines (``docs/sensor-sets.md``,
``docs/results/750M.md``), not a promise for every machine: each diagnosis reports the
groups it actually could not separate.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pneufdd.errors import InputError, describe

__all__ = [
    "SENSOR_SETS",
    "SUPPLY_CHANNELS",
    "SensorSetReport",
    "check_sensor_set_names",
    "is_line_sensor",
    "machine_sensor_sets",
    "sensor_set_channels",
    "sensor_set_kind",
    "sensor_set_report",
]

SENSOR_SETS = ("full", "line-flows", "supply-only", "pressure-only", "digital-only")
"""The named sensor sets, most sensors first."""

SUPPLY_CHANNELS = ("P_In", "Q_In")
"""The supply meter: pressure and flow at the machine's inlet."""

_ANALOG = r"(P_In|Q_In|[PQ]_[A-Z][A-Z0-9_]*_[AB]|X_[A-Z][A-Z0-9_]*)"
_CUSTOM = re.compile(rf"^{_ANALOG}(\+{_ANALOG})*$")
_LINE = re.compile(r"^([PQ]_[A-Z][A-Z0-9_]*_[AB]|X_[A-Z][A-Z0-9_]*)$")


def is_line_sensor(channel: str) -> bool:
    """True for a sensor on an actuator or its lines: ``P_/Q_<ACT>_A/B``, ``X_<ACT>``.

    Examples
    --------
    >>> [is_line_sensor(c) for c in ("Q_DNC_A", "X_DNC", "P_In", "Q_In")]
    [True, True, False, False]
    """
    return channel not in SUPPLY_CHANNELS and bool(_LINE.match(channel))


def check_sensor_set_names(names: Sequence[str], what: str = "sensor sets") -> None:
    """Refuse a name that is neither a named set nor channels joined by ``+``."""
    bad = [n for n in names if n not in SENSOR_SETS and not _CUSTOM.match(n)]
    if bad or not names:
        raise InputError(
            describe(
                what,
                bad or list(names),
                f"{', '.join(SENSOR_SETS)}, or analog channels joined by '+' (P_In+X_DNC)",
            )
        )


def sensor_set_channels(name: str, analog: Sequence[str]) -> tuple[str, ...] | None:
    """The analog channels of the set ``name`` on a machine with channels ``analog``.

    None when the machine lacks the set: ``line-flows`` needs a line flow meter and a
    supply flow meter to leave out (without ``Q_In`` it is ``full``); ``supply-only``
    needs ``P_In`` and ``Q_In``; ``pressure-only`` needs ``P_In``; a custom set needs
    each of its channels; ``full`` is every analog channel (None when there is none).

    Examples
    --------
    >>> ch = ("P_In", "Q_In", "P_DNC_A", "Q_DNC_A", "X_DNC")
    >>> sensor_set_channels("line-flows", ch)
    ('P_In', 'P_DNC_A', 'Q_DNC_A', 'X_DNC')
    >>> sensor_set_channels("pressure-only", ch), sensor_set_channels("digital-only", ch)
    (('P_In',), ())
    >>> sensor_set_channels("line-flows", ("P_In", "Q_In")) is None
    True
    >>> sensor_set_channels("P_In+X_DNC", ch)
    ('P_In', 'X_DNC')
    """
    channels = tuple(analog)
    if name == "full":
        return channels or None
    if name == "line-flows":
        flows = any(c.startswith("Q_") and is_line_sensor(c) for c in channels)
        return tuple(c for c in channels if c != "Q_In") if flows and "Q_In" in channels else None
    if name == "supply-only":
        return SUPPLY_CHANNELS if all(c in channels for c in SUPPLY_CHANNELS) else None
    if name == "pressure-only":
        return ("P_In",) if "P_In" in channels else None
    if name == "digital-only":
        return ()
    check_sensor_set_names([name])
    wanted = tuple(name.split("+"))
    return wanted if all(c in channels for c in wanted) else None


def machine_sensor_sets(analog: Sequence[str], names: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """The analog channels of each named set a machine with channels ``analog`` has.

    ``full`` is left out when it holds supply channels only (then it is
    ``supply-only`` or ``pressure-only``).

    Examples
    --------
    >>> machine_sensor_sets(("P_In", "Q_In"), ["full", "line-flows", "pressure-only"])
    {'pressure-only': ('P_In',)}
    """
    sets: dict[str, tuple[str, ...]] = {}
    for name in names:
        channels = sensor_set_channels(name, analog)
        if channels is not None and not (name == "full" and set(channels) <= set(SUPPLY_CHANNELS)):
            sets[name] = channels
    return sets


def sensor_set_kind(channels: Sequence[str]) -> str:
    """The kind of set ``channels`` are (one of :data:`SENSOR_SETS`).

    Examples
    --------
    >>> sensor_set_kind(["P_In", "Q_CYL_A", "Q_CYL_B", "X_CYL"])
    'line-flows'
    >>> sensor_set_kind(["P_In"]), sensor_set_kind([]), sensor_set_kind(["Q_In"])
    ('pressure-only', 'digital-only', 'supply-only')
    """
    chosen = set(channels)
    line = any(is_line_sensor(c) for c in chosen)
    if not chosen:
        return "digital-only"
    if "Q_In" in chosen:
        return "full" if line else "supply-only"
    if line:
        return "line-flows"
    return "pressure-only"


@dataclass(frozen=True)
class SensorSetReport:
    """What a reference's sensor set can and cannot find.

    Attributes
    ----------
    kind : str
        One of :data:`SENSOR_SETS`.
    channels : tuple of str
        The analog channels.
    can : str
        What it locates and sizes (as measured on the built-in machines' plants).
    cannot : str
        What it cannot, or only poorly.
    """

    kind: str
    channels: tuple[str, ...]
    can: str
    cannot: str

    def lines(self) -> list[str]:
        """The report, one line per fact."""
        shown = ", ".join(self.channels) or "none (PLC signals only)"
        return [
            f"sensor set {self.kind} (analog channels: {shown})",
            f"  can: {self.can}",
            f"  cannot: {self.cannot}",
            "  (measured on plants of the built-in machines: docs/sensor-sets.md)",
        ]

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form (the ``sensor_set`` entry of ``diagnose --json``)."""
        return {
            "kind": self.kind,
            "channels": list(self.channels),
            "can": self.can,
            "cannot": self.cannot,
            "measured": "docs/sensor-sets.md",
        }


_STATEMENTS: dict[str, tuple[str, str]] = {
    "full": (
        "detect, locate and size leaks at the supply and on every actuator line",
        "nothing the other sets can (it is their union)",
    ),
    "line-flows": (
        "detect, locate and size leaks on actuator lines and at the supply from the line "
        "meters, pressures and positions (festo-dsd: 96 % located in the group, size error "
        "median 5 %, p90 17 %)",
        "measure the machine's air (no supply flow meter): a leak on a line without its own "
        "meter is located through pressures and step times only and reads like a spool leak "
        "to exhaust; two leaks at once are found less often (72 % of pairs on festo-dsd)",
    ),
    "supply-only": (
        "detect, locate and size leaks from the supply's pressure and flow, each step's air "
        "telling the lines apart (festo-dsd: 100 % located in the group, size error median "
        "1.6 %, p90 6 %)",
        "tell apart lines that are pressurised and exhausted in the same steps, nor see one "
        "actuator's chamber or position directly",
    ),
    "pressure-only": (
        "detect leaks and locate most from the supply pressure's sag per step and the step "
        "times (festo-dsd: 99 % located in the group, size error median 5 %, p90 17 %)",
        "measure air: sizes rest on the pressure and the twin's model, a small leak hides in "
        "a coarse pressure quantum, and two leaks at once are found less often (75 % of "
        "pairs on festo-dsd)",
    ),
    "digital-only": (
        "detect leaks that slow or speed a stroke, from the step times alone (festo-dsd: "
        "92 % detected, 91 % located in the group)",
        "see a leak that changes no stroke's time, nor size one better than its effect on "
        "the timing (size error median 9 %, p90 29 % on festo-dsd)",
    ),
}


def sensor_set_report(channels: Sequence[str]) -> SensorSetReport:
    """What the sensor set of ``channels`` can and cannot locate or size.

    Examples
    --------
    >>> sensor_set_report(["P_In", "Q_In"]).kind
    'supply-only'
    """
    kind = sensor_set_kind(channels)
    can, cannot = _STATEMENTS[kind]
    return SensorSetReport(kind, tuple(channels), can, cannot)
