"""What a diagnosis found: one :class:`LeakFinding` per leak, and the :class:`Diagnosis`.

A leak found on a run is reported once, as a :class:`LeakFinding`: its location and
ambiguity group, its flows [kg/s], its equivalent orifice [m], its annual cost and the
confidence in it. The quantities are SI; the units an engineer reads (SLPM: 0 degC,
1013 mbar, 1.294 kg/m^3; mm) are read-only properties computed from them
(:mod:`pneufdd.physics.units`). :class:`Diagnosis` gathers the findings with the
detection's statistics, the fit of the decomposition
(:class:`~pneufdd.diagnosis.localisation.search.Localisation`) and the notes, and writes
the ``--json`` summary (:meth:`Diagnosis.to_dict`) and the leak table
(:meth:`Diagnosis.to_pandas`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.detection.residuals import SupplyCheck
from pneufdd.diagnosis.localisation.remainder import Remainder
from pneufdd.diagnosis.localisation.search import Localisation
from pneufdd.diagnosis.reference.sensor_sets import SensorSetReport
from pneufdd.location import Location
from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.signals.quality import MAX_REPAIR_S

if TYPE_CHECKING:
    import pandas as pd

    from pneufdd.diagnosis.cost import CostSettings, LeakTotals

__all__ = ["FAULT_TYPES", "Diagnosis", "Finding", "GroupMember", "LeakFinding", "summary_sentence"]

M_TO_MM = 1e3
"""Millimetres per metre, for the orifice diameter an engineer reads [mm/m]."""

DAYS_PER_YEAR = 365.0
"""Calendar days per year, for a repair's payback [d]."""


@dataclass(frozen=True)
class LeakFinding:
    """One leak found on a run: where, how large, what it costs (SI values).

    Made by :func:`pneufdd.diagnosis.cost.cost_leaks`; :attr:`Diagnosis.leaks` holds
    one per leak, largest annual cost first.

    Attributes
    ----------
    location : Location
        Most likely location.
    mass_flow : float
        Nominal leak flow: while its line is pressurised, at the machine's supply
        pressure (what an ultrasonic detector finds) [kg/s].
    average_mass_flow : float
        Mean leaked flow over an operating cycle (``mass_flow`` when unknown, see
        ``cost_basis``) [kg/s].
    orifice_diameter : float
        Equivalent sharp-edged orifice (C_d = 0.61) of the nominal flow [m].
    annual_cost : float
        Cost per year by eq. 1.1 of the average flow [$].
    confidence : float
        Confidence that a leak lies in the ambiguity group [-].
    ambiguity_group : tuple of Location
        Locations the sensors cannot tell apart (best first, ``location`` included).
    cost_basis : str
        :data:`~pneufdd.diagnosis.cost.COST_BASIS_AVERAGE` or
        :data:`~pneufdd.diagnosis.cost.COST_BASIS_CONTINUOUS`.
    group_mass_flows : tuple of float
        Nominal flow each member of the ambiguity group would need to explain the run
        (empty when not known) [kg/s].
    mass_flow_interval : tuple of float
        95 % interval of ``mass_flow`` from the fit (NaN when not known) [kg/s].
    repair_cost : float
        Expected cost of repairing it (:func:`pneufdd.diagnosis.cost.repair_cost`;
        NaN when not known) [$].
    repair_kind : str
        What is likely repaired there.

    Examples
    --------
    >>> from pneufdd.location import SUPPLY
    >>> from pneufdd.physics.units import slpm_to_kg_s
    >>> leak = LeakFinding(SUPPLY, slpm_to_kg_s(30.0), slpm_to_kg_s(30.0), 1.2e-3,
    ...                    310.0, 0.9, (SUPPLY,), "nominal flow, continuous leakage assumed")
    >>> round(leak.flow_slpm, 9), round(leak.orifice_mm, 9)
    (30.0, 1.2)
    """

    location: Location
    mass_flow: float
    average_mass_flow: float
    orifice_diameter: float
    annual_cost: float
    confidence: float
    ambiguity_group: tuple[Location, ...]
    cost_basis: str
    group_mass_flows: tuple[float, ...] = ()
    mass_flow_interval: tuple[float, float] = (math.nan, math.nan)
    repair_cost: float = math.nan
    repair_kind: str = ""

    @property
    def flow_slpm(self) -> float:
        """Nominal leak flow [SLPM: 0 degC, 1013 mbar]."""
        return float(kg_s_to_slpm(self.mass_flow))

    @property
    def average_flow_slpm(self) -> float:
        """Mean leaked flow over an operating cycle [SLPM: 0 degC, 1013 mbar]."""
        return float(kg_s_to_slpm(self.average_mass_flow))

    @property
    def orifice_mm(self) -> float:
        """Equivalent sharp-edged orifice diameter [mm]."""
        return M_TO_MM * self.orifice_diameter

    @property
    def payback_days(self) -> float:
        """Days of its annual cost that pay its repair (inf when it costs nothing) [d]."""
        if not math.isfinite(self.repair_cost):
            return math.nan
        if self.annual_cost <= 0:
            return math.inf
        return DAYS_PER_YEAR * self.repair_cost / self.annual_cost


