"""Settings of the energy analysis: eq. 1.1's economics, the tolerance, standby hours.

Money follows eq. 1.1 (:class:`pneufdd.diagnosis.cost.CostSettings`: operating hours,
price per kWh, compressor kW per 100 scfm). A lower supply pressure also lowers the
compressor's discharge pressure when this machine is what sets it; the U.S. DOE rule
of thumb prices that: every 2 psi lower, about 1 % less compressor energy (U.S. DOE,
*Improving Compressed Air System Performance: a sourcebook for industry*, 2003, cited
by the dissertation's section 6.2.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from pneufdd.diagnosis.cost import CostSettings
from pneufdd.errors import InputError, describe
from pneufdd.limits import MAX_HOURS_PER_YEAR
from pneufdd.physics.economics import leak_annual_cost
from pneufdd.physics.units import kg_s_to_l_min_anr, kg_s_to_scfm

__all__ = ["DOE_PSI_PER_PERCENT", "EnergySettings", "Money"]

DOE_PSI_PER_PERCENT = 2.0
"""U.S. DOE rule of thumb: every 2 psi of lower system pressure saves about 1 % of the
compressor's energy (dissertation section 6.2.1) [psi per %]."""

MAX_ENERGY_CYCLES = 20
"""Most twin cycles per candidate (each candidate runs them; a search runs dozens)."""


@dataclass(frozen=True)
class Money:
    """A flow of air priced by eq. 1.1 over a year.

    Attributes
    ----------
    mass_flow_kg_s : float
        Mean mass flow [kg/s].
    hours : float
        Hours a year it flows [h].
    kwh : float
        Compressor energy a year [kWh].
    cost : float
        Its cost a year [$ or the price's currency].
    """

    mass_flow_kg_s: float
    hours: float
    kwh: float
    cost: float

    @property
    def air_m3_anr(self) -> float:
        """Air a year [m^3 at ISO 8778 ANR: 20 degC, 100 kPa]."""
        litres_per_min = math.copysign(
            float(kg_s_to_l_min_anr(abs(self.mass_flow_kg_s))), self.mass_flow_kg_s
        )
        return litres_per_min * 60.0 * self.hours / 1000.0

    def to_dict(self) -> dict[str, Any]:
        """JSON form: kg/s, scfm, m^3 ANR, kWh and money a year."""
        return {
            "mass_flow_kg_s": self.mass_flow_kg_s,
            "scfm": math.copysign(
                float(kg_s_to_scfm(abs(self.mass_flow_kg_s))), self.mass_flow_kg_s
            ),
            "air_m3_anr_per_year": self.air_m3_anr,
            "kwh_per_year": self.kwh,
            "cost_per_year": self.cost,
        }


