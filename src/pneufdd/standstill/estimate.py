"""Measurements of a standstill test -> each line's leak with its uncertainty.

The model is linear in the leaks (:mod:`pneufdd.standstill.plan`): every measurement
row sees the locations its state pressurises. In the ``flow`` mode the unknowns are
the leaks' mass flows at the reference pressure (the highest supply pressure of the
test, the regulator's with the least flow), each row scaled by the orifice law to its
own supply pressure (a choked leak's flow is proportional to its pressure, eq. 4.3)
and, for a line leak, to its line's pressure: the leak draws its air through the
line's fill path (valve and tube, eq. 4.6, the description's), so its line stands below
the supply by the path's drop at the leak's flow (:func:`line_pressure`; a 60 SLPM leak
behind festo-dsd's CPE10 valve and 1.5 m of 2.9 mm tube: 0.55 bar, 9 % of its flow; three
passes of the fit, each from the previous sizes),
plus one zero error per flow meter with a prior of the meter's zero tolerance
(:data:`ZERO_TOLERANCE` of its span); in the ``decay`` mode the unknowns are the leaks'
effective areas, and a row is a state's total area. Rows are weighted by their
standard error and :data:`MODEL_ERROR` of their value.

Leaks are never negative and rarely many, so the estimate is the **sparsest
non-negative** explanation: no leak, the best single leak, the best pair, each by
bounded weighted least squares (``scipy.optimize.lsq_linear``); a leak is reported
when it lowers the misfit by more than :data:`CHI2_STEP` and exceeds
:data:`MIN_LEAK_SLPM` and three standard errors, a second one on the same terms. The
explanations of the same size that fit as well (within :data:`ALTERNATIVE_CHI2`) are
its alternatives: what the plan cannot separate. Standard errors come from the fit
(the measurement noise) with the size tolerance in quadrature (the flow meter's span,
or the decay's volume and thermal model, :data:`SIZE_TOLERANCE`). The locations the
plan separates on their own also get their estimate from the full least-squares fit
(``lines``), whatever the sparse search found.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import brentq, lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.physics.constants import P_ATM
from pneufdd.physics.flow import isa_mass_flow
from pneufdd.physics.leaks import leak_mass_flow
from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.standstill.analyse import Measurement
from pneufdd.standstill.plan import StandstillPlan

__all__ = [
    "FoundLeak",
    "StandstillResult",
    "estimate_leaks",
    "line_pressure",
]

ZERO_TOLERANCE = 0.003
"""A flow meter's zero error as a fraction of its span: Festo SFAM/SFAB +-0.3 % FS
(docs/plant-variation.md) [-]."""
MODEL_ERROR = {"flow": 0.02, "decay": 0.05}
"""Relative error of a row beyond its noise: the leaks' line pressures a little below
the supply's, the thermal model and volumes of a decay [-]."""
SIZE_TOLERANCE = {"flow": 0.03, "decay": 0.10}
"""Relative tolerance added to a reported size: the meter's span (SFAB +-3 %), or the
connected volume of the description and the thermal model of a decay [-]."""
CHI2_STEP = 25.0
"""Drop of the weighted misfit a leak must bring (five standard errors) [-]."""
ALTERNATIVE_CHI2 = 9.0
"""Misfit above the best within which an explanation is an alternative [-]."""
MIN_LEAK_SLPM = 1.0
"""Smallest leak reported [SLPM]."""
PATH_PASSES = 3
"""Fits: the first with every leak at the supply's pressure, then each line leak at
its line's pressure below its fill path, from the previous fit's sizes [-]."""


@dataclass(frozen=True)
class FoundLeak:
    """One leak found: where, how large, and what explains the test as well."""

    location: str
    flow_slpm: float
    std_slpm: float
    area_mm2: float
    alternatives: tuple[tuple[str, ...], ...] = ()


