"""Physics of pneumatic components: pure functions in SI units.

One module per physical topic (constants, units, flow, chamber, friction, leaks,
economics). Engineering symbols (P1, Cv, xT) are used only inside this package.
"""

from __future__ import annotations

from pneufdd.physics.chamber import (
    chamber_energy_derivatives,
    chamber_energy_derivatives_kernel,
    chamber_pressure,
    chamber_pressure_derivative,
    chamber_pressure_derivative_kernel,
    chamber_pressure_kernel,
    chamber_volume,
    chamber_volume_kernel,
)
from pneufdd.physics.constants import (
    ANR,
    CAGI_SCFM,
    DISSERTATION_STANDARD,
    GAMMA_AIR,
    ISA_STANDARD,
    P_ATM,
    R_AIR,
    T_ROOM,
    FlowBasis,
)
from pneufdd.physics.economics import (
    FIGURE_1_2_CFM,
    figure_1_2_leak_rate,
    leak_annual_cost,
)
from pneufdd.physics.flow import (
    critical_pressure_ratio,
    isa_mass_flow,
    isa_mass_flow_kernel,
    iso6358_mass_flow,
    iso6358_mass_flow_kernel,
    orifice_mass_flow,
    orifice_mass_flow_kernel,
    sonic_conductance_from_catalogue,
)
from pneufdd.physics.friction import (
    friction_force,
    friction_force_kernel,
    piston_force,
    piston_force_kernel,
    stick_slip_force_from_pressures,
)
from pneufdd.physics.leaks import (
    equivalent_orifice_diameter,
    leak_area,
    leak_mass_flow,
    leak_mass_flow_kernel,
    leak_valve_area,
    turns_for_area,
)
from pneufdd.physics.units import (
    bar_gauge_to_pa,
    kg_s_to_scfm,
    kg_s_to_slpm,
    pa_to_bar_gauge,
    pa_to_psig,
    psig_to_pa,
    scfm_to_kg_s,
    slpm_to_kg_s,
    to_si,
)

__all__ = [
    "ANR",
    "CAGI_SCFM",
    "DISSERTATION_STANDARD",
    "FIGURE_1_2_CFM",
    "GAMMA_AIR",
    "ISA_STANDARD",
    "P_ATM",
    "R_AIR",
    "T_ROOM",
    "FlowBasis",
    "bar_gauge_to_pa",
    "chamber_energy_derivatives",
    "chamber_energy_derivatives_kernel",
    "chamber_pressure",
    "chamber_pressure_derivative",
    "chamber_pressure_derivative_kernel",
    "chamber_pressure_kernel",
    "chamber_volume",
    "chamber_volume_kernel",
    "critical_pressure_ratio",
    "equivalent_orifice_diameter",
    "figure_1_2_leak_rate",
    "friction_force",
    "friction_force_kernel",
    "isa_mass_flow",
    "isa_mass_flow_kernel",
    "iso6358_mass_flow",
    "iso6358_mass_flow_kernel",
    "kg_s_to_scfm",
    "kg_s_to_slpm",
    "leak_annual_cost",
    "leak_area",
    "leak_mass_flow",
    "leak_mass_flow_kernel",
    "leak_valve_area",
    "orifice_mass_flow",
    "orifice_mass_flow_kernel",
    "pa_to_bar_gauge",
    "pa_to_psig",
    "piston_force",
    "piston_force_kernel",
    "psig_to_pa",
    "scfm_to_kg_s",
    "slpm_to_kg_s",
    "sonic_conductance_from_catalogue",
    "stick_slip_force_from_pressures",
    "to_si",
    "turns_for_area",
]