FAULT_TYPES = (
    "leak",
    "internal-leak",
    "throttle",
    "cushion",
    "friction",
    "valve",
    "switch",
    "supply",
)
"""Fault types a :class:`Finding` names (the catalogue's families, ``docs/faults.md``)."""


def _finite_or_none(x: float | None) -> float | None:
    """``x`` as a JSON number, None when missing or not finite."""
    return None if x is None or not math.isfinite(x) else float(x)


_UNIT_LABEL = {"%": "% of Cv"}
"""How a size's unit reads for a kind whose ``%`` means something particular."""


@dataclass(frozen=True)
class GroupMember:
    """One explanation in a finding's ambiguity group.

    Attributes
    ----------
    fault_type : str
        One of :data:`FAULT_TYPES`.
    kind : str
        ``leak`` or a kind of :data:`~pneufdd.sim.faults.FAULT_KINDS`.
    location : str
        Where: ``supply``, a line (``PRESS_B``), an actuator (``PRESS``) or a switch.
    size : float
        Size it needs to explain the run, in ``unit`` (signed: a throttle -40 % is 40 %
        closed).
    unit : str
        ``SLPM`` (leaks, internal leaks), ``%`` (throttle: of its Cv; friction),
        ``ms``, ``bar``.

    Examples
    --------
    >>> GroupMember("throttle", "throttle", "PRESS_B", -40.0, "%").describe()
    'PRESS_B throttle -40 % of Cv'
    >>> GroupMember("leak", "leak", "supply", 31.04, "SLPM").describe()
    'supply leak 31.0 SLPM'
    """

    fault_type: str
    kind: str
    location: str
    size: float
    unit: str

    def describe(self) -> str:
        """``LOCATION KIND SIZE UNIT``, as an engineer reads it."""
        unit = self.unit
        if self.kind in ("throttle", "cushion"):  # % of the screw's Cv
            unit = _UNIT_LABEL.get(self.unit, self.unit)
        size = f"{self.size:.1f}" if self.unit == "SLPM" else f"{self.size:+.3g}"
        if self.unit in ("%", "ms"):
            size = f"{self.size:+.0f}"
        return f"{self.location} {self.kind} {size} {unit}".strip()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "type": self.fault_type,
            "kind": self.kind,
            "location": self.location,
            "size": _finite_or_none(self.size),
            "unit": self.unit,
        }


