"""What a leak costs: equivalent orifice and annual cost by eq. 1.1.

Two flows describe a leak on a sequenced machine:

- its **nominal flow** (``mass_flow``): the leak flow while its line is pressurised,
  at the machine's supply pressure. This is what a technician finds with an
  ultrasonic detector and what the equivalent orifice is computed from;
- its **average flow** (``average_mass_flow``): the mean leaked flow over an
  operating cycle. A ``supply`` leak blows all cycle, so the two are equal; a leak on
  an actuator line only loses air while that line holds pressure (with a 5/3
  closed-centre valve it blows until the isolated chamber is empty, with a 5/2
  valve during the steps the line is pressurised).

The annual cost of eq. 1.1 is that of the air really lost: the average flow times the
operating hours (1.1's "leakage rate" is a continuous flow). When the average flow is
not known (a reference without signature mean flows) the nominal flow is used, i.e.
continuous leakage is assumed;
:attr:`~pneufdd.diagnosis.findings.LeakFinding.cost_basis` says which.

.. math::

    \\text{cost per year} = Q_{cfm} \\cdot \\frac{kW}{cfm} \\cdot \\text{hours}
    \\cdot \\text{price per kWh} \\qquad (1.1)

with the leak flow :math:`Q_{cfm}` in CAGI/DOE standard cubic feet per minute (the
basis of Figure 1.2) and the compressor's specific power given as kW per 100 cfm
(the dissertation's example: 18 kW/100 cfm, 7000 h, $0.05/kWh).

The equivalent orifice is the sharp-edged orifice (discharge coefficient 0.61, the
Figure 1.2 note) that passes the leak's mass flow from the leak's nominal absolute
pressure to the atmosphere (eq. 4.2-4.3). Both formulas are those of
:mod:`pneufdd.physics.economics` and :mod:`pneufdd.physics.leaks`; this module adds
the ranking and makes the :class:`~pneufdd.diagnosis.findings.LeakFinding` of each leak
(SI values; SLPM and mm are its read-only properties).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pneufdd.diagnosis.findings import LeakFinding
from pneufdd.errors import InputError, describe
from pneufdd.limits import MAX_HOURS_PER_YEAR
from pneufdd.location import Location
from pneufdd.physics.constants import P_ATM, T_ROOM
from pneufdd.physics.economics import leak_annual_cost
from pneufdd.physics.leaks import SHARP_EDGE_CD, equivalent_orifice_diameter

__all__ = [
    "COST_BASIS_AVERAGE",
    "COST_BASIS_CONTINUOUS",
    "SHARP_EDGED_CD",
    "CostSettings",
    "annual_cost",
    "cost_leaks",
    "equivalent_orifice",
]

SHARP_EDGED_CD: float = SHARP_EDGE_CD
"""Discharge coefficient of a sharp-edged orifice (Figure 1.2 note) [-]."""

COST_BASIS_AVERAGE = "average flow over the operating cycle"
"""Cost basis: operating hours x the mean leaked flow while the machine cycles."""

COST_BASIS_CONTINUOUS = "nominal flow, continuous leakage assumed"
"""Cost basis when the average flow is unknown: the nominal flow all operating hours."""


MAX_PRICE_PER_KWH = 100.0
"""Highest electricity price accepted [$ / kWh] (prices are below 1)."""

MAX_KW_PER_100_CFM = 100.0
"""Highest compressor specific power accepted [kW per 100 scfm] (typical: 15-25)."""


@dataclass(frozen=True)
class CostSettings:
    """Economic inputs of eq. 1.1.

    Attributes
    ----------
    hours : float
        Operating hours per year [h].
    price_per_kwh : float
        Electricity price [$ / kWh].
    kw_per_100_cfm : float
        Compressor specific power [kW per 100 scfm].
    """

    hours: float = 7000.0
    price_per_kwh: float = 0.05
    kw_per_100_cfm: float = 18.0

    def __post_init__(self) -> None:
        for name, option, high, unit in (
            ("hours", "--hours", MAX_HOURS_PER_YEAR, "h per year: a leap year around the clock"),
            ("price_per_kwh", "--price", MAX_PRICE_PER_KWH, "$ / kWh"),
            ("kw_per_100_cfm", "--kw-per-100cfm", MAX_KW_PER_100_CFM, "kW per 100 scfm"),
        ):
            value = getattr(self, name)
            if not math.isfinite(value) or not 0 <= value <= high:
                raise InputError(describe(f"{name} ({option})", value, f"0 to {high:g} ({unit})"))


def annual_cost(mass_flow: float, settings: CostSettings) -> float:
    """Annual cost of one leak by eq. 1.1.

    Parameters
    ----------
    mass_flow : float
        Mean leaked mass flow while the machine operates [kg/s].
    settings : CostSettings
        Hours, price and specific power.

    Returns
    -------
    float
        Cost per year [$].

    Examples
    --------
    One 1/4 in leak at 100 psig (Figure 1.2: 100.9 cfm, sharp-edged x 0.61) at the
    section 1.1 settings:

    >>> from pneufdd.physics.units import scfm_to_kg_s
    >>> round(annual_cost(scfm_to_kg_s(100.9 * 0.61), CostSettings()))
    3878
    """
    return float(
        leak_annual_cost(
            float(mass_flow),
            hours=settings.hours,
            energy_price=settings.price_per_kwh,
            kw_per_100_cfm=settings.kw_per_100_cfm,
        )
    )


def equivalent_orifice(mass_flow: float, pressure: float, temperature: float = T_ROOM) -> float:
    """Diameter of the sharp-edged orifice passing ``mass_flow`` from ``pressure``.

    Delegates to :func:`pneufdd.physics.leaks.equivalent_orifice_diameter`
    (eq. 4.2-4.3 with C_d = 0.61), after checking the pressure.

    Parameters
    ----------
    mass_flow : float
        Leak mass flow (negative counts as 0) [kg/s].
    pressure : float
        Upstream absolute pressure [Pa].
    temperature : float
        Upstream temperature [K].

    Returns
    -------
    float
        Equivalent orifice diameter [m].

    Raises
    ------
    InputError
        If ``pressure`` is not above the atmosphere's.

    Examples
    --------
    A 1/16 in (1.5875 mm) orifice at 90 psig leaks 5.72 cfm x 0.61 (Figure 1.2):

    >>> from pneufdd.physics.units import psig_to_pa, scfm_to_kg_s
    >>> round(1e3 * equivalent_orifice(scfm_to_kg_s(5.72 * 0.61), psig_to_pa(90.0)), 2)
    1.56
    """
    if not math.isfinite(pressure) or pressure <= P_ATM:
        raise InputError(describe("leak pressure [Pa]", pressure, "> 101325 Pa absolute"))
    return float(equivalent_orifice_diameter(max(float(mass_flow), 0.0), pressure, temperature))


def cost_leaks(
    locations: Sequence[Location],
    mass_flows: Sequence[float],
    pressures: Sequence[float],
    confidences: Sequence[float],
    groups: Sequence[tuple[Location, ...]],
    settings: CostSettings,
    average_flows: Sequence[float | None] | None = None,
    group_mass_flows: Sequence[tuple[float, ...]] | None = None,
) -> tuple[list[LeakFinding], float]:
    """Cost each leak and rank them, largest annual cost first.

    Parameters
    ----------
    locations : sequence of Location
        Most likely location of each leak.
    mass_flows : sequence of float
        Nominal leak flows, at the leak's nominal pressure [kg/s].
    pressures : sequence of float
        Nominal absolute pressure of each leak [Pa].
    confidences : sequence of float
        Confidence of each leak [-].
    groups : sequence of tuple of Location
        Ambiguity group of each leak.
    settings : CostSettings
        Economic inputs of eq. 1.1.
    average_flows : sequence of float or None, optional
        Mean leaked flow of each leak over an operating cycle [kg/s]; None (for all
        or one leak) prices that leak at its nominal flow (continuous leakage).
    group_mass_flows : sequence of tuple of float, optional
        Nominal flow each member of each leak's group would need [kg/s].

    Returns
    -------
    leaks : list of LeakFinding
        Ranked leaks.
    total : float
        Sum of the annual costs [$].

    Examples
    --------
    >>> from pneufdd.location import SUPPLY, Location
    >>> dnc_b = Location("DNC", "B")
    >>> leaks, total = cost_leaks([SUPPLY, dnc_b], [6.0e-4, 1.2e-3], [6e5, 6e5],
    ...                           [0.9, 0.8], [(SUPPLY,), (dnc_b,)], CostSettings())
    >>> [str(leak.location) for leak in leaks], round(total, 2) == round(sum(
    ...     leak.annual_cost for leak in leaks), 2)
    (['DNC_B', 'supply'], True)

    A line leak that loses on average a twentieth of its nominal flow costs a
    twentieth as much:

    >>> leaks, _ = cost_leaks([dnc_b], [1.2e-3], [6e5], [0.9], [(dnc_b,)],
    ...                       CostSettings(), average_flows=[6.0e-5])
    >>> round(leaks[0].flow_slpm, 1), round(leaks[0].average_flow_slpm, 2)
    (55.6, 2.78)
    """
    if average_flows is None:
        average_flows = [None] * len(locations)
    if group_mass_flows is None:
        group_mass_flows = [()] * len(locations)
    rows = []
    for loc, flow, p, conf, group, mean, group_flows in zip(
        locations,
        mass_flows,
        pressures,
        confidences,
        groups,
        average_flows,
        group_mass_flows,
        strict=True,
    ):
        if mean is not None and (not math.isfinite(mean) or mean < 0):
            raise InputError(describe(f"average leak flow at {loc} [kg/s]", mean, ">= 0"))
        lost = float(flow) if mean is None else float(mean)
        rows.append(
            LeakFinding(
                location=loc,
                mass_flow=float(flow),
                average_mass_flow=lost,
                orifice_diameter=equivalent_orifice(float(flow), float(p)),
                annual_cost=annual_cost(lost, settings),
                confidence=float(conf),
                ambiguity_group=tuple(group),
                cost_basis=COST_BASIS_CONTINUOUS if mean is None else COST_BASIS_AVERAGE,
                group_mass_flows=tuple(float(x) for x in group_flows),
            )
        )
    rows.sort(key=lambda r: -r.annual_cost)
    return rows, float(sum(r.annual_cost for r in rows))
