"""The fault and nuisance laws of pneufdd.physics.faults against their sources and invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import InputError
from pneufdd.physics.constants import P_ATM
from pneufdd.physics.faults import (
    BASE_OIL_NU40,
    BASE_OIL_NU100,
    cushion_engaged_kernel,
    cushioned_exhaust_cv,
    header_dip_kernel,
    header_dip_profile,
    lubricant_viscosity_ratio,
    pilot_delay_factor_kernel,
    regulator_outlet_pressure_kernel,
    seal_friction_temperature_factors,
    seal_leak_mass_flow,
    throttled_cv,
    worn_friction,
)
from pneufdd.physics.flow import isa_mass_flow, orifice_mass_flow
from pneufdd.physics.leaks import leak_area
from pneufdd.physics.restrictions import series_cv
from pneufdd.physics.units import bar_gauge_to_pa, kg_s_to_slpm, psig_to_pa

pressures = st.floats(min_value=P_ATM, max_value=1.2e6)


@given(pressures, pressures)
def test_seal_leak_is_the_orifice_law_and_conserves_mass(p1: float, p2: float) -> None:
    area = 3e-7
    forward = float(seal_leak_mass_flow(p1, p2, area, 300.0, 280.0))
    backward = float(seal_leak_mass_flow(p2, p1, area, 280.0, 300.0))
    assert forward == -backward  # what one volume loses the other gains
    upstream_t = 300.0 if p1 >= p2 else 280.0
    expected = orifice_mass_flow(max(p1, p2), min(p1, p2), area, 1.0, upstream_t)
    assert abs(forward) == pytest.approx(expected, rel=1e-12, abs=0.0)
    assert (forward > 0) == (p1 > p2)


def test_seal_leak_sized_in_slpm_passes_that_flow_to_the_atmosphere() -> None:
    # the size convention of the catalogue: the flow from the nominal pressure to the
    # atmosphere (here the rig's 72 psig), like a leak
    p_nom = psig_to_pa(72.0)
    area = leak_area(20.0, "SLPM", reference_pressure=p_nom)
    assert kg_s_to_slpm(seal_leak_mass_flow(p_nom, P_ATM, area)) == pytest.approx(20.0, rel=1e-9)
    # choked down to the critical ratio 0.528: the flow does not depend on P2 there
    low = 0.5 * p_nom
    assert seal_leak_mass_flow(p_nom, low, area) == pytest.approx(
        seal_leak_mass_flow(p_nom, P_ATM, area), rel=1e-12
    )


def test_a_throttle_scales_the_exhaust_flow_by_its_series_cv() -> None:
    # eq. 4.6 is linear in Cv: the path's flow at fixed pressures scales by the ratio of
    # the series Cvs (valve, tube, throttle), the throttle's own by 1 + change/100
    valve, tube, meter = 0.3971, 0.3236, 0.125
    p1, p2 = bar_gauge_to_pa(3.0), P_ATM
    for change in (-60.0, -30.0, 50.0):
        healthy = series_cv(valve, tube, meter)
        faulty = series_cv(valve, tube, throttled_cv(meter, change))
        ratio = isa_mass_flow(p1, p2, faulty) / isa_mass_flow(p1, p2, healthy)
        assert ratio == pytest.approx(faulty / healthy, rel=1e-12)
        assert isa_mass_flow(p1, p2, throttled_cv(meter, change)) == pytest.approx(
            (1 + change / 100) * isa_mass_flow(p1, p2, meter), rel=1e-12
        )
    with pytest.raises(InputError, match="change_percent"):
        throttled_cv(meter, -100.0)


def test_worn_friction_scales_and_adds_to_both_terms() -> None:
    assert worn_friction(150.0, 158.6, change_percent=80.0) == pytest.approx((270.0, 285.48))
    assert worn_friction(150.0, 158.6, added_n=20.0) == pytest.approx((170.0, 178.6))
    with pytest.raises(InputError, match="forces >= 0"):
        worn_friction(150.0, 158.6, added_n=-200.0)


def test_the_viscosity_law_returns_its_source_numbers() -> None:
    # ASTM D341 (Walther) through the ISO VG 32 base oil's 40 and 100 degC viscosities
    to40 = lubricant_viscosity_ratio(373.15, 313.15)
    assert to40 * BASE_OIL_NU40 == pytest.approx(BASE_OIL_NU100, rel=1e-12)
    assert 28.8 <= BASE_OIL_NU40 <= 35.2  # ISO 3448: VG 32 is 28.8-35.2 mm^2/s at 40 degC
    # the Walther form: log log (nu + 0.7) is linear in log T, so any three
    # temperatures lie on one line
    temps = np.array([283.15, 303.15, 343.15])
    nu = np.asarray(lubricant_viscosity_ratio(temps, 313.15)) * BASE_OIL_NU40
    z = np.log10(np.log10(nu + 0.7))
    slope = np.diff(z) / np.diff(np.log10(temps))
    assert slope[0] == pytest.approx(slope[1], rel=1e-9)
    assert np.all(np.diff(nu) < 0)  # thinner when warmer


def test_seal_friction_factors_at_the_reference_and_away_from_it() -> None:
    assert seal_friction_temperature_factors(293.15, 293.15) == (1.0, 1.0)
    coulomb, viscous = seal_friction_temperature_factors(308.15, 293.15)
    assert coulomb == pytest.approx(math.exp(-0.005 * 15.0))
    # the film's shear grows with sqrt(viscosity) (inverse hydrodynamic lubrication)
    assert viscous == pytest.approx(math.sqrt(float(lubricant_viscosity_ratio(308.15, 293.15))))
    cold = seal_friction_temperature_factors(278.15, 293.15)
    assert cold[0] > 1.0  # Festo: breakaway friction rises in the cold
    assert cold[1] > 1.0
    with pytest.raises(InputError):
        seal_friction_temperature_factors(300.0, 293.15, coulomb_per_k=0.2)


@given(st.floats(min_value=3.05e5, max_value=8e5), st.floats(min_value=3.0e5, max_value=8e5))
def test_pilot_factor_grows_as_the_margin_shrinks(p_supply: float, p_min: float) -> None:
    factor = pilot_delay_factor_kernel(p_supply, 3e5, p_min)
    if p_supply <= p_min:
        assert factor == math.inf
    else:
        assert factor >= 1.0
        assert factor == pytest.approx(math.sqrt((p_supply - 3e5) / (p_supply - p_min)))
        # more supply, less delay
        assert pilot_delay_factor_kernel(p_supply + 1e4, 3e5, p_min) <= factor
    assert pilot_delay_factor_kernel(p_supply, 3e5, 2e5) == 1.0  # a healthy pilot


def test_cushion_zones_and_series_cv() -> None:
    stroke, length = 0.2, 0.02
    assert cushion_engaged_kernel(0.019, stroke, length, 0.0)
    assert not cushion_engaged_kernel(0.021, stroke, length, 0.0)
    assert cushion_engaged_kernel(0.181, stroke, length, 1.0)
    assert not cushion_engaged_kernel(0.179, stroke, length, 1.0)
    assert not cushion_engaged_kernel(0.0, stroke, 0.0, 0.0)  # no cushioning
    exhaust = series_cv(0.3971, 0.3236, 0.125)
    engaged = cushioned_exhaust_cv(exhaust, 0.012)
    assert engaged < min(exhaust, 0.012)
    assert 1 / engaged**2 == pytest.approx(1 / exhaust**2 + 1 / 0.012**2)


def test_regulator_drift_and_inlet_limit() -> None:
    p_set, house = psig_to_pa(72.0), psig_to_pa(95.0)
    assert regulator_outlet_pressure_kernel(p_set, 0.08, house, house, 0.0) == p_set
    assert regulator_outlet_pressure_kernel(p_set, 0.08, house, house, -3e4) == pytest.approx(
        p_set - 3e4
    )
    # a header dip: 8 % passes while the inlet is above the set point, all below it
    dipped = house - 1e5
    assert regulator_outlet_pressure_kernel(p_set, 0.08, dipped, house, 0.0) == pytest.approx(
        p_set - 0.08e5
    )
    deep = p_set - 0.5e5
    assert regulator_outlet_pressure_kernel(p_set, 0.08, deep, house, 0.0) == deep


def test_header_dip_half_sine_integral() -> None:
    # a half sine of depth D over tau removes 2 D tau / pi of pressure-time
    depth, tau = 3e4, 2.0
    t = np.linspace(10.0, 12.0, 200_001)
    drop = header_dip_profile(t, [10.0], [tau], [depth])
    assert np.trapezoid(drop, t) == pytest.approx(2 * depth * tau / math.pi, rel=1e-8)
    assert drop.max() == pytest.approx(depth, rel=1e-9)
    assert header_dip_kernel(11.0, 10.0, tau, depth) == pytest.approx(depth)
    # overlapping dips add up
    both = header_dip_profile([11.0], [10.0, 10.5], [tau, tau], [depth, depth])
    assert both[0] == pytest.approx(depth + depth * math.sin(math.pi * 0.25))