@dataclass(frozen=True)
class Finding:
    """What is wrong, as one finding: a leak or another fault (issue 34).

    Attributes
    ----------
    fault_type : str
        One of :data:`FAULT_TYPES`.
    kind : str
        ``leak`` or a kind of :data:`~pneufdd.sim.faults.FAULT_KINDS`.
    location : str
        Most likely place.
    size : float
        Its size in its own unit (``unit``).
    unit : str
        ``SLPM`` (leaks and internal leaks: flow at the supply pressure), ``%``
        (a throttle's Cv; friction), ``ms`` (valve delay, late switch), ``bar``
        (regulator drift).
    ambiguity_group : tuple of GroupMember
        Explanations the sensors cannot tell apart, the finding's own first; may span
        types.
    confidence : float
        Confidence that the fault lies in the ambiguity group [-].
    annual_cost : float or None
        A leak's annual cost (eq. 1.1) [$/yr]; None for other faults.
    cycle_time_change : float or None
        Change of the cycle's duration the fault causes, per cycle [s] (by the twin at
        the fitted size); None for leaks.
    step_change : tuple of (int, float) or None
        The step (1-based) whose duration the fault changes most and by how much [s]
        (by the twin at the fitted size): "+790 ms on step 1"; None for leaks.

    Examples
    --------
    >>> f = Finding("throttle", "throttle", "PRESS_B", -40.0, "%",
    ...             (GroupMember("throttle", "throttle", "PRESS_B", -40.0, "%"),
    ...              GroupMember("friction", "friction", "PRESS", 60.0, "%")), 0.8, None, 0.21)
    >>> f.describe()
    'PRESS_B throttle -40 % of Cv or PRESS friction +60 %'
    """

    fault_type: str
    kind: str
    location: str
    size: float
    unit: str
    ambiguity_group: tuple[GroupMember, ...]
    confidence: float
    annual_cost: float | None = None
    cycle_time_change: float | None = None
    step_change: tuple[int, float] | None = None

    def describe(self) -> str:
        """The finding and its ambiguity group in one line."""
        members = self.ambiguity_group or (
            GroupMember(self.fault_type, self.kind, self.location, self.size, self.unit),
        )
        return " or ".join(m.describe() for m in members)

    @property
    def types(self) -> tuple[str, ...]:
        """The fault types its ambiguity group spans, its own first.

        Examples
        --------
        >>> f = Finding("leak", "leak", "DNC_B", 12.0, "SLPM",
        ...             (GroupMember("leak", "leak", "DNC_B", 12.0, "SLPM"),
        ...              GroupMember("internal-leak", "valve-leak-out", "DNC_B", 12.0, "SLPM")),
        ...             0.9, 1200.0)
        >>> f.types, f.claims_leak
        (('leak', 'internal-leak'), False)
        """
        seen = [self.fault_type]
        seen += [m.fault_type for m in self.ambiguity_group if m.fault_type not in seen]
        return tuple(dict.fromkeys(seen))

    @property
    def claims_leak(self) -> bool:
        """True when it says a leak and nothing else: no other type in its group.

        A leak whose group holds an internal leak (the sensors cannot tell a line's leak
        from its spool's leak to the exhaust) says "a leak or an internal leak"; its air
        is lost either way and keeps its cost.
        """
        return self.types == ("leak",)

    def consequence(self) -> str:
        """What it costs: a leak's annual cost, another fault's cycle time per cycle."""
        if self.annual_cost is not None:
            return f"{self.annual_cost:,.0f} $/yr"
        if self.cycle_time_change is not None:
            text = f"{1e3 * self.cycle_time_change:+.0f} ms per cycle"
            if self.step_change is not None:
                step, change = self.step_change
                text += f", {1e3 * change:+.0f} ms on step {step}"
            return text
        return ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``findings`` of ``pneufdd diagnose --json``)."""

        num = _finite_or_none
        return {
            "type": self.fault_type,
            "types": list(self.types),
            "kind": self.kind,
            "location": self.location,
            "size": num(self.size),
            "unit": self.unit,
            "confidence": num(self.confidence),
            "ambiguity_group": [m.to_dict() for m in self.ambiguity_group],
            "annual_cost": num(self.annual_cost),
            "cycle_time_change_s": num(self.cycle_time_change),
            "step_change": None
            if self.step_change is None
            else {"step": self.step_change[0], "duration_change_s": num(self.step_change[1])},
            "text": self.describe(),
        }


@dataclass(frozen=True)
class Diagnosis:
    """Everything :func:`~pneufdd.diagnosis.engine.diagnose` found about one run.

    Attributes
    ----------
    detected : bool
        Run-level decision of the per-cycle statistic.
    cycles_analyzed : int
        Complete cycles of the run used.
    cycle_scores : ndarray
        Per-cycle statistic ``T`` [-].
    cycle_threshold : float
        Per-cycle threshold of ``T`` [-].
    run_score, run_threshold : float
        The run's statistic (median ``T`` of its cycles, or the mean for references
        saved with ``run_statistic="mean"``) and its threshold [-].
    p_value : float
        Probability of a leak-free run scoring at least ``run_score`` [-].
    reference_false_alarm_rate : float
        Cross-validated per-cycle false-alarm rate on the reference cycles [-].
    band_fraction : ndarray
        Per-cycle out-of-band fraction of the band method (empty without traces) [-].
    band_alarms : int
        Cycles flagged by the band method.
    leaks : list of LeakFinding
        Leaks found, largest annual cost first.
    total_annual_cost : float
        Sum of the leaks' annual costs [$].
    localisation : Localisation or None
        Fit statistics of the decomposition, its alternative explanations and the
        locations it sized, largest flow first (None when not run).
    observed_change : ndarray
        Mean feature change of the run against the reference [feature unit].
    settings : CostSettings
        Economic inputs of eq. 1.1 the leaks were costed with.
    notes : list of str
        Plain-language remarks (missing signatures, unexplained deviations...).
    startup_cycles : int
        Complete cycles at the start of the run left out as start-up cycles
        (:attr:`~pneufdd.diagnosis.reference.model.DetectionSettings.startup_cycles`).
    cycles_skipped : tuple of (int, str)
        Complete cycles of the run left out by the gap rule
        (:mod:`pneufdd.signals.quality`): each one's number and the channel whose
        gap skipped it.
    gaps_repaired : int
        Short gaps (NaN, infinite or out-of-range samples) repaired by interpolation.
    supply : SupplyCheck, optional
        The eq. 4.19-4.21 verdict on the supply flow and pressure against the
        reference (None without supply sensors):
        :func:`pneufdd.diagnosis.detection.residuals.supply_check`.
    sensor_set : SensorSetReport, optional
        What the reference's sensor set can and cannot locate or size
        (:func:`pneufdd.diagnosis.reference.sensor_sets.sensor_set_report`).
    totals : LeakTotals, optional
        The leaks' total nominal flow, mean flow and cost with 95 % intervals from
        the fit (None when no leak was located).
    repair_order : tuple of int
        Indices into :attr:`leaks` in the order to repair them: most saved per repair
        dollar first (:func:`pneufdd.diagnosis.cost.repair_order`).
    remainder : Remainder, optional
        What the leaks leave unexplained: the share explained, the largest leak that
        could still hide at each other location, and whether more leaks may be
        present; for a run without a detected leak, the largest leak each location
        could hide (None without leak signatures).
    findings : list of Finding
        What is wrong: every leak of ``leaks`` and any other fault found, one
        :class:`Finding` each (``docs/faults.md``, Diagnosis of fault types).
    faults_tested : bool
        True when faults other than leaks were fitted with the twin (the leaks left
        the run poorly explained); their cost is then paid.
    """

    detected: bool
    cycles_analyzed: int
    cycle_scores: FloatArray
    cycle_threshold: float
    run_score: float
    run_threshold: float
    p_value: float
    reference_false_alarm_rate: float
    band_fraction: FloatArray
    band_alarms: int
    leaks: list[LeakFinding]
    total_annual_cost: float
    localisation: Localisation | None
    observed_change: FloatArray
    settings: CostSettings
    notes: list[str] = field(default_factory=list)
    startup_cycles: int = 0
    cycles_skipped: tuple[tuple[int, str], ...] = ()
    gaps_repaired: int = 0
    supply: SupplyCheck | None = None
    sensor_set: SensorSetReport | None = None
    totals: LeakTotals | None = None
    repair_order: tuple[int, ...] = ()
    remainder: Remainder | None = None
    findings: list[Finding] = field(default_factory=list)
    faults_tested: bool = False

    def summary(self) -> str:
        """One sentence: what was found, how much of the deviation it explains, and
        what could still hide (the message of the console, the report and the JSON).

        Examples
        --------
        >>> from pneufdd.diagnosis.localisation.remainder import HiddenLeak
        >>> from pneufdd.location import Location
        >>> r = Remainder(0.88, (HiddenLeak(Location("HGD2", "A"), 2.6e-4),
        ...                      HiddenLeak(Location("HMPL_V", "B"), 1.9e-4)),
        ...               more_leaks_possible=True)
        >>> text = Diagnosis(True, 10, np.zeros(10), 1.0, 5.0, 1.0, 0.0, 0.0, np.zeros(0),
        ...     0, [], 0.0, None, np.zeros(3), None, remainder=r).summary()
        >>> print(text.replace("; ", ";\\n"))
        leak detected: 0 leaks located, explaining 88 % of the deviation;
        more leaks may be present: up to 12 SLPM more at HGD2, 8.8 SLPM at HMPL_V (95 % bounds)
        """
        others = [f for f in self.findings if f.fault_type != "leak"]
        if self.detected and others and not self.leaks:
            first = others[0]
            return f"fault detected: {first.fault_type} ({first.describe()}); no leak reported"
        if self.detected and self.faults_tested and not self.findings:
            return (
                "deviation detected: neither leaks nor another fault of the catalogue "
                "explain it (see the notes)"
            )
        return summary_sentence(self.detected, len(self.leaks), self.remainder)

    def to_pandas(self) -> pd.DataFrame:
        """The leaks as a table, one row per leak, largest annual cost first.

        Columns: ``location``, ``ambiguity_group`` (comma separated),
        ``flow_slpm`` (while the line is pressurised) and ``average_flow_slpm`` (over
        the operating cycle) [SLPM: 0 degC, 1013 mbar], ``orifice_mm`` [mm],
        ``annual_cost`` [$/yr], ``confidence`` [-], ``cost_basis``.
        """
        import pandas as pd

        return pd.DataFrame(
            [
                {
                    "location": str(leak.location),
                    "ambiguity_group": ", ".join(str(x) for x in leak.ambiguity_group),
                    "flow_slpm": leak.flow_slpm,
                    "average_flow_slpm": leak.average_flow_slpm,
                    "orifice_mm": leak.orifice_mm,
                    "annual_cost": leak.annual_cost,
                    "confidence": leak.confidence,
                    "cost_basis": leak.cost_basis,
                }
                for leak in self.leaks
            ],
            columns=[
                "location",
                "ambiguity_group",
                "flow_slpm",
                "average_flow_slpm",
                "orifice_mm",
                "annual_cost",
                "confidence",
                "cost_basis",
            ],
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible summary (the ``--json`` output of ``pneufdd diagnose``)."""

        num = _finite_or_none
        return {
            "detected": self.detected,
            "cycles_analyzed": self.cycles_analyzed,
            "startup_cycles_excluded": self.startup_cycles,
            "data_gaps": {
                "rule": "samples NaN, infinite or out of their quantity's physical range are "
                f"gaps; gaps up to {MAX_REPAIR_S:g} s are interpolated, a cycle touched by a "
                "longer one is skipped (docs/data-quality.md)",
                "cycles_skipped": len(self.cycles_skipped),
                "skipped": [
                    {"cycle": cycle, "channel": channel} for cycle, channel in self.cycles_skipped
                ],
                "gaps_repaired": self.gaps_repaired,
            },
            "leaks": [
                {
                    "location": str(leak.location),
                    "flow_slpm": num(leak.flow_slpm),
                    "average_flow_slpm": num(leak.average_flow_slpm),
                    "orifice_mm": num(leak.orifice_mm),
                    "annual_cost": num(leak.annual_cost),
                    "cost_basis": leak.cost_basis,
                    "confidence": num(leak.confidence),
                    "ambiguity_group": [str(x) for x in leak.ambiguity_group],
                    "flow_slpm_interval": [
                        num(float(kg_s_to_slpm(x))) for x in leak.mass_flow_interval
                    ],
                    "repair_cost": num(leak.repair_cost),
                    "repair": leak.repair_kind,
                    "payback_days": num(leak.payback_days),
                }
                for leak in self.leaks
            ],
            "repair_order": [str(self.leaks[i].location) for i in self.repair_order],
            "summary": self.summary(),
            "totals": None if self.totals is None else _totals_dict(self.totals),
            "remainder": None if self.remainder is None else _remainder_dict(self.remainder),
            "alternative_explanations": []
            if self.localisation is None
            else [
                {
                    "locations": [str(x) for x in alt.locations],
                    "flows_slpm": [num(float(kg_s_to_slpm(f))) for f in alt.mass_flows],
                    "rss": num(alt.rss),
                }
                for alt in self.localisation.alternatives
            ],
            "findings": [finding.to_dict() for finding in self.findings],
            "faults_tested": self.faults_tested,
            "total_annual_cost": num(self.total_annual_cost),
            "supply_check": None if self.supply is None else self.supply.to_dict(),
            "sensor_set": None if self.sensor_set is None else self.sensor_set.to_dict(),
            "detection": {
                "statistic": "supply-fluctuation-projected standardised step distance",
                "run_score": num(self.run_score),
                "run_threshold": num(self.run_threshold),
                "p_value": num(self.p_value),
                "cycle_scores": [num(x) for x in self.cycle_scores],
                "cycle_threshold": num(self.cycle_threshold),
                "cycles_flagged": int(np.sum(self.cycle_scores > self.cycle_threshold)),
                "reference_false_alarm_rate": num(self.reference_false_alarm_rate),
                "band_cycles_flagged": self.band_alarms,
                "band_out_of_band_fraction": [num(x) for x in self.band_fraction],
            },
            "fit": None
            if self.localisation is None
            else {
                "explained_fraction": num(self.localisation.explained),
                "rss": num(self.localisation.rss),
                "rss_without_leak": num(self.localisation.rss_null),
                "dof": self.localisation.dof,
                "checked_by_simulation": self.localisation.checked_by_simulation,
            },
            "cost_settings": {
                "basis": "annual_cost = eq. 1.1 of average_flow_slpm (mean leaked flow "
                "over the operating cycle) x hours; flow_slpm = leak flow while its line "
                "is pressurised, at the machine's supply pressure",
                "hours": self.settings.hours,
                "price_per_kwh": self.settings.price_per_kwh,
                "kw_per_100_cfm": self.settings.kw_per_100_cfm,
                "repair_fitting": self.settings.repair_fitting,
                "repair_seal": self.settings.repair_seal,
                "seal_share": self.settings.seal_share,
                "repair_basis": "repair order: annual cost per expected repair cost, "
                "highest first (docs/cost.md)",
            },
            "notes": list(self.notes),
        }


