"""Physics of pneumatic components: pure functions in SI units.

One module per physical topic (constants, units, flow, chamber, friction, leaks,
economics). Engineering symbols (P1, Cv, xT) are used only inside this package.

May import: :mod:`pneufdd.errors`, :mod:`pneufdd.array_types` (the bottom of the chain).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pneufdd._lazy import lazy_getattr

if TYPE_CHECKING:
    from pneufdd.physics.chamber import (
        chamber_energy_derivatives,
        chamber_energy_derivatives_kernel,
        chamber_energy_step_kernel,
        chamber_pressure,
        chamber_pressure_derivative,
        chamber_pressure_derivative_kernel,
        chamber_pressure_kernel,
        chamber_volume,
        chamber_volume_kernel,
        enthalpy_flow_kernel,
    )
    from pneufdd.physics.constants import (
        ANR,
        CAGI_SCFM,
        CP_AIR,
        CV_AIR,
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
        piston_net_force_kernel,
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
    "CP_AIR",
    "CV_AIR",
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
    "chamber_energy_step_kernel",
    "chamber_pressure",
    "chamber_pressure_derivative",
    "chamber_pressure_derivative_kernel",
    "chamber_pressure_kernel",
    "chamber_volume",
    "chamber_volume_kernel",
    "critical_pressure_ratio",
    "enthalpy_flow_kernel",
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
    "piston_net_force_kernel",
    "psig_to_pa",
    "scfm_to_kg_s",
    "slpm_to_kg_s",
    "sonic_conductance_from_catalogue",
    "stick_slip_force_from_pressures",
    "to_si",
    "turns_for_area",
]

# Imported on first use, so that ``import pneufdd`` (and the CLI's --help) does not
# load numba and compile kernels for code that never evaluates physics.
_LAZY = {
    "chamber_energy_derivatives": "pneufdd.physics.chamber",
    "chamber_energy_derivatives_kernel": "pneufdd.physics.chamber",
    "chamber_energy_step_kernel": "pneufdd.physics.chamber",
    "chamber_pressure": "pneufdd.physics.chamber",
    "chamber_pressure_derivative": "pneufdd.physics.chamber",
    "chamber_pressure_derivative_kernel": "pneufdd.physics.chamber",
    "chamber_pressure_kernel": "pneufdd.physics.chamber",
    "chamber_volume": "pneufdd.physics.chamber",
    "chamber_volume_kernel": "pneufdd.physics.chamber",
    "enthalpy_flow_kernel": "pneufdd.physics.chamber",
    "ANR": "pneufdd.physics.constants",
    "CAGI_SCFM": "pneufdd.physics.constants",
    "CP_AIR": "pneufdd.physics.constants",
    "CV_AIR": "pneufdd.physics.constants",
    "DISSERTATION_STANDARD": "pneufdd.physics.constants",
    "GAMMA_AIR": "pneufdd.physics.constants",
    "ISA_STANDARD": "pneufdd.physics.constants",
    "P_ATM": "pneufdd.physics.constants",
    "R_AIR": "pneufdd.physics.constants",
    "T_ROOM": "pneufdd.physics.constants",
    "FlowBasis": "pneufdd.physics.constants",
    "FIGURE_1_2_CFM": "pneufdd.physics.economics",
    "figure_1_2_leak_rate": "pneufdd.physics.economics",
    "leak_annual_cost": "pneufdd.physics.economics",
    "critical_pressure_ratio": "pneufdd.physics.flow",
    "isa_mass_flow": "pneufdd.physics.flow",
    "isa_mass_flow_kernel": "pneufdd.physics.flow",
    "iso6358_mass_flow": "pneufdd.physics.flow",
    "iso6358_mass_flow_kernel": "pneufdd.physics.flow",
    "orifice_mass_flow": "pneufdd.physics.flow",
    "orifice_mass_flow_kernel": "pneufdd.physics.flow",
    "sonic_conductance_from_catalogue": "pneufdd.physics.flow",
    "friction_force": "pneufdd.physics.friction",
    "friction_force_kernel": "pneufdd.physics.friction",
    "piston_force": "pneufdd.physics.friction",
    "piston_force_kernel": "pneufdd.physics.friction",
    "piston_net_force_kernel": "pneufdd.physics.friction",
    "stick_slip_force_from_pressures": "pneufdd.physics.friction",
    "equivalent_orifice_diameter": "pneufdd.physics.leaks",
    "leak_area": "pneufdd.physics.leaks",
    "leak_mass_flow": "pneufdd.physics.leaks",
    "leak_mass_flow_kernel": "pneufdd.physics.leaks",
    "leak_valve_area": "pneufdd.physics.leaks",
    "turns_for_area": "pneufdd.physics.leaks",
    "bar_gauge_to_pa": "pneufdd.physics.units",
    "kg_s_to_scfm": "pneufdd.physics.units",
    "kg_s_to_slpm": "pneufdd.physics.units",
    "pa_to_bar_gauge": "pneufdd.physics.units",
    "pa_to_psig": "pneufdd.physics.units",
    "psig_to_pa": "pneufdd.physics.units",
    "scfm_to_kg_s": "pneufdd.physics.units",
    "slpm_to_kg_s": "pneufdd.physics.units",
    "to_si": "pneufdd.physics.units",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())
