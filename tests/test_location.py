"""Leak locations as a type: the supply, or one line of one actuator."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import InputError
from pneufdd.location import SUPPLY, Location, locations_of

IDS = st.from_regex(r"[A-Z][A-Z0-9_]{0,10}[A-Z0-9]", fullmatch=True)


@given(IDS, st.sampled_from(["A", "B"]))
def test_parse_is_the_inverse_of_str(actuator, side):
    loc = Location(actuator, side)
    assert Location.parse(str(loc)) == loc
    assert loc.other_line().other_line() == loc
    assert loc.other_line().side != side
    assert loc.same_actuator(loc.other_line())
    assert not loc.is_supply


def test_supply():
    assert Location.parse("supply") is SUPPLY
    assert SUPPLY.is_supply
    assert not SUPPLY.same_actuator(SUPPLY)
    with pytest.raises(InputError, match="actuator line"):
        SUPPLY.other_line()


@pytest.mark.parametrize("text", ["", "DNC", "DNC_C", "_A", "supply_A", "dnc-b"])
def test_bad_names_are_refused_with_the_name(text):
    with pytest.raises(InputError, match="leak location"):
        Location.parse(text)


def test_half_locations_are_refused():
    with pytest.raises(InputError, match="both None"):
        Location("DNC", None)
    with pytest.raises(InputError, match="side"):
        Location("DNC", "C")  # type: ignore[arg-type]


def test_locations_of_a_machine():
    assert [str(x) for x in locations_of(["DNC", "HMPL_V"])] == [
        "supply", "DNC_A", "DNC_B", "HMPL_V_A", "HMPL_V_B",
    ]  # fmt: skip
