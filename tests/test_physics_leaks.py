"""Acceptance tests of pneufdd.physics.leaks: the GR-3/8B valve and leak sizes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import InputError
from pneufdd.physics import (
    P_ATM,
    bar_gauge_to_pa,
    equivalent_orifice_diameter,
    kg_s_to_slpm,
    leak_area,
    leak_mass_flow,
    leak_mass_flow_kernel,
    leak_valve_area,
    orifice_mass_flow,
    turns_for_area,
)
from pneufdd.physics.leaks import LEAK_VALVE_MAX_AREA
from pneufdd.physics.units import kg_s_to_l_min_anr


def test_leak_valve_rating_at_20_turns() -> None:
    # Festo convention: standard nominal flow 6 -> 5 bar(g), ANR basis, 20 degC
    flow = orifice_mass_flow(bar_gauge_to_pa(6.0), bar_gauge_to_pa(5.0), leak_valve_area(20.0))
    assert kg_s_to_l_min_anr(flow) == pytest.approx(1000.0, rel=1e-10)
    assert leak_valve_area(20.0) == pytest.approx(16.62e-6, rel=1e-3)
    # to atmosphere at 5 bar(g) the full valve leaks ~1094 SLPM
    assert kg_s_to_slpm(leak_mass_flow(bar_gauge_to_pa(5.0), leak_valve_area(20.0))) == (
        pytest.approx(1093.8, abs=0.1)
    )


def test_leak_valve_span_of_the_experiments() -> None:
    p = bar_gauge_to_pa(5.0)
    slpm = [kg_s_to_slpm(leak_mass_flow(p, leak_valve_area(n))) for n in range(1, 7)]
    # 1 to 6 turns at 5 bar(g) to atmosphere: 10-200 SLPM (meters top out at 200)
    assert slpm[0] == pytest.approx(11.3, abs=0.05)
    assert slpm[-1] == pytest.approx(200.0, abs=0.05)
    assert 8.0 < slpm[0] < 15.0
    assert 180.0 < slpm[-1] <= 200.05
    # nonlinear, convex like Figs 3.13/3.14: increments grow with each turn
    assert np.all(np.diff(slpm, 2) > 0)
    assert leak_valve_area(0.0) == 0.0
    assert leak_valve_area(0.2) == 0.0  # inside the dead band


@given(a=st.floats(0.0, 20.0), b=st.floats(0.0, 20.0))
def test_leak_valve_monotone(a: float, b: float) -> None:
    lo, hi = sorted((a, b))
    assert leak_valve_area(lo) <= leak_valve_area(hi)
    if hi > max(lo, 0.3):
        assert leak_valve_area(lo) < leak_valve_area(hi)


@given(turns=st.floats(0.31, 20.0))
def test_turns_round_trip(turns: float) -> None:
    assert turns_for_area(leak_valve_area(turns)) == pytest.approx(turns, rel=1e-9)


def test_leak_area_units() -> None:
    assert leak_area(3.0, "turns") == leak_valve_area(3.0)
    assert leak_area(2.0, "mm") == pytest.approx(0.61 * math.pi / 4 * 0.002**2, rel=1e-12)
    p = bar_gauge_to_pa(4.0)
    area = leak_area(50.0, "SLPM", reference_pressure=p)
    assert kg_s_to_slpm(leak_mass_flow(p, area)) == pytest.approx(50.0, rel=1e-12)
    areas = leak_area([0.0, 1.0], "mm")
    assert isinstance(areas, np.ndarray)
    assert areas[0] == 0.0


def test_equivalent_diameter_inverts_the_sharp_hole() -> None:
    p = bar_gauge_to_pa(np.array([1.0, 6.0]))
    flows = leak_mass_flow(p, leak_area(np.array([0.5, 3.0]), "mm"))
    np.testing.assert_allclose(equivalent_orifice_diameter(flows, p), [0.5e-3, 3e-3], rtol=1e-12)


def test_leak_flow_kernel_and_inflow() -> None:
    p = bar_gauge_to_pa(5.0)
    assert leak_mass_flow_kernel(p, 2e-6, 293.15) == leak_mass_flow(p, 2e-6)
    assert leak_mass_flow(P_ATM, 2e-6) == 0.0
    assert leak_mass_flow(0.5 * P_ATM, 2e-6) < 0.0


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: leak_valve_area(-0.5), "turns"),
        (lambda: leak_valve_area(20.5), "turns"),
        (lambda: turns_for_area(2 * LEAK_VALVE_MAX_AREA), "area"),
        (lambda: leak_area(1.0, "inch"), "unit"),
        (lambda: leak_area(10.0, "SLPM"), "reference_pressure"),
        (lambda: leak_area(10.0, "SLPM", reference_pressure=9e4), "reference_pressure"),
        (lambda: leak_area(1.0, "mm", reference_pressure=6e5), "reference_pressure"),
        (lambda: leak_area(-1.0, "mm"), "value"),
        (lambda: equivalent_orifice_diameter(1e-3, P_ATM), "pressure"),
    ],
)
def test_bad_input_names_the_parameter(call, name: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=f"'{name}'"):
        call()