@dataclass(frozen=True)
class StandstillResult:
    """What :func:`estimate_leaks` found (``to_dict`` for JSON)."""

    machine: str
    mode: str
    reference_pressure_pa: float
    leaks: tuple[FoundLeak, ...]
    lines: dict[str, tuple[float, float]]
    not_separated: tuple[tuple[str, ...], ...]
    states: tuple[dict[str, Any], ...]
    misfit: dict[str, float] = field(default_factory=dict)

    @property
    def leak_found(self) -> bool:
        """Whether any leak was found."""
        return bool(self.leaks)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        out = asdict(self)
        out["leak_found"] = self.leak_found
        return out

    def lines_text(self) -> list[str]:
        """The findings as lines for a terminal."""
        bar_g = (self.reference_pressure_pa - 101_325.0) / 1e5
        out = [
            f"standstill test of {self.machine} ({self.mode}): {len(self.states)} states "
            f"measured; sizes at {bar_g:.2f} bar(g)"
        ]
        for leak in self.leaks:
            text = f"leak at {leak.location}: {leak.flow_slpm:.1f} +- {leak.std_slpm:.1f} SLPM"
            if leak.alternatives:
                alt = "; ".join(" + ".join(a) for a in leak.alternatives)
                text += f" (explained as well by: {alt})"
            out.append(text)
        if not self.leaks:
            out.append("no leak found")
        for loc, (value, std) in self.lines.items():
            out.append(f"  {loc}: {value:.1f} +- {std:.1f} SLPM (separated on its own)")
        for group in self.not_separated:
            out.append("  not separated on their own: " + ", ".join(group))
        return out


@dataclass(frozen=True)
class _Model:
    """The weighted linear model: rows, columns (leaks, then meter zero errors)."""

    design: FloatArray
    target: FloatArray
    n_leaks: int
    prior: FloatArray  # standard deviations of the nuisance columns


def line_pressure(supply_pa: float, path_cv: float, path_xt: float, area_m2: float) -> float:
    """Pressure of a line whose leak of effective area ``area_m2`` draws its air from the
    manifold at ``supply_pa`` through the line's fill path (valve and tube, eq. 4.6):
    the pressure at which the path passes what the leak (eq. 4.3) blows [Pa].

    Examples
    --------
    A 60 SLPM leak behind festo-dsd's CPE10 valve (Cv 0.16) and 1.5 m of 2.9 mm tube
    (path Cv 0.081) at 4.95 bar(g) stands its line 0.55 bar lower:

    >>> from pneufdd.physics.leaks import leak_area
    >>> area = leak_area(60.0, "SLPM", reference_pressure=597_000.0)
    >>> round(line_pressure(597_000.0, 0.081, 0.9, area) / 1e5, 3)
    5.419
    """
    if area_m2 <= 0.0 or supply_pa <= P_ATM:
        return supply_pa

    def balance(p_line: float) -> float:
        path = float(isa_mass_flow(supply_pa, p_line, path_cv, path_xt))
        return path - float(leak_mass_flow(p_line, area_m2))

    if balance(P_ATM + 1.0) <= 0.0:  # the path cannot feed the leak above the atmosphere
        return P_ATM + 1.0
    return float(brentq(balance, P_ATM + 1.0, supply_pa, xtol=1.0))


def _factors(plan: StandstillPlan, pressure: float, areas: FloatArray, p_ref: float) -> FloatArray:
    """Per location, the flow of its leak at the supply pressure ``pressure`` relative to
    the same leak free at ``p_ref``: a line leak blows at its line's pressure, below the
    supply's by its fill path's drop [-]."""
    per_ref = float(leak_mass_flow(p_ref, 1.0))
    out = np.full(len(plan.locations), float(leak_mass_flow(pressure, 1.0)) / per_ref)
    for k, loc in enumerate(plan.locations):
        if loc in plan.line_paths and areas[k] > 0.0:
            cv, xt = plan.line_paths[loc]
            p_line = line_pressure(pressure, cv, xt, float(areas[k]))
            out[k] = float(leak_mass_flow(p_line, 1.0)) / per_ref
    return out


