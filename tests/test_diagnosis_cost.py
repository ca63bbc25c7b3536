"""Leak cost by eq. 1.1, the equivalent sharp-edged orifice and the leak findings."""

from __future__ import annotations

import math

import pytest

from pneufdd.diagnosis.cost import (
    COST_BASIS_AVERAGE,
    COST_BASIS_CONTINUOUS,
    CostSettings,
    annual_cost,
    cost_leaks,
    equivalent_orifice,
)
from pneufdd.diagnosis.findings import LeakFinding
from pneufdd.errors import InputError
from pneufdd.physics.units import kg_s_to_scfm, kg_s_to_slpm, psig_to_pa, scfm_to_kg_s


def test_eq_1_1_by_hand():
    # 10 cfm at 18 kW / 100 cfm, 7000 h, $0.05 / kWh: 10 * 0.18 * 7000 * 0.05 = $630
    assert annual_cost(scfm_to_kg_s(10.0), CostSettings()) == pytest.approx(630.0, rel=1e-12)
    custom = CostSettings(hours=8760.0, price_per_kwh=0.12, kw_per_100_cfm=22.0)
    assert annual_cost(scfm_to_kg_s(3.0), custom) == pytest.approx(
        3.0 * 0.22 * 8760.0 * 0.12, rel=1e-12
    )


def test_section_1_1_example_total():
    # 100 leaks of 1/32 in and 50 of 1/16 in at 90 psig, 10 of 1/4 in at 100 psig,
    # sharp-edged (x 0.61 of Figure 1.2), 7000 h, $0.05/kWh, 18 kW/100 cfm: $57,069.
    flows = [1.46] * 100 + [5.72] * 50 + [100.9] * 10
    pressures = [psig_to_pa(90.0)] * 150 + [psig_to_pa(100.0)] * 10
    _, total = cost_leaks(
        ["x"] * 160,
        [scfm_to_kg_s(0.61 * f) for f in flows],
        pressures,
        [1.0] * 160,
        [("x",)] * 160,
        CostSettings(),
    )
    assert total == pytest.approx(57_069.0, rel=0.05)


@pytest.mark.parametrize(
    ("inch", "psig", "cfm"),
    [(1 / 64, 70, 0.29), (1 / 16, 90, 5.72), (1 / 4, 100, 100.9), (3 / 8, 125, 275.5)],
)
def test_orifice_inverts_figure_1_2(inch, psig, cfm):
    # Figure 1.2 gives flows of well-rounded orifices (Cd ~ 1); the sharp-edged flow
    # is x 0.61, so the equivalent sharp-edged diameter of that flow is the table's.
    d = equivalent_orifice(scfm_to_kg_s(0.61 * cfm), psig_to_pa(psig))
    assert d == pytest.approx(0.0254 * inch, rel=0.07)


def test_orifice_scales_with_square_root_of_flow():
    d1 = equivalent_orifice(1e-3, 6e5)
    d4 = equivalent_orifice(4e-3, 6e5)
    assert d4 == pytest.approx(2 * d1, rel=1e-12)


def test_ranking_and_total():
    leaks, total = cost_leaks(
        ["a", "b", "c"],
        [1e-4, 3e-3, 1e-3],
        [6e5] * 3,
        [1.0] * 3,
        [("a",), ("b",), ("c",)],
        CostSettings(),
    )
    assert [leak.location for leak in leaks] == ["b", "c", "a"]
    assert math.isclose(total, sum(leak.annual_cost for leak in leaks))
    assert leaks[0].flow_slpm == pytest.approx(3e-3 / 1.294 * 60_000.0)
    assert kg_s_to_scfm(leaks[0].mass_flow) > 0


def test_bad_settings_rejected():
    with pytest.raises(InputError, match="hours"):
        CostSettings(hours=-1.0)


