"""Scoring a campaign: the figures of the acceptance tables and the reliability table.

Every diagnosed run becomes one :class:`RunOutcome` per sensor set; a :class:`Tally`
accumulates them per (machine, plant scale, sensor set) and computes the figures:

- single-leak runs: detected, true location inside a reported ambiguity group, mean
  group size, relative size error of the true location's estimate (median, 90th
  percentile), runs that report a spurious second leak;
- leak-free runs: flagged (run level); per cycle: leak-free and leak cycles flagged;
- two leaks: both true locations inside the reported groups (and, separately,
  inside the groups or one listed alternative explanation);
- many leaks (:class:`MultiTally`, per number of leaks): all true locations inside
  the reported groups, the total flow's error and its interval, and whether a
  missed leak lies within the remainder the diagnosis states;
- diagnosis time per run;
- **reliability**: reported leaks binned by their confidence against the share of them
  that are true (a reported leak is true when a true leak location lies in its
  ambiguity group: that is what its confidence claims).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.location import Location

__all__ = [
    "CONFIDENCE_BINS",
    "MultiTally",
    "RunOutcome",
    "Tally",
    "outcome_from_record",
]

CONFIDENCE_BINS: tuple[float, ...] = (0.0, 0.5, 0.7, 0.8, 0.9, 0.95, 1.0000001)
"""Edges of the confidence bins of the reliability table [-]."""


def _rate(a: int, b: int) -> float | None:
    """``a / b``; None when nothing was measured (``b`` 0)."""
    return None if b == 0 else a / b


def _median(values: FloatArray) -> float | None:
    """The median of ``values``; None when there are none."""
    return float(np.median(values)) if values.size else None


def _p90(values: FloatArray) -> float | None:
    """The 90th percentile of ``values``; None when there are none."""
    return float(np.percentile(values, 90)) if values.size else None


@dataclass(frozen=True)
class ReportedLeak:
    """One leak a diagnosis reported (locations as names)."""

    location: str
    group: tuple[str, ...]
    group_flows: tuple[float, ...]
    confidence: float


@dataclass(frozen=True)
class RunOutcome:
    """What one diagnosis of one run said, next to the truth.

    Attributes
    ----------
    kind : {"single", "free", "pair", "multi"}
        The run's design.
    truth : dict
        True leak location -> nominal flow at the description's nominal supply
        pressure [kg/s].
    detected : bool
        Run-level decision.
    cycles, cycles_flagged : int
        Cycles judged and flagged alone.
    leaks : tuple of ReportedLeak
        Leaks reported.
    alternatives : tuple of tuple of str
        Alternative explanations listed.
    seconds : float
        Diagnosis time [s].
    simulated : bool
        Explanations were checked by simulation.
    total_flow : float
        Sum of the reported leaks' nominal flows [kg/s].
    total_interval : tuple of float
        Its 95 % interval [kg/s].
    more_leaks : bool
        The diagnosis says more leaks may be present.
    hidden : dict
        Location -> largest leak that could still hide there [kg/s].
    """

    kind: str
    truth: dict[str, float]
    detected: bool
    cycles: int
    cycles_flagged: int
    leaks: tuple[ReportedLeak, ...]
    alternatives: tuple[tuple[str, ...], ...]
    seconds: float
    simulated: bool
    total_flow: float = math.nan
    total_interval: tuple[float, float] = (math.nan, math.nan)
    more_leaks: bool = False
    hidden: Mapping[str, float] = field(default_factory=dict)


def outcome_from_record(record: Mapping[str, Any]) -> RunOutcome:
    """A :class:`RunOutcome` from its JSON record (``runs.jsonl``)."""
    return RunOutcome(
        kind=str(record["kind"]),
        truth={str(k): float(v) for k, v in record["truth"].items()},
        detected=bool(record["detected"]),
        cycles=int(record["cycles"]),
        cycles_flagged=int(record["cycles_flagged"]),
        leaks=tuple(
            ReportedLeak(
                str(leak["location"]),
                tuple(str(x) for x in leak["group"]),
                tuple(float(x) for x in leak["group_flows"]),
                float(leak["confidence"]),
            )
            for leak in record["leaks"]
        ),
        alternatives=tuple(tuple(str(x) for x in alt) for alt in record["alternatives"]),
        seconds=float(record["seconds"]),
        simulated=bool(record["simulated"]),
        total_flow=_float(record.get("total_flow")),
        total_interval=tuple(  # type: ignore[arg-type]
            _float(x) for x in record.get("total_flow_interval", (None, None))
        ),
        more_leaks=bool(record.get("more_leaks", False)),
        hidden={str(k): float(v) for k, v in record.get("hidden", {}).items()},
    )


def _float(x: Any) -> float:
    return math.nan if x is None else float(x)


def _one_actuator(locations: set[str]) -> bool:
    """True when ``locations`` are the extend and the retract line of one actuator."""
    if len(locations) != 2:
        return False
    a, b = (Location.parse(name) for name in sorted(locations))
    return a.is_other_line(b)


def _pct(a: int, b: int) -> str:
    return "n/a" if b == 0 else f"{100.0 * a / b:.2f} % ({a}/{b})"


@dataclass
class Tally:
    """Outcome counts of one machine, plant scale and sensor set."""

    leak_runs: int = 0
    detected: int = 0
    inside: int = 0
    group_sizes: list[int] = field(default_factory=list)
    size_errors: list[float] = field(default_factory=list)
    single_extra_leak: int = 0
    single_with_alternatives: int = 0
    free_runs: int = 0
    free_flagged: int = 0
    cycle_leak: int = 0
    cycle_leak_flagged: int = 0
    cycle_free: int = 0
    cycle_free_flagged: int = 0
    pairs: int = 0
    pairs_both: int = 0
    pairs_both_alt: int = 0
    pairs_one_actuator: int = 0
    pairs_one_actuator_both: int = 0
    pair_group_sizes: list[int] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    simulated: int = 0
    confidences: list[float] = field(default_factory=list)
    confidence_true: list[bool] = field(default_factory=list)
    by_location: dict[str, list[bool]] = field(default_factory=dict)
    multi: dict[int, MultiTally] = field(default_factory=dict)

    def add(self, run: RunOutcome) -> None:
        """Count one run."""
        self.seconds.append(run.seconds)
        self.simulated += int(run.simulated)
        for leak in run.leaks:
            self.confidences.append(leak.confidence)
            self.confidence_true.append(any(loc in leak.group for loc in run.truth))
        if run.kind == "multi":
            self.cycle_leak += run.cycles
            self.cycle_leak_flagged += run.cycles_flagged
            self.multi.setdefault(len(run.truth), MultiTally()).add(run)
            return
        if run.kind == "free":
            self.free_runs += 1
            self.free_flagged += int(run.detected)
            self.cycle_free += run.cycles
            self.cycle_free_flagged += run.cycles_flagged
            return
        self.cycle_leak += run.cycles
        self.cycle_leak_flagged += run.cycles_flagged
        if run.kind == "single":
            ((loc, flow),) = run.truth.items()
            self.leak_runs += 1
            self.detected += int(run.detected)
            hit = [leak for leak in run.leaks if loc in leak.group]
            ok = bool(run.detected and hit)
            self.inside += int(ok)
            self.by_location.setdefault(loc, []).append(ok)
            self.single_extra_leak += int(len(run.leaks) > 1)
            self.single_with_alternatives += int(bool(run.alternatives))
            if hit:
                leak = hit[0]
                self.group_sizes.append(len(leak.group))
                estimate = leak.group_flows[leak.group.index(loc)]
                self.size_errors.append(abs(estimate / flow - 1.0))
            elif run.leaks:
                self.group_sizes.append(len(run.leaks[0].group))
            return
        self.pairs += 1
        locations = set(run.truth)
        groups = [set(leak.group) for leak in run.leaks]
        both = run.detected and all(any(loc in g for g in groups) for loc in locations)
        self.pairs_both += int(both)
        if _one_actuator(locations):
            # counted apart too: with a 5/2 valve one of the two lines is pressurised
            # at almost every moment, so at the supply meter such a pair can draw air
            # much like a supply leak (docs/results/710M.md)
            self.pairs_one_actuator += 1
            self.pairs_one_actuator_both += int(both)
        self.pair_group_sizes.extend(len(g) for g in groups)
        alternative = any(locations <= set(alt) for alt in run.alternatives)
        self.pairs_both_alt += int(both or (run.detected and alternative))

    def figures(self) -> dict[str, float | int | None]:
        """The figures as numbers (rates as fractions; None when not measured)."""

        errors = np.asarray(self.size_errors)
        return {
            "single_runs": self.leak_runs,
            "detected": _rate(self.detected, self.leak_runs),
            "in_group": _rate(self.inside, self.leak_runs),
            "mean_group": float(np.mean(self.group_sizes)) if self.group_sizes else None,
            "size_error_median": _median(errors),
            "size_error_p90": _p90(errors),
            "spurious_second_leak": _rate(self.single_extra_leak, self.leak_runs),
            "single_with_alternative": _rate(self.single_with_alternatives, self.leak_runs),
            "leak_free_runs": self.free_runs,
            "leak_free_flagged": _rate(self.free_flagged, self.free_runs),
            "cycle_leak_flagged": _rate(self.cycle_leak_flagged, self.cycle_leak),
            "cycle_free_flagged": _rate(self.cycle_free_flagged, self.cycle_free),
            "pair_runs": self.pairs,
            "pairs_both": _rate(self.pairs_both, self.pairs),
            "pairs_both_or_alternative": _rate(self.pairs_both_alt, self.pairs),
            "pair_runs_one_actuator": self.pairs_one_actuator,
            "pairs_one_actuator_both": _rate(self.pairs_one_actuator_both, self.pairs_one_actuator),
            "mean_group_pairs": (
                float(np.mean(self.pair_group_sizes)) if self.pair_group_sizes else None
            ),
            "seconds_mean": float(np.mean(self.seconds)) if self.seconds else None,
            "seconds_max": float(np.max(self.seconds)) if self.seconds else None,
            "checked_by_simulation": _rate(self.simulated, len(self.seconds)),
            "confident_true": self.confident_share(0.9),
        }

    def confident_share(self, level: float) -> float | None:
        """Share of reported leaks with confidence >= ``level`` that are true [-]."""
        conf = np.asarray(self.confidences)
        true = np.asarray(self.confidence_true, dtype=bool)
        sel = conf >= level
        return float(np.mean(true[sel])) if np.any(sel) else None

    def reliability(
        self, edges: Sequence[float] = CONFIDENCE_BINS
    ) -> list[tuple[float, float, int, float | None, float | None]]:
        """Rows ``(low, high, reported, share true, mean confidence)`` per bin."""
        conf = np.asarray(self.confidences)
        true = np.asarray(self.confidence_true, dtype=bool)
        rows = []
        for low, high in itertools.pairwise(edges):
            sel = (conf >= low) & (conf < high)
            n = int(np.sum(sel))
            rows.append(
                (
                    float(low),
                    float(min(high, 1.0)),
                    n,
                    float(np.mean(true[sel])) if n else None,
                    float(np.mean(conf[sel])) if n else None,
                )
            )
        return rows

    def lines(
        self,
        targets: Mapping[str, float] | None = None,
        multi_targets: Mapping[int, Mapping[str, float]] | None = None,
    ) -> list[str]:
        """The figures as printable lines (with PASS/FAIL against ``targets``, and the
        many-leak designs' against ``multi_targets`` per number of leaks)."""
        out: list[str] = []
        singles_or_pairs = bool(self.leak_runs or self.free_runs or self.pairs)
        if singles_or_pairs:
            out.extend(self._lines(targets))
        for k, multi in sorted(self.multi.items()):
            out.extend(multi.lines(k, (multi_targets or {}).get(k)))
        if not singles_or_pairs:
            out.extend(self._reliability_lines())
        return out

    def _reliability_lines(self) -> list[str]:
        out = ["reliability (confidence bin: reported leaks, share true, mean confidence):"]
        for low, high, n, share, mean in self.reliability():
            out.append(
                f"  [{low:.2f}, {high:.2f}{']' if high >= 1.0 else ')'}: {n:5d} leaks, "
                f"{_pcts(share)} true, mean confidence {_num(mean, 3)}"
            )
        return out

    def multi_figures(self) -> dict[str, dict[str, float | int | None]]:
        """The many-leak designs' figures, by the number of leaks per run."""
        return {str(k): multi.figures() for k, multi in sorted(self.multi.items())}

    def _lines(self, targets: Mapping[str, float] | None = None) -> list[str]:
        f = self.figures()
        out = [
            f"single-leak runs detected:            {_pct(self.detected, self.leak_runs)}",
            f"true location inside group:           {_pct(self.inside, self.leak_runs)}",
            f"mean ambiguity-group size:            {_num(f['mean_group'], 3)}",
            f"size error, median / 90th percentile: {_pcts(f['size_error_median'])} / "
            f"{_pcts(f['size_error_p90'])}",
            "single-leak runs with a spurious 2nd leak: "
            f"{_pct(self.single_extra_leak, self.leak_runs)}",
            "single-leak runs listing an alternative:   "
            f"{_pct(self.single_with_alternatives, self.leak_runs)}",
            f"leak-free runs flagged:               {_pct(self.free_flagged, self.free_runs)}",
            "per cycle: leak cycles flagged        "
            f"{_pct(self.cycle_leak_flagged, self.cycle_leak)}",
            "per cycle: leak-free cycles flagged   "
            f"{_pct(self.cycle_free_flagged, self.cycle_free)}",
            f"two leaks, both found:                {_pct(self.pairs_both, self.pairs)}",
            f"  ... or one alternative explanation: {_pct(self.pairs_both_alt, self.pairs)}",
            "  pairs on both lines of one actuator, both found: "
            f"{_pct(self.pairs_one_actuator_both, self.pairs_one_actuator)}",
            f"  mean group size on pair runs:       {_num(f['mean_group_pairs'], 3)}",
            f"diagnosis time per run, mean / max:   {_num(f['seconds_mean'], 2)} s / "
            f"{_num(f['seconds_max'], 2)} s; checked by simulation "
            f"{_pct(self.simulated, len(self.seconds))}",
        ]
        worst = sorted(self.by_location.items(), key=lambda kv: float(np.mean(kv[1])))[:5]
        if worst:
            out.append(
                "lowest location accuracy: "
                + ", ".join(f"{loc} {100 * np.mean(v):.0f} %" for loc, v in worst)
            )
        out.extend(self._reliability_lines())
        if targets:
            checks = self.checks(targets)
            out.append(
                "targets: "
                + "; ".join(f"{k}: {'PASS' if v else 'FAIL'}" for k, v in checks.items())
            )
        return out

    def checks(self, targets: Mapping[str, float]) -> dict[str, bool]:
        """PASS/FAIL of each target (``{figure: bound}``; see :data:`TARGETS`)."""
        f = self.figures()
        out = {}
        for name, bound in targets.items():
            value = f.get(name)
            if value is None:
                out[f"{name} (not measured)"] = False
            elif name in LOWER_IS_BETTER:
                out[f"{name} <= {bound:g}"] = float(value) <= bound
            else:
                out[f"{name} >= {bound:g}"] = float(value) >= bound
        return out


LOWER_IS_BETTER = frozenset(
    {
        "mean_group",
        "size_error_median",
        "size_error_p90",
        "spurious_second_leak",
        "leak_free_flagged",
        "total_flow_error_median",
        "total_flow_error_p90",
        "spurious_per_run",
    }
)


@dataclass
class MultiTally:
    """Outcome counts of the runs with one number of simultaneous leaks.

    A true leak is *found* when its location lies in a reported leak's ambiguity
    group. A run that misses a leak *states the remainder* when the diagnosis says
    more leaks may be present, or when its bound of a hidden leak at every missed
    location is at least that leak's true flow (it said a leak that large may still
    be there); both are counted apart too.
    """

    runs: int = 0
    detected: int = 0
    all_found: int = 0
    true_leaks: int = 0
    found_leaks: int = 0
    total_errors: list[float] = field(default_factory=list)
    interval_covers: int = 0
    runs_missing: int = 0
    missing_stated: int = 0
    missing_flagged: int = 0
    missed_leaks: int = 0
    missed_within_bound: int = 0
    spurious: int = 0
    reported: list[int] = field(default_factory=list)
    group_sizes: list[int] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    simulated: int = 0

    def add(self, run: RunOutcome) -> None:
        """Count one run."""
        self.runs += 1
        self.detected += int(run.detected)
        self.seconds.append(run.seconds)
        self.simulated += int(run.simulated)
        groups = [set(leak.group) for leak in run.leaks]
        found = {loc for loc in run.truth if run.detected and any(loc in g for g in groups)}
        missed = [loc for loc in run.truth if loc not in found]
        self.true_leaks += len(run.truth)
        self.found_leaks += len(found)
        self.all_found += int(not missed)
        self.reported.append(len(run.leaks))
        self.group_sizes.extend(len(g) for g in groups)
        self.spurious += sum(1 for g in groups if not g & set(run.truth))
        truth = sum(run.truth.values())
        estimate = run.total_flow if math.isfinite(run.total_flow) else 0.0
        if truth > 0:
            self.total_errors.append(abs(estimate / truth - 1.0))
        low, high = run.total_interval
        self.interval_covers += int(math.isfinite(low) and low <= truth <= high)
        if missed:
            self.runs_missing += 1
            self.missing_flagged += int(run.more_leaks)
            within = [run.hidden.get(loc, 0.0) >= run.truth[loc] for loc in missed]
            self.missed_leaks += len(missed)
            self.missed_within_bound += sum(within)
            self.missing_stated += int(run.more_leaks or all(within))

    def figures(self) -> dict[str, float | int | None]:
        """The figures as numbers (rates as fractions; None when not measured)."""

        errors = np.asarray(self.total_errors)
        return {
            "runs": self.runs,
            "detected": _rate(self.detected, self.runs),
            "all_in_group": _rate(self.all_found, self.runs),
            "leaks_found": _rate(self.found_leaks, self.true_leaks),
            "total_flow_error_median": _median(errors),
            "total_flow_error_p90": _p90(errors),
            "total_within_10pct": _rate(int(np.sum(errors <= 0.10)), int(errors.size)),
            "total_interval_covers": _rate(self.interval_covers, self.runs),
            "runs_missing_a_leak": self.runs_missing,
            "remainder_stated": _rate(self.missing_stated, self.runs_missing),
            "missed_within_bound": _rate(self.missed_within_bound, self.missed_leaks),
            "more_leaks_flagged": _rate(self.missing_flagged, self.runs_missing),
            "spurious_per_run": _rate(self.spurious, self.runs),
            "mean_reported": float(np.mean(self.reported)) if self.reported else None,
            "mean_group": float(np.mean(self.group_sizes)) if self.group_sizes else None,
            "seconds_mean": float(np.mean(self.seconds)) if self.seconds else None,
            "seconds_max": float(np.max(self.seconds)) if self.seconds else None,
            "checked_by_simulation": _rate(self.simulated, self.runs),
        }

    def lines(self, k: int, targets: Mapping[str, float] | None = None) -> list[str]:
        """The figures as printable lines (with PASS/FAIL against ``targets``)."""
        f = self.figures()
        out = [
            f"--- runs with {k} leaks ---",
            f"all {k} leaks inside reported groups: {_pct(self.all_found, self.runs)}",
            f"leaks found:                          {_pct(self.found_leaks, self.true_leaks)}",
            f"total flow error, median / 90th pct:  {_pcts(f['total_flow_error_median'])} / "
            f"{_pcts(f['total_flow_error_p90'])}; within 10 %: "
            f"{_pcts(f['total_within_10pct'])}; interval holds the truth: "
            f"{_pct(self.interval_covers, self.runs)}",
            f"runs missing a leak: {self.runs_missing}; every missed leak within the stated "
            f"remainder: {_pct(self.missing_stated, self.runs_missing)}; 'more leaks may be "
            f"present' said: {_pct(self.missing_flagged, self.runs_missing)}",
            f"missed leaks within their hidden-leak bound: "
            f"{_pct(self.missed_within_bound, self.missed_leaks)}",
            f"reported leaks per run {_num(f['mean_reported'], 2)}, matching no true leak "
            f"{_num(f['spurious_per_run'], 2)}; mean group size {_num(f['mean_group'], 3)}",
            f"diagnosis time per run, mean / max:   {_num(f['seconds_mean'], 2)} s / "
            f"{_num(f['seconds_max'], 2)} s; checked by simulation "
            f"{_pct(self.simulated, self.runs)}",
        ]
        if targets:
            checks = {}
            for name, bound in targets.items():
                value = f.get(name)
                lower = name in LOWER_IS_BETTER
                label = f"{name} {'<=' if lower else '>='} {bound:g}"
                checks[label] = value is not None and (
                    float(value) <= bound if lower else float(value) >= bound
                )
            out.append(
                "targets: "
                + "; ".join(f"{k}: {'PASS' if v else 'FAIL'}" for k, v in checks.items())
            )
        return out


def _num(x: float | int | None, digits: int) -> str:
    return "n/a" if x is None else f"{float(x):.{digits}f}"


def _pcts(x: float | int | None) -> str:
    return "n/a" if x is None else f"{100 * float(x):.1f} %"


def tally(outcomes: Iterable[RunOutcome]) -> Tally:
    """A :class:`Tally` of ``outcomes``."""
    t = Tally()
    for run in outcomes:
        t.add(run)
    return t
