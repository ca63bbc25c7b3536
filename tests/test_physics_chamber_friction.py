"""Acceptance tests of pneufdd.physics.chamber and .friction (section 4.2.2-4.2.3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from pneufdd.errors import InputError
from pneufdd.physics import (
    CP_AIR,
    CV_AIR,
    GAMMA_AIR,
    P_ATM,
    R_AIR,
    chamber_energy_derivatives,
    chamber_energy_derivatives_kernel,
    chamber_energy_step_kernel,
    chamber_pressure,
    chamber_pressure_derivative,
    chamber_volume,
    enthalpy_flow_kernel,
    friction_force,
    friction_force_kernel,
    piston_force,
    piston_force_kernel,
    piston_net_force_kernel,
    psig_to_pa,
    stick_slip_force_from_pressures,
)

AA = math.pi / 4 * 0.032**2  # DNC 32 bore (Figure 4.10)
AB = AA - math.pi / 4 * 0.012**2  # 12 mm rod


# ---------------------------------------------------------------------------
# Chamber
# ---------------------------------------------------------------------------


def test_chamber_volume_eq_4_11() -> None:
    x = np.array([0.0, 0.1, 0.2])
    np.testing.assert_allclose(chamber_volume(x, AA, 5e-6, "A"), 5e-6 + AA * x, rtol=1e-15)
    np.testing.assert_allclose(
        chamber_volume(x, AB, 4e-6, "B", stroke=0.2), 4e-6 + AB * (0.2 - x), rtol=1e-15
    )
    with pytest.raises(InputError, match="'chamber'"):
        chamber_volume(0.1, AA, 5e-6, "C")
    with pytest.raises(InputError, match="'stroke'"):
        chamber_volume(0.1, AB, 5e-6, "B")
    with pytest.raises(InputError, match="'x'"):
        chamber_volume(0.3, AB, 5e-6, "B", stroke=0.2)


def test_pressure_derivative_eq_4_10() -> None:
    P, V, dV, m_in, m_out, T = 3e5, 2e-5, 1e-4, 2e-4, 5e-5, 300.0
    expected = R_AIR * T / V * (1.4 * m_in - 1.0 * m_out) - 1.2 * P / V * dV
    assert chamber_pressure_derivative(P, V, dV, m_in, m_out, T) == pytest.approx(expected)
    with pytest.raises(InputError, match="'V'"):
        chamber_pressure_derivative(P, 0.0, dV, m_in, m_out)


def test_energy_form_limits_reproduce_eq_4_10() -> None:
    m, T, V, dV, m_in, m_out = 4e-5, 310.0, 3e-5, 2e-5, 1e-4, 3e-5
    P = chamber_pressure(m, T, V)
    dm, dT = chamber_energy_derivatives(m, T, V, dV, m_in, m_out, T_in=T, hA=0.0)
    assert dm == m_in - m_out
    # dP/dt from P = m R T / V
    dP = R_AIR / V * (T * dm + m * dT) - P / V * dV
    adiabatic = chamber_pressure_derivative(
        P, V, dV, m_in, m_out, T, GAMMA_AIR, GAMMA_AIR, GAMMA_AIR
    )
    assert dP == pytest.approx(adiabatic, rel=1e-12)
    # with the gas held at the wall temperature (isothermal), all alphas are 1
    isothermal = R_AIR / V * T * dm - P / V * dV
    assert isothermal == pytest.approx(
        chamber_pressure_derivative(P, V, dV, m_in, m_out, T, 1.0, 1.0, 1.0), rel=1e-12
    )
    # the kernel returns the same tuple
    assert chamber_energy_derivatives_kernel(m, T, V, dV, m_in, m_out, T, 0.0, T) == (dm, dT)
    # heat flows from a hotter wall into the gas
    _, dT_hot = chamber_energy_derivatives(m, T, V, 0.0, 0.0, 0.0, hA=0.5, T_wall=T + 20)
    assert dT_hot == pytest.approx(0.5 * 20 / (m * R_AIR / (GAMMA_AIR - 1)), rel=1e-12)


def test_eq_4_10_creates_mass_over_a_cycle_energy_form_does_not() -> None:
    """Fill then exhaust the same mass (fixed volume, 1 ms each at 1 g/s)."""
    V, T0, flow, dt = 2e-5, 293.15, 1e-3, 1e-3
    P0 = 2e5
    m0 = P0 * V / (R_AIR * T0)

    # eq. 4.10 at fixed T with alpha_in = 1.4, alpha_out = 1.0
    def polytropic(t: float, y: np.ndarray) -> list[float]:
        filling = t < dt
        m_in, m_out = (flow, 0.0) if filling else (0.0, flow)
        return [chamber_pressure_derivative(y[0], V, 0.0, m_in, m_out, T0)]

    P_end = solve_ivp(polytropic, (0, 2 * dt), [P0], max_step=dt / 50, rtol=1e-10).y[0, -1]
    implied_mass_gain = (P_end - P0) * V / (R_AIR * T0)
    assert implied_mass_gain == pytest.approx(0.4 * flow * dt, rel=1e-6)

    # energy form with heat transfer: mass returns exactly to m0
    def energy(t: float, y: np.ndarray) -> list[float]:
        filling = t < dt
        m_in, m_out = (flow, 0.0) if filling else (0.0, flow)
        return list(chamber_energy_derivatives(y[0], y[1], V, 0.0, m_in, m_out, T0, 0.05, T0))

    sol = solve_ivp(energy, (0, 2 * dt), [m0, T0], max_step=dt / 50, rtol=1e-10, atol=1e-14)
    assert sol.y[0, -1] == pytest.approx(m0, rel=1e-9)


def test_air_heat_capacities_are_defined_once() -> None:
    """Issue 31: one c_v (and c_p) for physics, the twin's kernel and its ODE reference."""
    from pneufdd.physics import chamber
    from pneufdd.sim import kernel, rhs

    assert chamber.CV_AIR is CV_AIR
    assert rhs.CV_AIR is CV_AIR
    assert not hasattr(kernel, "_CV_AIR")
    assert not hasattr(kernel, "_CP_AIR")
    assert not hasattr(rhs, "_CV_AIR")
    assert CV_AIR == R_AIR / (GAMMA_AIR - 1.0)  # the expression of all three old copies
    assert CP_AIR == GAMMA_AIR * R_AIR / (GAMMA_AIR - 1.0)
    assert abs(CP_AIR - CV_AIR - R_AIR) <= 1e-12 * R_AIR  # Mayer's relation