def test_cost_is_eq_1_1_of_the_average_flow():
    # a 55 SLPM rod-side leak losing 4.5 SLPM on average over the cycle
    nominal, average = 55.0 * 1.294 / 60_000.0, 4.5 * 1.294 / 60_000.0
    settings = CostSettings(hours=6000.0, price_per_kwh=0.1, kw_per_100_cfm=20.0)
    (leak,), total = cost_leaks(
        ["DNC_B"], [nominal], [6e5], [1.0], [("DNC_B",)], settings, [average]
    )
    cfm = kg_s_to_scfm(average)
    assert leak.annual_cost == pytest.approx(cfm * 0.20 * 6000.0 * 0.1, rel=1e-12)
    assert total == leak.annual_cost
    assert leak.flow_slpm == pytest.approx(55.0, rel=1e-12)  # nominal flow unchanged
    assert leak.average_flow_slpm == pytest.approx(4.5, rel=1e-12)
    assert leak.orifice_diameter == equivalent_orifice(nominal, 6e5)
    assert leak.orifice_mm == pytest.approx(1e3 * equivalent_orifice(nominal, 6e5), rel=1e-12)
    assert leak.cost_basis == COST_BASIS_AVERAGE
    # linear in the average flow
    (double,), _ = cost_leaks(
        ["DNC_B"], [nominal], [6e5], [1.0], [("DNC_B",)], settings, [2 * average]
    )
    assert double.annual_cost == pytest.approx(2 * leak.annual_cost, rel=1e-12)


def test_ranking_follows_the_cost_not_the_nominal_flow():
    # the rod-side leak is larger but loses less air than the supply leak
    leaks, total = cost_leaks(
        ["supply", "DNC_B"],
        [6.0e-4, 1.2e-3],
        [6e5, 6e5],
        [1.0, 1.0],
        [("supply",), ("DNC_B",)],
        CostSettings(),
        [5.8e-4, 9.0e-5],
    )
    assert [leak.location for leak in leaks] == ["supply", "DNC_B"]
    assert total == pytest.approx(annual_cost(5.8e-4 + 9.0e-5, CostSettings()), rel=1e-12)


def test_unknown_average_assumes_continuous_leakage():
    leaks, _ = cost_leaks(
        ["a", "b"],
        [1e-3, 1e-3],
        [6e5, 6e5],
        [1.0, 1.0],
        [("a",), ("b",)],
        CostSettings(),
        [None, 1e-4],
    )
    by = {leak.location: leak for leak in leaks}
    assert by["a"].cost_basis == COST_BASIS_CONTINUOUS
    assert by["a"].annual_cost == pytest.approx(annual_cost(1e-3, CostSettings()), rel=1e-12)
    assert by["a"].average_flow_slpm == by["a"].flow_slpm
    assert by["b"].annual_cost == pytest.approx(0.1 * by["a"].annual_cost, rel=1e-12)
    with pytest.raises(InputError, match="average leak flow at b"):
        cost_leaks(["b"], [1e-3], [6e5], [1.0], [("b",)], CostSettings(), [-1.0])


def test_orifice_needs_a_pressure_above_the_atmosphere():
    assert equivalent_orifice(-1e-3, 6e5) == 0.0  # a negative flow counts as none
    with pytest.raises(InputError, match="leak pressure"):
        equivalent_orifice(1e-3, 101325.0)


def test_finding_holds_si_and_reads_slpm_and_mm():
    # the engineer's units are computed from the SI values with the arithmetic the
    # CLI, the JSON and the report always used: kg_s_to_slpm and x 1e3
    (leak,), _ = cost_leaks(
        ["DNC_B"],
        [1.2e-3],
        [6e5],
        [0.8],
        [("DNC_B", "supply")],
        CostSettings(),
        [6.0e-5],
        [(1.2e-3, 1.1e-3)],
    )
    assert isinstance(leak, LeakFinding)
    assert (leak.mass_flow, leak.average_mass_flow) == (1.2e-3, 6.0e-5)
    assert leak.flow_slpm == float(kg_s_to_slpm(1.2e-3))
    assert leak.flow_slpm == pytest.approx(1.2e-3 / 1.294 * 60_000.0, rel=1e-12)
    assert leak.average_flow_slpm == float(kg_s_to_slpm(6.0e-5))
    assert leak.orifice_mm == 1e3 * leak.orifice_diameter
    assert 1e-3 < leak.orifice_diameter < 3e-3  # a 56 SLPM leak at 6 bar: about 1.6 mm
    assert leak.ambiguity_group == ("DNC_B", "supply")
    assert leak.group_mass_flows == (1.2e-3, 1.1e-3)
    assert leak.confidence == 0.8
    # without group flows they are unknown, not made up
    (bare,), _ = cost_leaks(["a"], [1e-3], [6e5], [1.0], [("a",)], CostSettings())
    assert bare.group_mass_flows == ()
    with pytest.raises(AttributeError):
        leak.flow_slpm = 1.0  # type: ignore[misc]