def _slpm(x: float) -> float | None:
    return None if not math.isfinite(x) else float(kg_s_to_slpm(x))


def _totals_dict(totals: LeakTotals) -> dict[str, Any]:
    """The ``totals`` entry of :meth:`Diagnosis.to_dict`."""

    def num(x: float) -> float | None:
        return None if not math.isfinite(x) else float(x)

    return {
        "flow_slpm": _slpm(totals.mass_flow),
        "flow_slpm_interval": [_slpm(x) for x in totals.mass_flow_interval],
        "average_flow_slpm": _slpm(totals.average_mass_flow),
        "average_flow_slpm_interval": [_slpm(x) for x in totals.average_mass_flow_interval],
        "annual_cost": num(totals.annual_cost),
        "annual_cost_interval": [num(x) for x in totals.annual_cost_interval],
        "level": totals.level,
        "basis": "sum of the reported leaks; interval from the fit's covariance of their "
        "sizes (the remainder says what may hide elsewhere)",
    }


def _remainder_dict(remainder: Remainder) -> dict[str, Any]:
    """The ``remainder`` entry of :meth:`Diagnosis.to_dict`."""
    return {
        "explained_fraction": remainder.explained,
        "more_leaks_possible": remainder.more_leaks_possible,
        "reasons": list(remainder.reasons),
        "complete_confidence": remainder.complete_confidence,
        "level": remainder.level,
        "basis": "largest additional leak at each location that the residual cannot "
        "reject (one-sided profile-likelihood bound, the reported leaks refit)",
        "hidden_leaks_by_group": [
            {"group": name, "flow_slpm": _slpm(flow), "at_size_cap": cap}
            for name, flow, cap in remainder.groups()
        ],
        "hidden_leaks": [
            {"location": str(h.location), "flow_slpm": _slpm(h.mass_flow), "at_size_cap": h.at_cap}
            for h in remainder.hidden
        ],
    }