def test_enthalpy_flow_carries_the_upstream_temperature() -> None:
    assert enthalpy_flow_kernel(2e-3, 300.0, 400.0) == CP_AIR * 2e-3 * 300.0
    assert enthalpy_flow_kernel(-2e-3, 300.0, 400.0) == CP_AIR * -2e-3 * 400.0
    assert enthalpy_flow_kernel(0.0, 300.0, 400.0) == 0.0


def test_energy_step_converges_to_the_energy_derivatives() -> None:
    """The twin's step (energy form) against eq. 4.7-4.9 in mass-temperature form."""
    m, T, V, dV, m_in, m_out, T_in = 4e-5, 310.0, 3e-5, 2e-5, 1e-4, 3e-5, 293.15
    P = chamber_pressure(m, T, V)
    dm, dT = chamber_energy_derivatives(m, T, V, dV, m_in, m_out, T_in=T_in, hA=0.0)
    h = enthalpy_flow_kernel(m_in, T_in, T) - enthalpy_flow_kernel(m_out, T, T_in)
    errors = []
    for dt in (1e-5, 1e-6):
        m_new, T_new = chamber_energy_step_kernel(m, T, P, dV, dm, h, dt, T, 1.0)
        assert m_new == m + dt * dm  # mass exactly
        errors.append(abs((T_new - T) / dt - dT) / abs(dT))
    # first order in dt: 1.75e-5 and 1.75e-6 of dT/dt
    assert errors[1] < 2e-6
    assert errors[0] / errors[1] == pytest.approx(10.0, rel=1e-3)
    # the wall exchange relaxes the temperature: none left with decay 0, half with 0.5
    _, T_wall = chamber_energy_step_kernel(m, T, P, 0.0, 0.0, 0.0, 1e-3, 293.15, 0.0)
    assert T_wall == 293.15
    _, T_half = chamber_energy_step_kernel(m, T, P, 0.0, 0.0, 0.0, 1e-3, 293.15, 0.5)
    assert T_half == pytest.approx((T + 293.15) / 2, rel=1e-15)
    # floors: an emptied node keeps 1e-12 kg, never below 150 K
    m_min, T_min = chamber_energy_step_kernel(m, T, P, 0.0, -1.0, 0.0, 1e-3, 293.15, 1.0)
    assert m_min == 1e-12
    assert T_min >= 150.0


