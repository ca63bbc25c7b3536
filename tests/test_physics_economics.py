"""Acceptance tests of pneufdd.physics.economics: eq. 1.1 and Figure 1.2."""

from __future__ import annotations

import numpy as np
import pytest

from pneufdd.errors import InputError
from pneufdd.physics import (
    FIGURE_1_2_CFM,
    figure_1_2_leak_rate,
    kg_s_to_scfm,
    leak_annual_cost,
    scfm_to_kg_s,
)
from pneufdd.physics.economics import FIGURE_1_2_DIAMETERS_IN


def test_section_1_1_example_from_the_table() -> None:
    """100 x 1/32 in and 50 x 1/16 in at 90 psig, 10 x 1/4 in at 100 psig, sharp-edged,
    7000 h, $0.05/kWh, 18 kW per 100 cfm: the dissertation states $57,069."""
    total = (
        leak_annual_cost(figure_1_2_leak_rate(90, 1 / 32, "sharp"), count=100)
        + leak_annual_cost(figure_1_2_leak_rate(90, 1 / 16, "sharp"), count=50)
        + leak_annual_cost(figure_1_2_leak_rate(100, 1 / 4, "sharp"), count=10)
    )
    # by hand: (100*1.46 + 50*5.72 + 10*100.9) * 0.61 * 0.18 * 7000 * 0.05 = 55,377.63
    assert total == pytest.approx(55_377.63, abs=0.01)
    assert total == pytest.approx(57_069.0, rel=0.05)  # measured -2.96 %


def test_section_1_1_example_from_the_orifice_law() -> None:
    """Same example with flows from eq. 4.3 (Cd = 0.61, 293.15 K, CAGI scfm) instead."""
    import math

    from pneufdd.physics import P_ATM, orifice_mass_flow, psig_to_pa

    def sharp(psig: float, d_in: float) -> float:
        area = math.pi / 4 * (d_in * 0.0254) ** 2
        return orifice_mass_flow(psig_to_pa(psig), P_ATM, area, 0.61, 293.15)

    total = (
        leak_annual_cost(sharp(90, 1 / 32), count=100)
        + leak_annual_cost(sharp(90, 1 / 16), count=50)
        + leak_annual_cost(sharp(100, 1 / 4), count=10)
    )
    assert total == pytest.approx(57_211.27, abs=0.01)
    assert total == pytest.approx(57_069.0, rel=0.005)  # measured +0.25 %


def test_cost_formula_and_defaults() -> None:
    one_scfm = scfm_to_kg_s(1.0)
    assert leak_annual_cost(one_scfm) == pytest.approx(0.18 * 7000 * 0.05, rel=1e-12)
    assert leak_annual_cost(
        one_scfm, hours=8760, energy_price=0.12, kw_per_100_cfm=20, count=3
    ) == (pytest.approx(3 * 0.2 * 8760 * 0.12, rel=1e-12))
    costs = leak_annual_cost(np.array([0.0, one_scfm, 2 * one_scfm]))
    assert isinstance(costs, np.ndarray)
    np.testing.assert_allclose(costs, [0.0, 63.0, 126.0], rtol=1e-12)


def test_figure_1_2_table_as_data_and_factors() -> None:
    assert sorted(FIGURE_1_2_CFM) == [70.0, 80.0, 90.0, 100.0, 125.0]
    assert all(len(row) == 6 for row in FIGURE_1_2_CFM.values())
    assert FIGURE_1_2_DIAMETERS_IN == (1 / 64, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 3 / 8)
    assert kg_s_to_scfm(figure_1_2_leak_rate(125, 3 / 8)) == pytest.approx(275.5, rel=1e-12)
    assert kg_s_to_scfm(figure_1_2_leak_rate(70, 1 / 64, "rounded")) == pytest.approx(
        0.29 * 0.97, rel=1e-12
    )
    assert kg_s_to_scfm(figure_1_2_leak_rate(90, 1 / 4, "sharp")) == pytest.approx(
        92 * 0.61, rel=1e-12
    )


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: figure_1_2_leak_rate(85, 1 / 4), "pressure_psig"),
        (lambda: figure_1_2_leak_rate(90, 0.2), "diameter_in"),
        (lambda: figure_1_2_leak_rate(90, 1 / 4, "jagged"), "orifice"),
        (lambda: leak_annual_cost(-1.0), "mass_flow"),
        (lambda: leak_annual_cost(1.0, hours=-5), "hours"),
        (lambda: leak_annual_cost(1.0, count=-1), "count"),
    ],
)
def test_bad_input_names_the_parameter(call, name: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=f"'{name}'"):
        call()
