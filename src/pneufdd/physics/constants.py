"""Gas constants and the reference conditions behind every flow unit.

The commonest bug in compressed-air work is mixing flow bases: a "litre per minute"
means nothing until its reference temperature and pressure are named. Each basis here
carries its temperature, pressure and the density of air at that state, so a
volumetric flow at standard conditions converts to mass flow by one multiplication.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, Stony Brook University, section 3.4.1 (standard
   conditions 0 degC, 1013 mbar, 1.294 kg/m^3).
.. [2] ISO 8778:2003, Pneumatic fluid power - Standard reference atmosphere
   (ANR: 20 degC, 100 kPa, 65 % relative humidity, 1.185 kg/m^3).
.. [3] CAGI / US DOE compressed-air "standard air": 68 degF, 14.7 psia, 36 % RH,
   0.075 lb/ft^3 (1.2014 kg/m^3); the basis of "scfm" in US leak tables.
.. [4] ANSI/ISA-75.01.01, Flow equations for sizing control valves: standard
   conditions 60 degF and 14.73 psia for the scfh constant N7 = 1360.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "ANR",
    "CAGI_SCFM",
    "CP_AIR",
    "CV_AIR",
    "DISSERTATION_STANDARD",
    "FT3",
    "GAMMA_AIR",
    "ISA_STANDARD",
    "KELVIN_OFFSET",
    "LB",
    "PSI",
    "P_ATM",
    "R_AIR",
    "T_ROOM",
    "FlowBasis",
]

R_AIR: float = 287.058
"""Specific gas constant of dry air [J/(kg K)]."""

GAMMA_AIR: float = 1.4
"""Ratio of specific heats of air, k in eq. 4.2 [-]."""

CV_AIR: float = R_AIR / (GAMMA_AIR - 1.0)
"""Specific heat of air at constant volume, R/(k-1) = 717.6 [J/(kg K)] (eq. 4.8)."""

CP_AIR: float = GAMMA_AIR * R_AIR / (GAMMA_AIR - 1.0)
"""Specific heat of air at constant pressure, k R/(k-1) = 1004.7 [J/(kg K)] (eq. 4.8)."""

P_ATM: float = 101_325.0
"""Standard atmospheric pressure, the zero of every gauge pressure [Pa]."""

T_ROOM: float = 293.15
"""Default gas temperature, 20 degC, as in the dissertation's valve tests [K]."""

KELVIN_OFFSET: float = 273.15
"""0 degC in kelvin [K]."""

PSI: float = 6_894.757293168361
"""One pound-force per square inch [Pa]."""

FT3: float = 0.028316846592
"""One cubic foot [m^3]."""

LB: float = 0.45359237
"""One pound mass [kg]."""


@dataclass(frozen=True)
class FlowBasis:
    """Reference state of a volumetric flow "at standard conditions".

    Attributes
    ----------
    name : str
        Short name used in unit strings and messages.
    temperature : float
        Reference temperature [K].
    pressure : float
        Reference absolute pressure [Pa].
    density : float
        Density of air at the reference state [kg/m^3]; the value the source
        document states, which may differ slightly from ``pressure / (R T)``
        because of humidity or rounding.
    source : str
        Where the definition comes from.
    """

    name: str
    temperature: float
    pressure: float
    density: float
    source: str


DISSERTATION_STANDARD = FlowBasis(
    name="standard (0 degC, 1013 mbar)",
    temperature=273.15,
    pressure=101_300.0,
    density=1.294,
    source="Zhang dissertation section 3.4.1; basis of SLPM and SL in pneufdd",
)
"""Basis of every ``SLPM`` and ``SL`` in pneufdd, and of the rig's flow meters."""

ANR = FlowBasis(
    name="ANR (20 degC, 100 kPa, 65 % RH)",
    temperature=293.15,
    pressure=100_000.0,
    density=1.185,
    source="ISO 8778:2003 standard reference atmosphere",
)
"""Basis of ``l/min (ANR)``, used in Festo/SMC catalogues and ISO 6358."""

CAGI_SCFM = FlowBasis(
    name="scfm (68 degF, 14.7 psia, 36 % RH)",
    temperature=293.15,
    pressure=14.7 * PSI,
    density=0.075 * LB / FT3,
    source="CAGI / US DOE standard air, 0.075 lb/ft^3; basis of Figure 1.2",
)
"""Basis of ``scfm`` in leak tables such as Figure 1.2 of the dissertation."""

ISA_STANDARD = FlowBasis(
    name="ISA (60 degF, 14.73 psia)",
    temperature=(60.0 - 32.0) / 1.8 + 273.15,
    pressure=14.73 * PSI,
    density=14.73 * PSI / (R_AIR * ((60.0 - 32.0) / 1.8 + 273.15)),
    source="ANSI/ISA-75.01.01 scfh basis of N7 = 1360 (eq. 4.6)",
)
"""Basis of the volumetric flow returned by the ISA valve equation (eq. 4.6)."""