def _flow_text(flow: float) -> str:
    slpm = float(kg_s_to_slpm(flow))
    return f"{slpm:.0f}" if slpm >= 10 else f"{slpm:.2g}"


def summary_sentence(detected: bool, n_leaks: int, remainder: Remainder | None) -> str:
    """The sentence of :meth:`Diagnosis.summary` [-].

    Examples
    --------
    >>> summary_sentence(False, 0, None)
    'no leak detected'
    """
    if not detected:
        head = "no leak detected"
        if remainder is None or not remainder.hidden:
            return head
        name, flow, cap = remainder.groups()[0]
        largest = "any size" if cap else f"{_flow_text(flow)} SLPM"
        return f"{head}; the largest leak the run cannot rule out: {largest} at {name} (95 % bound)"
    found = f"leak detected: {n_leaks} leak{'' if n_leaks == 1 else 's'} located"
    if remainder is None:
        return found
    found += f", explaining {100 * remainder.explained:.0f} % of the deviation"
    groups = remainder.groups()[:2]
    where = ", ".join(
        f"{'any size' if cap else _flow_text(flow) + ' SLPM'} at {name}"
        for name, flow, cap in groups
    )
    if remainder.more_leaks_possible:
        if not groups:
            return f"{found}; more leaks may be present"
        first, rest = where.split(", ", 1) if ", " in where else (where, "")
        more = f"up to {first.replace(' at ', ' more at ', 1)}" + (f", {rest}" if rest else "")
        return f"{found}; more leaks may be present: {more} ({100 * remainder.level:.0f} % bounds)"
    if not groups:
        return f"{found}; no sign of further leaks"
    return (
        f"{found}; no sign of further leaks (the largest that could hide: {where}, "
        f"{100 * remainder.level:.0f} % bounds)"
    )
