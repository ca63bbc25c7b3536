"""Physics of pneumatic components: pure functions in SI units.

One module per physical topic (constants, units, flow, chamber, friction, leaks,
economics). Engineering symbols (P1, Cv, xT) are used only inside this package.
"""

from __future__ import annotations

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
    "GAMMA_AIR",
    "ISA_STANDARD",
    "P_ATM",
    "R_AIR",
    "T_ROOM",
    "FlowBasis",
    "bar_gauge_to_pa",
    "kg_s_to_scfm",
    "kg_s_to_slpm",
    "pa_to_bar_gauge",
    "pa_to_psig",
    "psig_to_pa",
    "scfm_to_kg_s",
    "slpm_to_kg_s",
    "to_si",
]
