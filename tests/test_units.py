"""Unit conversions: published reference densities and exact round trips."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import UnitError
from pneufdd.physics import constants, units


def test_standard_densities_are_the_published_ones() -> None:
    assert constants.DISSERTATION_STANDARD.density == 1.294  # section 3.4.1
    assert constants.ANR.density == 1.185  # ISO 8778
    # CAGI standard air: 0.075 lb/ft^3
    assert constants.CAGI_SCFM.density == pytest.approx(1.2014, abs=1e-4)
    # ISA scfh basis: 60 degF, 14.73 psia, ideal gas
    assert constants.ISA_STANDARD.density == pytest.approx(1.2255, abs=2e-4)


def test_one_slpm_is_one_standard_litre_per_minute() -> None:
    assert units.slpm_to_kg_s(60.0) == pytest.approx(1.294e-3)


def test_gauge_conversions_invert() -> None:
    assert units.psig_to_pa(0.0) == constants.P_ATM
    assert units.pa_to_bar_gauge(units.bar_gauge_to_pa(5.5)) == pytest.approx(5.5)
    # 80 psig is about 5.5 bar(g) (section 3.2.1)
    assert units.pa_to_bar_gauge(units.psig_to_pa(80.0)) == pytest.approx(5.516, abs=1e-3)


@given(st.floats(min_value=0.0, max_value=1e4, allow_nan=False))
def test_flow_round_trips(flow: float) -> None:
    assert units.kg_s_to_slpm(units.slpm_to_kg_s(flow)) == pytest.approx(flow, rel=1e-12)
    assert units.kg_s_to_scfm(units.scfm_to_kg_s(flow)) == pytest.approx(flow, rel=1e-12)


def test_to_si_converts_and_names_si_unit() -> None:
    values, unit = units.to_si(np.array([0.0, 200.0]), "SLPM")
    assert unit == "kg/s"
    np.testing.assert_allclose(values, [0.0, 200.0 * 1.294e-3 / 60.0])


@pytest.mark.parametrize("bad", ["psi", "lpm", "cfm", "furlong"])
def test_unknown_or_ambiguous_unit_is_refused_with_allowed_list(bad: str) -> None:
    with pytest.raises(UnitError, match="allowed") as info:
        units.to_si([1.0], bad, where="of channel 'P_In'")
    assert bad in str(info.value)
    assert "P_In" in str(info.value)