def _model(
    plan: StandstillPlan, rows: Sequence[Measurement], p_ref: float, areas: FloatArray
) -> _Model:
    inc = plan.incidence()
    n = len(plan.locations)
    meters = (
        [plan.supply_flow_channel, *plan.line_flow_channels.values()] if plan.mode == "flow" else []
    )
    design, target = [], []
    per_area = float(leak_mass_flow(p_ref, 1.0))
    for m in rows:
        if plan.mode == "decay":
            # a line leak drains its line through the fill path: seen from the supply it
            # is an orifice smaller by the flow at its line's pressure over the supply's
            seen = _factors(plan, m.pressure_pa, areas, p_ref) * (
                per_area / float(leak_mass_flow(m.pressure_pa, 1.0))
            )
            sigma = np.hypot(m.area_std_m2, MODEL_ERROR["decay"] * abs(m.area_m2)) + 1e-9
            design.append(inc[m.state] * seen / sigma)
            target.append(m.area_m2 / sigma)
            continue
        scale = _factors(plan, m.pressure_pa, areas, p_ref)
        for j, channel in enumerate(meters):
            value, se = m.flows_kg_s[channel]
            sigma = np.hypot(se, MODEL_ERROR["flow"] * abs(value)) + 1e-7
            row = np.zeros(n + len(meters))
            if channel == plan.supply_flow_channel:
                row[:n] = inc[m.state] * scale
            else:
                location = next(k for k, c in plan.line_flow_channels.items() if c == channel)
                k = plan.locations.index(location)
                row[k] = inc[m.state, k] * scale[k]
            row[n + j] = 1.0
            design.append(row / sigma)
            target.append(value / sigma)
    prior = np.array([ZERO_TOLERANCE * plan.meter_spans_kg_s.get(c, 0.0) + 1e-9 for c in meters])
    return _Model(np.array(design), np.array(target), n, prior)


_Fit = tuple[float, FloatArray, FloatArray]
"""A fit: weighted misfit, the leaks' values and their standard errors."""


def _fit(model: _Model, support: Sequence[int]) -> _Fit:
    """Misfit, values and standard errors of the leaks in ``support`` (>= 0) and the
    nuisances (with their prior)."""
    cols = [*support, *range(model.n_leaks, model.design.shape[1])]
    a = model.design[:, cols]
    nuis = len(cols) - len(support)
    prior_rows = np.zeros((nuis, len(cols)))
    for j in range(nuis):
        prior_rows[j, len(support) + j] = 1.0 / model.prior[j]
    a_full = np.vstack([a, prior_rows]) if nuis else a
    b_full = np.concatenate([model.target, np.zeros(nuis)])
    low = np.r_[np.zeros(len(support)), np.full(nuis, -np.inf)]
    if a_full.shape[1] == 0:
        return float(b_full @ b_full), np.empty(0), np.empty(0)
    sol = lsq_linear(a_full, b_full, bounds=(low, np.full(low.size, np.inf)), method="bvls")
    r = a_full @ sol.x - b_full
    cov = np.linalg.pinv(a_full.T @ a_full)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return float(r @ r), sol.x[: len(support)], std[: len(support)]


def _to_slpm(plan: StandstillPlan, value: float, p_ref: float) -> tuple[float, float]:
    """A fitted value (flow at p_ref, or area) as SLPM at p_ref, and its area [mm^2]."""
    if plan.mode == "decay":  # an unconstrained estimate may be negative: signed
        flow = float(kg_s_to_slpm(float(leak_mass_flow(p_ref, abs(value)))))
        return float(np.copysign(flow, value)), value * 1e6
    area = value / float(leak_mass_flow(p_ref, 1.0))
    return float(kg_s_to_slpm(value)), area * 1e6


def _reported(
    plan: StandstillPlan, support: tuple[int, ...], x: FloatArray, std: FloatArray, p_ref: float
) -> list[FoundLeak]:
    out = []
    tol = SIZE_TOLERANCE[plan.mode]
    for k, value, se in zip(support, x, std, strict=True):
        flow, area = _to_slpm(plan, float(value), p_ref)
        se_flow = abs(_to_slpm(plan, float(value + se), p_ref)[0] - flow)
        out.append(FoundLeak(plan.locations[k], flow, float(np.hypot(se_flow, tol * flow)), area))
    return out


def _area(plan: StandstillPlan, value: float, p_ref: float) -> float:
    """A fitted value (flow at ``p_ref``, or area) as an effective area [m^2]."""
    if plan.mode == "decay":
        return max(value, 0.0)
    return max(value, 0.0) / float(leak_mass_flow(p_ref, 1.0))


def _significant(leaks: list[FoundLeak]) -> bool:
    return all(
        leak.flow_slpm >= MIN_LEAK_SLPM and leak.flow_slpm > 3.0 * leak.std_slpm for leak in leaks
    )


