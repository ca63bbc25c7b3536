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
from collections.abc import Callable, Sequence
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
    "SEAL_VENTS",
    "SHARP_EDGED_CD",
    "CostSettings",
    "LeakTotals",
    "annual_cost",
    "cost_leaks",
    "equivalent_orifice",
    "leak_totals",
    "repair_cost",
    "repair_order",
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

MAX_REPAIR_COST = 1e6
"""Highest repair cost accepted [$] (a fitting costs tens, an actuator hundreds)."""

SEAL_VENTS: dict[str, tuple[str, ...]] = {
    "linear": ("B",),
    "slide": ("B",),
    "rodless": ("A", "B"),
}
"""Actuator kinds whose seals vent a chamber to the atmosphere, by the chamber's line:
a cylinder's or a slide's rod seal (the rod side, ``B``), a rodless cylinder's sealing
band (both sides). A leak on such a line may be that seal, not the line's tube or
fitting (``docs/assumptions.md``)."""

REPAIR_FITTING = "fitting, tube, hose or coupling"
REPAIR_SEAL = "actuator seal, or its line's fitting or tube"


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
    repair_fitting : float
        Cost of repairing a leaking fitting, tube, hose or coupling: about half an
        hour of a technician and the part [$] (:func:`repair_cost`).
    repair_seal : float
        Cost of resealing an actuator: the seal kit and dismantling, two to three
        hours [$].
    seal_share : float
        Share of the leaks on a line whose actuator's seal vents to the atmosphere
        (:data:`SEAL_VENTS`) that are that seal [-].
    """

    hours: float = 7000.0
    price_per_kwh: float = 0.05
    kw_per_100_cfm: float = 18.0
    repair_fitting: float = 40.0
    repair_seal: float = 250.0
    seal_share: float = 0.5

    def __post_init__(self) -> None:
        for name, option, high, unit in (
            ("hours", "--hours", MAX_HOURS_PER_YEAR, "h per year: a leap year around the clock"),
            ("price_per_kwh", "--price", MAX_PRICE_PER_KWH, "$ / kWh"),
            ("kw_per_100_cfm", "--kw-per-100cfm", MAX_KW_PER_100_CFM, "kW per 100 scfm"),
            ("repair_fitting", "--repair-fitting", MAX_REPAIR_COST, "$ per repair"),
            ("repair_seal", "--repair-seal", MAX_REPAIR_COST, "$ per repair"),
            ("seal_share", "--seal-share", 1.0, "a share"),
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
    intervals: Sequence[tuple[float, float]] | None = None,
    repairs: Sequence[tuple[float, str]] | None = None,
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
    intervals : sequence of (float, float), optional
        95 % interval of each nominal flow [kg/s].
    repairs : sequence of (float, str), optional
        Expected repair cost of each leak [$] and what is repaired
        (:func:`repair_cost`).

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
    if intervals is None:
        intervals = [(math.nan, math.nan)] * len(locations)
    if repairs is None:
        repairs = [(math.nan, "")] * len(locations)
    rows = []
    for loc, flow, p, conf, group, mean, group_flows, interval, repair in zip(
        locations,
        mass_flows,
        pressures,
        confidences,
        groups,
        average_flows,
        group_mass_flows,
        intervals,
        repairs,
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
                mass_flow_interval=(float(interval[0]), float(interval[1])),
                repair_cost=float(repair[0]),
                repair_kind=repair[1],
            )
        )
    rows.sort(key=lambda r: -r.annual_cost)
    return rows, float(sum(r.annual_cost for r in rows))


def repair_cost(
    location: Location, actuator_kind: str | None, settings: CostSettings
) -> tuple[float, str]:
    """Expected cost of repairing a leak at ``location``, and what is repaired [$].

    A supply leak and a leak on an actuator line are a fitting, tube, hose or
    coupling (``repair_fitting``); on a line whose actuator's seal vents to the
    atmosphere (:data:`SEAL_VENTS`: a cylinder's rod side, a rodless cylinder's
    sealing band) it is that seal with the probability ``seal_share``, so the
    expected cost is ``seal_share * repair_seal + (1 - seal_share) * repair_fitting``.
    The assumptions are in ``docs/assumptions.md``.

    Examples
    --------
    >>> from pneufdd.location import SUPPLY, Location
    >>> repair_cost(SUPPLY, None, CostSettings())
    (40.0, 'fitting, tube, hose or coupling')
    >>> repair_cost(Location("DNC", "B"), "linear", CostSettings())[0]
    145.0
    >>> repair_cost(Location("DNC", "A"), "linear", CostSettings())[0]
    40.0
    """
    if location.side is not None and location.side in SEAL_VENTS.get(actuator_kind or "", ()):
        share = settings.seal_share
        cost = share * settings.repair_seal + (1.0 - share) * settings.repair_fitting
        return float(cost), REPAIR_SEAL
    return float(settings.repair_fitting), REPAIR_FITTING


def repair_order(leaks: Sequence[LeakFinding]) -> tuple[int, ...]:
    """Indices of ``leaks`` in the order to repair them: most saved per repair dollar.

    By annual cost per repair cost, highest first (the shortest payback); a leak
    whose repair cost is unknown or zero comes first by its annual cost.

    Examples
    --------
    >>> from pneufdd.location import SUPPLY
    >>> a = LeakFinding(SUPPLY, 1e-3, 1e-3, 1e-3, 300.0, 0.9, (SUPPLY,), "", repair_cost=40.0)
    >>> b = LeakFinding(SUPPLY, 2e-3, 2e-3, 2e-3, 500.0, 0.9, (SUPPLY,), "", repair_cost=145.0)
    >>> repair_order([b, a])
    (1, 0)
    """

    def saved_per_dollar(i: int) -> float:
        cost = leaks[i].repair_cost
        if not math.isfinite(cost) or cost <= 0:
            return math.inf
        return leaks[i].annual_cost / cost

    return tuple(
        sorted(range(len(leaks)), key=lambda i: (-saved_per_dollar(i), -leaks[i].annual_cost))
    )


@dataclass(frozen=True)
class LeakTotals:
    """The reported leaks together, with intervals from the fit.

    The interval of a total is that of the sum of the fitted sizes, from their
    covariance (:attr:`~pneufdd.diagnosis.localisation.search.Localisation.size_spread`:
    the fit's and the twin's model error on the plausible plants): often narrower
    than the single leaks' intervals would suggest, since leaks the sensors cannot
    tell apart have a poorly determined difference but a well determined sum. It
    covers the reported leaks; what could still hide elsewhere is the diagnosis's
    remainder.

    Attributes
    ----------
    mass_flow : float
        Sum of the nominal flows [kg/s].
    mass_flow_interval : tuple of float
        Its interval at :attr:`level` (low floored at 0) [kg/s].
    average_mass_flow : float
        Sum of the mean flows over the operating cycle [kg/s].
    average_mass_flow_interval : tuple of float
        Its interval [kg/s].
    annual_cost : float
        Sum of the annual costs [$].
    annual_cost_interval : tuple of float
        Its interval [$].
    level : float
        Two-sided level of the intervals [-].
    """

    mass_flow: float
    mass_flow_interval: tuple[float, float]
    average_mass_flow: float
    average_mass_flow_interval: tuple[float, float]
    annual_cost: float
    annual_cost_interval: tuple[float, float]
    level: float = 0.95


_Z_95 = 1.959963984540054
"""The normal distribution's 97.5 % quantile: half-width of a two-sided 95 % interval [-]."""