@dataclass(frozen=True)
class EnergySettings:
    """What the energy analysis assumes; every value a user may change.

    Attributes
    ----------
    cost : CostSettings
        Eq. 1.1: operating hours, price per kWh, compressor kW per 100 scfm.
    tolerance : float
        How much longer each step may take, as a fraction of the cycle time [-].
    standby_hours : float or None
        Hours a year the machine stands still with the air on; None: the rest of the
        year, 8760 h minus the operating hours [h].
    restarts_per_year : float
        How often the air would be switched on again if switched off at standstill [-].
    cycle_time_needed_s : float or None
        The cycle time production needs; None: the present one [s]. A longer one lets
        every step slow down in proportion.
    header_follows : bool
        Whether the compressor's discharge pressure follows a lower set point (this
        machine sets it); then the DOE rule's compressor-side saving counts.
    cycles : int
        Twin cycles per candidate (the first, from rest, left out).
    seed : int
        Seed of every twin run.
    resolution_psi : float
        Bisection stops when the feasible and infeasible set points are this close [psi].
    tube_length_m : float
        Tube length of the "shorter tubes" what-if (valves next to their cylinders) [m].
    """

    cost: CostSettings = field(default_factory=CostSettings)
    tolerance: float = 0.02
    standby_hours: float | None = None
    restarts_per_year: float = 250.0
    cycle_time_needed_s: float | None = None
    header_follows: bool = False
    cycles: int = 3
    seed: int = 0
    resolution_psi: float = 0.5
    tube_length_m: float = 0.3

    def __post_init__(self) -> None:
        def check(name: str, value: float | None, low: float, high: float, what: str) -> None:
            if value is None:
                return
            if not (
                isinstance(value, int | float) and math.isfinite(value) and low <= value <= high
            ):
                raise InputError(describe(name, value, f"{low:g} to {high:g} ({what})"))

        check("tolerance (--tolerance)", self.tolerance, 0.001, 0.5, "fraction of the cycle time")
        check("standby hours (--standby-hours)", self.standby_hours, 0.0, MAX_HOURS_PER_YEAR, "h")
        check("restarts per year", self.restarts_per_year, 0.0, 1e6, "per year")
        check("cycle time needed (--cycle-time)", self.cycle_time_needed_s, 1e-3, 3600.0, "s")
        check("twin cycles (--twin-cycles)", self.cycles, 2, MAX_ENERGY_CYCLES, "cycles")
        check("resolution", self.resolution_psi, 0.05, 10.0, "psi")
        check("tube length", self.tube_length_m, 0.01, 100.0, "m")
        if self.cost.hours + self.hours_standstill > MAX_HOURS_PER_YEAR + 1e-9:
            raise InputError(
                describe(
                    "operating + standby hours (--hours, --standby-hours)",
                    self.cost.hours + self.hours_standstill,
                    f"at most {MAX_HOURS_PER_YEAR:g} h a year",
                )
            )

    @property
    def hours_standstill(self) -> float:
        """Hours a year at standstill with the air on [h]."""
        if self.standby_hours is not None:
            return float(self.standby_hours)
        return max(8760.0 - self.cost.hours, 0.0)

    def price(self, mass_flow_kg_s: float, hours: float | None = None) -> Money:
        """A mean mass flow priced by eq. 1.1 over ``hours`` (default the operating hours).

        Examples
        --------
        >>> from pneufdd.physics.units import scfm_to_kg_s
        >>> m = EnergySettings().price(scfm_to_kg_s(100.0))
        >>> round(m.kwh), round(m.cost, 2)
        (126000, 6300.0)
        """
        h = self.cost.hours if hours is None else float(hours)
        magnitude = float(
            leak_annual_cost(
                abs(mass_flow_kg_s),
                hours=h,
                energy_price=self.cost.price_per_kwh,
                kw_per_100_cfm=self.cost.kw_per_100_cfm,
            )
        )
        cost = math.copysign(magnitude, mass_flow_kg_s)
        kwh = float(kg_s_to_scfm(abs(mass_flow_kg_s))) * self.cost.kw_per_100_cfm / 100.0 * h
        return Money(mass_flow_kg_s, h, math.copysign(kwh, mass_flow_kg_s), cost)

    def compressor_side(self, air_kg_s: float, drop_psi: float) -> Money:
        """DOE rule: the compressor energy a ``drop_psi`` lower header saves on ``air_kg_s``.

        ``drop_psi / 2`` % of the energy that compresses the machine's air (eq. 1.1).

        Examples
        --------
        >>> from pneufdd.physics.units import scfm_to_kg_s
        >>> round(EnergySettings().compressor_side(scfm_to_kg_s(100.0), 10.0).cost, 2)
        315.0
        """
        base = self.price(air_kg_s)
        share = drop_psi / DOE_PSI_PER_PERCENT / 100.0
        return Money(0.0, base.hours, base.kwh * share, base.cost * share)

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {
            "hours": self.cost.hours,
            "price_per_kwh": self.cost.price_per_kwh,
            "kw_per_100_cfm": self.cost.kw_per_100_cfm,
            "standby_hours": self.hours_standstill,
            "restarts_per_year": self.restarts_per_year,
            "tolerance_of_cycle_time": self.tolerance,
            "cycle_time_needed_s": self.cycle_time_needed_s,
            "header_follows": self.header_follows,
            "twin_cycles": self.cycles,
            "seed": self.seed,
            "basis": (
                "eq. 1.1: scfm (68 degF, 14.7 psia) x kW per 100 cfm / 100 x hours x price; "
                "compressor side: U.S. DOE, 2 psi lower ~ 1 % less compressor energy"
            ),
        }