# ---------------------------------------------------------------------------
# Friction and force balance
# ---------------------------------------------------------------------------


@given(
    st.floats(0.0, 1e6),
    st.floats(0.0, 1e6),
    st.floats(1e-6, 1e-2),
    st.floats(0.0, 1.0),
)
def test_net_force_is_the_gauge_force_up_to_rounding(
    pa: float, pb: float, aa: float, rod_share: float
) -> None:
    """The twin's absolute-pressure form of eq. 4.13 against piston_force_kernel."""
    ab = aa * (1.0 - rod_share)
    rod = aa - ab
    net = piston_net_force_kernel(pa, pb, aa, ab, rod)
    assert net == pa * aa - pb * ab - P_ATM * rod  # the kernel's order, bit for bit
    scale = (pa + pb + P_ATM) * aa  # the size of the terms that cancel
    assert net == pytest.approx(piston_force_kernel(pa, pb, aa, ab), abs=1e-14 * scale)


def test_stick_slip_force_eq_4_15_dnc() -> None:
    # section 4.2.3: Pa = 61.37 psi, Pb = 40.22 psi (gauge) at t2 -> Fsf = 150 N
    fsf = stick_slip_force_from_pressures(psig_to_pa(61.37), psig_to_pa(40.22), AA, AB)
    assert fsf == pytest.approx(150.0, rel=0.02)  # measured 148.64 N
    assert fsf == pytest.approx(148.64, abs=0.01)


def test_force_balance_includes_atmosphere_on_rod() -> None:
    pa, pb = 5e5, 3e5
    expected = pa * AA - pb * AB - 101325.0 * (AA - AB)
    assert piston_force(pa, pb, AA, AB) == pytest.approx(expected, rel=1e-13)
    assert piston_force(101325.0, 101325.0, AA, AB) == 0.0


def test_friction_defaults_and_regimes() -> None:
    assert friction_force(0.0, 100.0) == 100.0
    assert friction_force(0.0, -400.0) == -150.0
    assert friction_force(0.2, 0.0) == pytest.approx(158.6 + 17.88 * 0.2)
    assert friction_force(-0.2, 0.0) == pytest.approx(-158.6 - 17.88 * 0.2)
    assert friction_force_kernel(0.0005, 50.0, 150.0, 158.6, 17.88, 1e-3) == 50.0
    with pytest.raises(InputError, match="'v_stick'"):
        friction_force(0.0, 1.0, v_stick=0.0)


velocities = st.floats(-2.0, 2.0)
forces = st.floats(-2000.0, 2000.0)
params = st.floats(0.0, 500.0)


@given(v=velocities, f=forces, fsf=params, fcf=params, cvf=st.floats(0.0, 100.0))
def test_friction_never_adds_energy(v: float, f: float, fsf: float, fcf: float, cvf: float) -> None:
    ff = friction_force(v, f, fsf, fcf, cvf, 1e-3)
    if abs(v) >= 1e-3:
        # power friction delivers to the piston, -F_f v, is never positive
        assert -ff * v <= 0.0
    else:
        # stuck: friction at most balances the driving force, never exceeds it
        assert abs(ff) <= abs(f)
        assert abs(ff) <= fsf
        assert ff * f >= 0.0
        assert abs(f - ff) <= abs(f)