def _separated_lines(
    plan: StandstillPlan, model: _Model, p_ref: float
) -> dict[str, tuple[float, float]]:
    """The full least-squares estimate of each location the plan separates [SLPM]."""
    if not plan.separable:
        return {}
    n_nuis = model.design.shape[1] - model.n_leaks
    prior = np.zeros((n_nuis, model.design.shape[1]))
    for j in range(n_nuis):
        prior[j, model.n_leaks + j] = 1.0 / model.prior[j]
    a = np.vstack([model.design, prior])
    b = np.concatenate([model.target, np.zeros(n_nuis)])
    pinv = np.linalg.pinv(a)
    x = pinv @ b
    std = np.sqrt(np.clip(np.diag(pinv @ pinv.T), 0.0, None))
    out = {}
    for loc in plan.separable:
        k = plan.locations.index(loc)
        flow, _ = _to_slpm(plan, float(x[k]), p_ref)
        se = abs(_to_slpm(plan, float(x[k] + std[k]), p_ref)[0] - flow)
        out[loc] = (flow, float(np.hypot(se, SIZE_TOLERANCE[plan.mode] * abs(flow))))
    return out


def estimate_leaks(plan: StandstillPlan, rows: Sequence[Measurement]) -> StandstillResult:
    """The leaks the measured states show (module docstring).

    Parameters
    ----------
    plan : StandstillPlan
        The test.
    rows : sequence of Measurement
        From :func:`pneufdd.standstill.analyse.measure_states`.

    Returns
    -------
    StandstillResult
    """
    pressures = [m.pressure_pa for m in rows if np.isfinite(m.pressure_pa)]
    p_ref = max(pressures) if pressures else plan.reference_pressure_pa
    n = len(plan.locations)
    areas = np.zeros(n)  # first pass: every leak at the supply's pressure
    for _ in range(PATH_PASSES):
        model = _model(plan, rows, p_ref, areas)
        chi_empty = _fit(model, ())[0]
        singles: dict[tuple[int, ...], _Fit] = {(k,): _fit(model, (k,)) for k in range(n)}
        pairs: dict[tuple[int, ...], _Fit] = {
            pair: _fit(model, pair) for pair in itertools.combinations(range(n), 2)
        }
        # each location's line pressure from the size it would have alone (or in the
        # best pair), for the next pass
        areas = np.array([_area(plan, float(singles[(k,)][1][0]), p_ref) for k in range(n)])
        if pairs:
            top = min(pairs, key=lambda s: pairs[s][0])
            for k, value in zip(top, pairs[top][1], strict=True):
                areas[k] = _area(plan, float(value), p_ref)
    best1 = min(singles, key=lambda s: singles[s][0])
    best2 = min(pairs, key=lambda s: pairs[s][0]) if pairs else best1
    chosen: tuple[int, ...] = ()
    candidates: dict[tuple[int, ...], _Fit] = {}
    one = _reported(plan, best1, singles[best1][1], singles[best1][2], p_ref)
    if chi_empty - singles[best1][0] > CHI2_STEP and _significant(one):
        chosen, candidates = best1, singles
    two = _reported(plan, best2, pairs[best2][1], pairs[best2][2], p_ref) if pairs else []
    if chosen and singles[best1][0] - pairs[best2][0] > CHI2_STEP and _significant(two):
        chosen, candidates = best2, pairs
    leaks: list[FoundLeak] = []
    if chosen:
        fit = candidates[chosen]
        best = fit[0]
        alternatives = tuple(
            tuple(plan.locations[k] for k in s)
            for s, f in candidates.items()
            if s != chosen and f[0] <= best + max(ALTERNATIVE_CHI2, 0.1 * best)
        )
        leaks = [
            FoundLeak(x.location, x.flow_slpm, x.std_slpm, x.area_mm2, alternatives)
            for x in _reported(plan, chosen, fit[1], fit[2], p_ref)
        ]
    states = tuple(
        {
            "state": plan.states[m.state].name,
            "start_s": m.start_s,
            "end_s": m.end_s,
            "pressure_pa": m.pressure_pa,
            **(
                {c: float(kg_s_to_slpm(v)) for c, (v, _) in m.flows_kg_s.items()}
                if plan.mode == "flow"
                else {"area_mm2": m.area_m2 * 1e6}
            ),
        }
        for m in rows
    )
    return StandstillResult(
        machine=plan.machine,
        mode=plan.mode,
        reference_pressure_pa=p_ref,
        leaks=tuple(leaks),
        lines=_separated_lines(plan, model, p_ref),
        not_separated=plan.groups,
        states=states,
        misfit={
            "none": chi_empty,
            "best_single": singles[best1][0],
            "best_pair": pairs[best2][0] if pairs else float("nan"),
        },
    )