def leak_totals(
    mass_flows: Sequence[float],
    average_flows: Sequence[float],
    average_slopes: Sequence[float],
    variance: Callable[[Sequence[float]], float],
    settings: CostSettings,
    upper: float = math.inf,
) -> LeakTotals:
    """Total nominal flow, mean flow and cost of leaks, with 95 % intervals.

    Parameters
    ----------
    mass_flows : sequence of float
        Nominal flow of each leak [kg/s].
    average_flows : sequence of float
        Its mean flow over the operating cycle [kg/s].
    average_slopes : sequence of float
        Derivative of each mean flow by the nominal flow (its duty, for a duty that
        does not change with the size) [-].
    variance : callable
        ``variance(weights)``: the variance of the weighted sum of the nominal
        flows, weights in the order of ``mass_flows`` [(kg/s)^2].
    settings : CostSettings
        For the cost (eq. 1.1 is linear in the flow).
    upper : float
        Largest total the search could give (the sum of the leaks' size caps): no
        interval reaches beyond it [kg/s].

    Examples
    --------
    Two leaks of 1 and 2 g/s, each known to 0.5 g/s, their sum to 0.1 g/s:

    >>> var = lambda w: 1e-8 if w[0] == w[1] else 0.25e-6 * sum(x * x for x in w)
    >>> t = leak_totals([1e-3, 2e-3], [1e-3, 1e-3], [1.0, 1.0], var, CostSettings())
    >>> round(t.mass_flow, 6), [round(x, 6) for x in t.mass_flow_interval]
    (0.003, [0.002804, 0.003196])
    """

    def interval(value: float, weights: Sequence[float]) -> tuple[float, float]:
        half = _Z_95 * math.sqrt(max(variance(weights), 0.0)) if len(weights) else 0.0
        return max(value - half, 0.0), min(value + half, max(upper, value))

    flow = float(sum(mass_flows))
    average = float(sum(average_flows))
    low, high = interval(average, list(average_slopes))
    return LeakTotals(
        mass_flow=flow,
        mass_flow_interval=interval(flow, [1.0] * len(mass_flows)),
        average_mass_flow=average,
        average_mass_flow_interval=(low, high),
        annual_cost=annual_cost(average, settings),
        annual_cost_interval=(annual_cost(low, settings), annual_cost(high, settings)),
    )
