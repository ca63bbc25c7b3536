"""Cost of compressed-air leaks: eq. 1.1 and the leak-rate table of Figure 1.2.

Eq. 1.1 prices a leak by the electric power needed to compress the air it loses:

.. math::

    \\text{cost} = n \\cdot Q_{scfm} \\cdot \\frac{kW}{cfm} \\cdot \\text{hours}
                 \\cdot \\frac{\\$}{kWh}

The leak rate is in scfm on the CAGI/US DOE standard-air basis (68 degF, 14.7 psia,
0.075 lb/ft^3 = 1.2014 kg/m^3, ``constants.CAGI_SCFM``), the basis of the DOE table
reproduced as Figure 1.2. The defaults are the section 1.1 example: 7000 operating
hours a year, $0.05/kWh and 18 kW of compressor power per 100 cfm.

References
----------
.. [1] Zhang, K., *Fault Detection and Diagnosis for Multi-Actuator Pneumatic
   Systems*, PhD dissertation, section 1.1, eq. 1.1, Figure 1.2.
.. [2] US DOE, Compressed Air Tip Sheet #3, "Minimize compressed air leaks"
   (origin of the table and example).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

from pneufdd.errors import InputError, describe
from pneufdd.physics._jit import FloatOrArray, as_float_array, require, scalar_or_array
from pneufdd.physics.units import kg_s_to_scfm, scfm_to_kg_s

__all__ = [
    "FIGURE_1_2_CFM",
    "FIGURE_1_2_DIAMETERS_IN",
    "FIGURE_1_2_PRESSURES_PSIG",
    "ORIFICE_FACTORS",
    "figure_1_2_leak_rate",
    "leak_annual_cost",
]

FIGURE_1_2_PRESSURES_PSIG: tuple[float, ...] = (70.0, 80.0, 90.0, 100.0, 125.0)
"""Row headings of Figure 1.2: supply pressure [psig]."""

FIGURE_1_2_DIAMETERS_IN: tuple[float, ...] = (1 / 64, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 3 / 8)
"""Column headings of Figure 1.2: orifice diameter [in]."""

FIGURE_1_2_CFM: dict[float, tuple[float, ...]] = {
    70.0: (0.29, 1.16, 4.66, 18.62, 74.4, 167.8),
    80.0: (0.32, 1.26, 5.24, 20.76, 83.1, 187.2),
    90.0: (0.36, 1.46, 5.72, 23.1, 92.0, 206.6),
    100.0: (0.4, 1.55, 6.31, 25.22, 100.9, 227.0),
    125.0: (0.48, 1.94, 7.66, 30.65, 122.2, 275.5),
}
"""Figure 1.2 as printed: leak rate of an ideal orifice [scfm], keyed by pressure [psig],
one entry per diameter of :data:`FIGURE_1_2_DIAMETERS_IN`."""

ORIFICE_FACTORS: dict[str, float] = {"ideal": 1.0, "rounded": 0.97, "sharp": 0.61}
"""Figure 1.2 note: multiply by 0.97 for well-rounded and 0.61 for sharp orifices [-]."""


def figure_1_2_leak_rate(
    pressure_psig: float,
    diameter_in: float,
    orifice: Literal["ideal", "rounded", "sharp"] = "ideal",
) -> float:
    """Leak mass flow read from Figure 1.2, with its orifice-shape factor.

    .. math:: \\dot m = f_{shape} \\cdot Q_{table}\\,[\\mathrm{scfm}]
              \\cdot 1.2014\\,\\mathrm{kg/m^3} \\cdot 0.0283168\\,\\mathrm{m^3} / 60\\,\\mathrm{s}

    Parameters
    ----------
    pressure_psig : float
        One of the table's pressures: 70, 80, 90, 100 or 125 [psig].
    diameter_in : float
        One of the table's diameters: 1/64, 1/32, 1/16, 1/8, 1/4 or 3/8 [in].
    orifice : {"ideal", "rounded", "sharp"}
        Orifice shape; factor 1, 0.97 or 0.61.

    Returns
    -------
    float
        Leak mass flow [kg/s] (table cfm on the CAGI standard-air basis).

    Raises
    ------
    InputError
        For a pressure, diameter or shape not in the table.

    Examples
    --------
    >>> from pneufdd.physics.units import kg_s_to_scfm
    >>> round(kg_s_to_scfm(figure_1_2_leak_rate(100.0, 1 / 4, "sharp")), 3)
    61.549
    """
    if orifice not in ORIFICE_FACTORS:
        raise InputError(describe("parameter 'orifice'", orifice, list(ORIFICE_FACTORS)))
    row = FIGURE_1_2_CFM.get(float(pressure_psig))
    if row is None:
        raise InputError(
            describe("parameter 'pressure_psig'", pressure_psig, FIGURE_1_2_PRESSURES_PSIG)
        )
    matches = [
        i for i, d in enumerate(FIGURE_1_2_DIAMETERS_IN) if abs(float(diameter_in) - d) <= 1e-9 * d
    ]
    if not matches:
        raise InputError(
            describe(
                "parameter 'diameter_in'",
                diameter_in,
                "1/64, 1/32, 1/16, 1/8, 1/4 or 3/8 (inches)",
            )
        )
    return float(scfm_to_kg_s(row[matches[0]] * ORIFICE_FACTORS[orifice]))


def leak_annual_cost(
    mass_flow: npt.ArrayLike,
    hours: float = 7000.0,
    energy_price: float = 0.05,
    kw_per_100_cfm: float = 18.0,
    count: npt.ArrayLike = 1,
) -> FloatOrArray:
    """Yearly electricity cost of compressed-air leaks, eq. 1.1.

    .. math::

        \\text{cost} = n \\cdot Q_{scfm}(\\dot m) \\cdot \\frac{kW_{100}}{100}
                      \\cdot h \\cdot c_{kWh}

    The mass flow is converted to scfm on the CAGI standard-air basis
    (1.2014 kg/m^3). Defaults are the section 1.1 example.

    Parameters
    ----------
    mass_flow : float or array_like
        Mass flow of one leak, >= 0 [kg/s].
    hours : float
        Operating hours per year, >= 0 [h]; default 7000 h.
    energy_price : float
        Aggregate electricity price, >= 0 [$/kWh]; default 0.05 $/kWh.
    kw_per_100_cfm : float
        Compressor power needed per 100 scfm of air, >= 0 [kW/(100 scfm)];
        default 18.
    count : int or array_like
        Number of identical leaks, >= 0 [-].

    Returns
    -------
    float or ndarray
        Cost per year [$]; elementwise for arrays.

    Examples
    --------
    100 sharp-edged 1/32 in leaks at 90 psig (section 1.1):

    >>> round(leak_annual_cost(figure_1_2_leak_rate(90.0, 1 / 32, "sharp"), count=100), 2)
    5610.78
    """
    m = as_float_array(mass_flow, "mass_flow")
    require(m, m >= 0.0, "mass_flow", "a leak mass flow >= 0 kg/s")
    n = as_float_array(count, "count")
    require(n, n >= 0.0, "count", "a number of leaks >= 0")
    for name, value in (
        ("hours", hours),
        ("energy_price", energy_price),
        ("kw_per_100_cfm", kw_per_100_cfm),
    ):
        if not (np.isfinite(value) and value >= 0.0):
            raise InputError(describe(f"parameter {name!r}", value, "a finite value >= 0"))
    scfm = kg_s_to_scfm(m)
    return scalar_or_array(n * scfm * kw_per_100_cfm / 100.0 * hours * energy_price)
