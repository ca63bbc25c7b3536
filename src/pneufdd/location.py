"""Where a leak can be: the supply, or one line of one actuator.

A machine's air reaches its actuators through the supply (house air, regulator,
supply line with the flow meter, valve-terminal manifold) and then, per actuator,
through two lines from its directional valve: the **extend line** to chamber A (the
blind side; ``<ACT>_A``) and the **retract line** to chamber B (the rod side;
``<ACT>_B``). Section 5.3.1 of the dissertation locates a leak at one of these
places; this module gives them a type, so no code recognises a location by the
suffix of a string.

Examples
--------
>>> loc = Location.parse("HMPL_V_B")
>>> loc.actuator, loc.side, loc.is_supply, str(loc)
('HMPL_V', 'B', False, 'HMPL_V_B')
>>> loc.other_line()
Location(actuator='HMPL_V', side='A')
>>> SUPPLY.is_supply, str(SUPPLY)
(True, 'supply')
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

from pneufdd.errors import InputError, describe

__all__ = ["SUPPLY", "Location", "locations_of"]

Side = Literal["A", "B"]

SUPPLY_NAME = "supply"


@dataclass(frozen=True)
class Location:
    """A leak location: the supply (both fields None) or one line of an actuator.

    Attributes
    ----------
    actuator : str or None
        Actuator id (``"DNC"``); None for the supply.
    side : {"A", "B"} or None
        ``"A"``: extend line, chamber A (blind side); ``"B"``: retract line, chamber B
        (rod side); None for the supply.
    """

    actuator: str | None = None
    side: Side | None = None

    def __post_init__(self) -> None:
        if (self.actuator is None) != (self.side is None):
            raise InputError(
                describe(
                    "leak location",
                    f"actuator={self.actuator!r}, side={self.side!r}",
                    "both None (the supply) or an actuator id with side 'A' or 'B'",
                )
            )
        if self.side is not None and self.side not in ("A", "B"):
            raise InputError(describe("leak location side", self.side, ["A", "B"]))
        if self.actuator is not None and (not self.actuator or self.actuator == SUPPLY_NAME):
            raise InputError(
                describe("leak location actuator", self.actuator, "an actuator id (not 'supply')")
            )

    @classmethod
    def parse(cls, text: str) -> Location:
        """The location named ``supply``, ``<ACT>_A`` or ``<ACT>_B``."""
        if not isinstance(text, str):
            raise InputError(describe("leak location", text, "'supply', '<ACT>_A' or '<ACT>_B'"))
        if text == SUPPLY_NAME:
            return SUPPLY
        actuator, sep, side = text.rpartition("_")
        if not sep or not actuator or side not in ("A", "B"):
            raise InputError(describe("leak location", text, "'supply', '<ACT>_A' or '<ACT>_B'"))
        return cls(actuator, side)  # type: ignore[arg-type]

    @property
    def is_supply(self) -> bool:
        """True for the supply (manifold) location."""
        return self.actuator is None

    def other_line(self) -> Location:
        """The other line of the same actuator.

        Raises
        ------
        InputError
            For the supply, which has no other line.
        """
        if self.actuator is None:
            raise InputError(describe("location", SUPPLY_NAME, "an actuator line"))
        return Location(self.actuator, "B" if self.side == "A" else "A")

    def same_actuator(self, other: Location) -> bool:
        """True when both are lines of one actuator (not the supply)."""
        return self.actuator is not None and self.actuator == other.actuator

    def is_other_line(self, other: Location) -> bool:
        """True when ``other`` is this actuator's other line (extend against retract).

        >>> Location("DNC", "A").is_other_line(Location("DNC", "B"))
        True
        >>> Location("DNC", "A").is_other_line(Location("DNC", "A")), SUPPLY.is_other_line(SUPPLY)
        (False, False)
        """
        return self.same_actuator(other) and self.side != other.side

    def __str__(self) -> str:
        return SUPPLY_NAME if self.actuator is None else f"{self.actuator}_{self.side}"


SUPPLY = Location()
"""The supply: the manifold downstream of the supply flow meter."""


def locations_of(actuators: Iterable[str]) -> tuple[Location, ...]:
    """``supply`` then both lines of every actuator, in order.

    Examples
    --------
    >>> [str(x) for x in locations_of(["DNC", "SLT"])]
    ['supply', 'DNC_A', 'DNC_B', 'SLT_A', 'SLT_B']
    """
    out = [SUPPLY]
    for actuator in actuators:
        out += [Location(actuator, "A"), Location(actuator, "B")]
    return tuple(out)
