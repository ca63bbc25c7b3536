"""Locate and size leaks: a non-negative decomposition into leak effects.

The observed change of the per-step features of a run against the leak-free
reference, :math:`\\Delta x`, is explained as the vector sum of the effects of one or
two leaks (eqs. 5.23-5.24, generalised from the 2-D vectorized map to all features):

.. math::

    \\Delta x \\approx \\sum_{l \\in M} e_l(a_l), \\qquad a_l \\ge 0,

where :math:`e_l(a)` is location ``l``'s effect at size ``a``
(:class:`~pneufdd.diagnosis.effects.model.LeakEffectModel`). The fit is weighted
(``whiten``): each feature divided by its reference spread, the house-air
fluctuation directions projected out (the space of
:class:`~pneufdd.diagnosis.detection.statistic.CycleDistanceDetector`), the residual scaled to
unit variance for a run mean of ``m`` cycles. Steps:

1. **Signature fits** of every set of one or two locations, exact for the piecewise
   linear effects (:class:`~pneufdd.diagnosis.effects.piecewise.WhitenedEffects`).
2. **Interaction**: the best pairs are refit with their bilinear interaction
   (:meth:`LeakEffectModel.pair_coupling`), so their effects are not taken as additive.
3. **Model choice** (:func:`~pneufdd.diagnosis.localisation.model_choice.choose_leak_count`).
4. **Check by simulation** (:mod:`pneufdd.diagnosis.localisation.check`): when even that leaves a
   residual well above the noise (typically two large leaks), the best explanations
   are simulated with the digital twin and chosen among by their simulated residual.
5. **Ambiguity groups and confidence**
   (:func:`~pneufdd.diagnosis.localisation.model_choice.ambiguity_group`) and **alternative
   explanations** (:func:`~pneufdd.diagnosis.localisation.model_choice.alternative_explanations`,
   :func:`~pneufdd.diagnosis.localisation.model_choice.both_lines_alternatives`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects, Whitener
from pneufdd.diagnosis.localisation.check import (
    SimulatedEffect,
    SimulatedFit,
)
from pneufdd.diagnosis.localisation.model_choice import (
    Best,
    Explanation,
    Fits,
    Subset,
    alternative_explanations,
    ambiguity_group,
    both_lines_alternatives,
    choose_leak_count,
    more_leak_reasons,
    next_leak_weight,
)
from pneufdd.diagnosis.localisation.remainder import (
    HiddenLeak,
    Remainder,
    hidden_leak_bounds,
    model_error_spread,
    size_spread,
)
from pneufdd.diagnosis.localisation.settings import LocalisationSettings, leak_limit
from pneufdd.diagnosis.localisation.simulated import (
    Imitation,
    check_by_simulation,
    simulate_group_competitors,
)
from pneufdd.diagnosis.localisation.subsets import PairTerm, SetSearch
from pneufdd.errors import InputError, describe
from pneufdd.location import SUPPLY, Location

__all__ = ["Localisation", "LocalisationSettings", "SizedLocation", "locate"]


@dataclass(frozen=True)
class SizedLocation:
    """A location the decomposition chose, with the leak flow it needs there.

    The search's own result, before costing: :func:`pneufdd.diagnosis.engine.diagnose`
    reports each leak once, as a :class:`~pneufdd.diagnosis.findings.LeakFinding`
    (with its orifice, average flow and cost) in ``Diagnosis.leaks``.

    Attributes
    ----------
    location : Location
        Most likely location.
    mass_flow : float
        Estimated leak flow at the location's nominal pressure [kg/s].
    ambiguity_group : tuple of Location
        Locations the sensors cannot tell apart from ``location`` (best first,
        ``location`` included); one element when unambiguous.
    group_mass_flows : tuple of float
        Leak flow each group member would need to explain the data [kg/s].
    confidence : float
        Probability-like confidence that a leak lies in the ambiguity group [-].
    """

    location: Location
    mass_flow: float
    ambiguity_group: tuple[Location, ...]
    group_mass_flows: tuple[float, ...]
    confidence: float


@dataclass(frozen=True)
class Localisation:
    """Result of :func:`locate`.

    Attributes
    ----------
    leaks : tuple of SizedLocation
        Locations of the chosen explanation with their leak flows, largest flow
        first (the leaks are reported, costed, in ``Diagnosis.leaks``).
    rss_null : float
        Weighted residual sum of squares without any leak [-].
    rss : float
        Weighted residual sum of squares of the chosen model [-].
    dof : int
        Number of weighted residual components [-].
    explained : float
        ``1 - rss / rss_null``, the fraction of the deviation explained [-].
    alternatives : tuple of Explanation
        Other explanations that share no location with the chosen one yet fit about
        as well (e.g. one supply leak versus leaks on both lines of an actuator
        without line sensors), best first; empty when the chosen one stands alone.
    checked_by_simulation : bool
        True when the explanations were checked and sized by simulation
        (:mod:`pneufdd.diagnosis.localisation.check`); ``rss`` is then the simulated residual.
    remainder : Remainder, optional
        What the leaks leave: the largest leak that could still hide at each other
        location, whether more leaks may be present
        (:mod:`pneufdd.diagnosis.localisation.remainder`).
    size_spread : ndarray, shape (n_leaks, m), optional
        A factor ``F`` of the covariance ``F F^T`` of the leaks' flows, rows in the
        order of :attr:`leaks`: the fit's
        (:func:`~pneufdd.diagnosis.localisation.remainder.size_spread`) beside the
        twin's model error on the plausible plants
        (:func:`~pneufdd.diagnosis.localisation.remainder.model_error_spread`) [kg/s].
    """

    leaks: tuple[SizedLocation, ...]
    rss_null: float
    rss: float
    dof: int
    explained: float
    alternatives: tuple[Explanation, ...] = ()
    checked_by_simulation: bool = False
    remainder: Remainder | None = None
    size_spread: FloatArray | None = None

    def flow_variance(self, weights: FloatArray) -> float:
        """Variance of a weighted sum of the leaks' flows, ``|F^T w|^2`` [(kg/s)^2].

        ``weights`` in the order of :attr:`leaks` (ones: the total flow); inf without
        :attr:`size_spread`.
        """
        if self.size_spread is None or len(self.leaks) == 0:
            return math.inf if self.leaks else 0.0
        w = np.asarray(weights, dtype=np.float64)
        with np.errstate(over="ignore", invalid="ignore"):
            value = float(np.sum((self.size_spread.T @ w) ** 2))
        return value if math.isfinite(value) else math.inf


def _signature_fits(
    model: WhitenedEffects, n_loc: int, max_leaks: int, min_flow: float, rss_null: float
) -> tuple[Fits, Best]:
    """Fits of every set of one or two locations, and the best of each size."""
    best: Best = {0: ((), np.zeros(0), rss_null)}
    fits: Fits = {}
    for k in range(1, min(max_leaks, n_loc, 2) + 1):
        for subset in itertools.combinations(range(n_loc), k):
            coef, rss = model.fit(subset)
            fits[subset] = (coef, rss)
            if np.any(coef < min_flow):
                continue
            if k not in best or rss < best[k][2]:
                best[k] = (subset, coef, rss)
    return fits, best


def _refit_pairs_with_interaction(
    effects: LeakEffectModel,
    model: WhitenedEffects,
    whiten: Whitener,
    fits: Fits,
    best: Best,
    settings: LocalisationSettings,
) -> set[Subset]:
    """Refit the best additive pairs with their bilinear interaction (in place).

    Returns the pairs whose fit now holds the interaction.
    """
    coupling = effects.pair_coupling()
    refit: set[Subset] = set()
    if coupling is None or 2 not in best:
        return refit
    ranked = sorted(
        (fit[1], sub)
        for sub, fit in fits.items()
        if len(sub) == 2 and np.all(fit[0] >= settings.min_mass_flow)
    )
    for _, sub in ranked[: settings.refine_top]:
        term = coupling(*sub)
        if term is None:
            continue
        start = (float(fits[sub][0][0]), float(fits[sub][0][1]))
        a, b, rss = model.refine_pair(sub[0], sub[1], whiten(term)[0], start)
        if rss < fits[sub][1] and min(a, b) >= settings.min_mass_flow:
            fits[sub] = (np.array([a, b]), rss)
            refit.add(sub)
            if rss < best[2][2]:
                best[2] = (sub, fits[sub][0], rss)
    return refit


def _pair_term(effects: LeakEffectModel, whiten: Whitener) -> PairTerm | None:
    """The whitened pairwise interaction of two locations (None: additive model)."""
    coupling = effects.pair_coupling()
    if coupling is None:
        return None

    def term(first: int, second: int) -> FloatArray | None:
        raw = coupling(first, second)
        return None if raw is None else np.asarray(whiten(raw)[0], dtype=np.float64)

    return term


def _forced_member(
    slot: int,
    subset: Subset,
    sizes: FloatArray,
    locations: tuple[Location, ...],
    model: WhitenedEffects,
) -> tuple[int, float] | None:
    """A location that joins the group of ``slot`` whatever the residuals say.

    Both lines of one actuator draw air in every step like a supply leak: of two
    leaks on both lines of one actuator the smaller may stand for a supply leak; of a
    supply leak next to a leak on one line, the supply may stand for a leak on the
    other line (large ``X_B`` plus small ``X_A`` is how "``X_B`` plus a supply leak"
    is usually fitted, and the other way round). Among more leaks the same holds
    for each actuator with both lines chosen, and for the supply leak beside the
    largest leak on one line whose other line is not chosen. Returns the location
    and the size it would need [kg/s] (of more than two leaks: the size of the leak
    it stands for), or None.
    """
    if len(subset) < 2 or SUPPLY not in locations:
        return None
    supply = locations.index(SUPPLY)
    loc = subset[slot]
    candidate: int | None = None
    if loc != supply:
        partner = locations[loc].other_line()
        if partner in locations and locations.index(partner) in subset:
            other = subset.index(locations.index(partner))
            if sizes[slot] <= sizes[other] and (len(subset) > 2 or slot == int(np.argmin(sizes))):
                candidate = supply
    else:
        lines = sorted(
            (
                (-float(sizes[i]), locations.index(locations[x].other_line()))
                for i, x in enumerate(subset)
                if x != supply
                and locations[x].other_line() in locations
                and locations.index(locations[x].other_line()) not in subset
            ),
        )
        if lines:
            candidate = lines[0][1]
    if candidate is None or candidate in subset:
        return None
    if len(subset) > 2:
        return candidate, float(sizes[slot])
    other = subset[1 - slot]
    trial = tuple(sorted((other, candidate)))
    return candidate, float(model.fit(trial)[0][trial.index(candidate)])


def _composite_competitors(
    slot: int, subset: Subset, fits: Fits, locations: tuple[Location, ...]
) -> list[float]:
    """Residuals of two line leaks that stand for a lone supply leak.

    Two line leaks pressurised in complementary parts of the cycle (both lines of one
    actuator, or lines of two actuators) draw air like a supply leak; they compete with
    it for the confidence although they are not one location.
    """
    if len(subset) != 1 or locations[subset[slot]] != SUPPLY:
        return []
    supply = subset[slot]
    return [fit[1] for sub, fit in fits.items() if len(sub) == 2 and supply not in sub]


def _sized_location(
    slot: int,
    subset: Subset,
    sizes: FloatArray,
    fits: Fits,
    model: WhitenedEffects,
    locations: tuple[Location, ...],
    s2: float,
    explained: float,
    settings: LocalisationSettings,
) -> SizedLocation:
    """The chosen leak in ``slot`` with its ambiguity group and confidence."""
    group = ambiguity_group(
        slot,
        subset,
        sizes,
        fits,
        len(locations),
        model.secant,
        s2,
        settings.min_mass_flow,
        settings.group_ratio,
        settings.relative_tolerance,
        settings.collinear_cos,
        _forced_member(slot, subset, sizes, locations, model),
        _composite_competitors(slot, subset, fits, locations),
    )
    return SizedLocation(
        location=locations[group.members[0]],
        mass_flow=float(group.sizes[0]),
        ambiguity_group=tuple(locations[a] for a in group.members),
        group_mass_flows=group.sizes,
        confidence=float(np.clip(group.weight * explained, 0.0, 1.0)),
    )


def locate(
    observed: FloatArray,
    effects: LeakEffectModel,
    whiten: Whitener,
    settings: LocalisationSettings | None = None,
    imitation: Imitation | None = None,
) -> Localisation:
    """Decompose an observed feature change into non-negative leak contributions.

    Parameters
    ----------
    observed : ndarray, shape (n_features,)
        Mean feature change of the run against the leak-free reference
        [feature unit].
    effects : LeakEffectModel
        The machine's leak effects over the same features.
    whiten : callable
        Maps feature-change vectors (rows, feature unit) to weighted residual
        components of unit noise variance [-]: standardisation by the reference
        spread, the supply-fluctuation projection and the run-length scaling.
    settings : LocalisationSettings, optional
        Tuning (defaults as documented there).
    imitation : callable, optional
        ``imitation(larger, smaller)``: the size [kg/s] of the leak ``smaller``
        (``(location index, size)``) that the model error of the leaks ``larger``
        imitates (:func:`pneufdd.diagnosis.engine.imitated_size`); with it, the check
        by simulation takes a third and further leak only when it is more than
        :attr:`LocalisationSettings.imitation_z` times that.

    Returns
    -------
    Localisation
        The leaks, largest first, with ambiguity groups and confidences.

    Examples
    --------
    >>> from pneufdd.diagnosis.effects.signatures import SignatureSet
    >>> sig = SignatureSet(("supply", "X_A"), np.array([[4.0], [4.0]]),
    ...     np.array([[[4.0, 4.0, 4.0]], [[0.0, 8.0, 0.0]]]), ("f1", "f2", "f3"),
    ...     np.array([6e5, 6e5]))
    >>> result = locate(np.array([3.0, 7.0, 3.0]), LeakEffectModel(sig),
    ...                 lambda d: np.atleast_2d(d) * 100.0)
    >>> [(str(leak.location), round(leak.mass_flow, 6)) for leak in result.leaks]
    [('supply', 3.0), ('X_A', 2.0)]
    """
    settings = settings or LocalisationSettings()
    signatures = effects.signatures
    obs = _observation(observed, signatures.n_features)
    locations = effects.locations
    n_loc = len(locations)
    limit = leak_limit(settings, n_loc)
    target = whiten(obs)[0]
    model = WhitenedEffects(
        signatures.sizes, signatures.deltas, whiten, target, settings.max_extrapolation
    )
    rss_null = float(target @ target)
    dof = int(target.size)
    fits, best = _signature_fits(model, n_loc, limit, settings.min_mass_flow, rss_null)
    interacting = _refit_pairs_with_interaction(effects, model, whiten, fits, best, settings)
    search = SetSearch(model, _pair_term(effects, whiten), settings.min_mass_flow)
    chosen = _signature_choice(search, fits, best, dof, limit, settings)
    simulate = _simulator(effects, whiten, settings)
    checked: dict[Subset, SimulatedFit] | None = None
    following = best[chosen + 1][2] if chosen + 1 in best else math.inf
    misfit = best[chosen][2] / max(dof, 1)
    if (
        simulate is not None
        and chosen > 0
        and misfit > settings.misfit_ratio
        and (chosen > 1 or misfit > settings.severe_misfit_ratio)
    ):
        outcome = check_by_simulation(
            target,
            model,
            fits,
            best,
            chosen,
            simulate,
            n_loc,
            dof,
            limit,
            settings,
            effects.threads,
            locations,
            imitation,
        )
        if outcome is not None:
            fits, best, chosen, checked, following = outcome
    subset, coef, rss = best[chosen]
    s2 = max(1.0, rss / max(dof - len(subset), 1))
    if checked is not None and simulate is not None:
        # only simulated explanations are compared: check the alternatives the
        # signature model ranks best in each slot
        simulate_group_competitors(
            target,
            search,
            fits,
            subset,
            coef,
            simulate,
            n_loc,
            settings.group_checks,
            effects.threads,
            checked.get(subset),
        )
    else:
        _signature_competitors(search, fits, subset, coef, rss, s2, settings)
    explained = 0.0 if rss_null <= 0 else max(0.0, 1.0 - rss / rss_null)
    slots = [
        (slot, _sized_location(slot, subset, coef, fits, model, locations, s2, explained, settings))
        for slot in range(len(subset))
    ]
    slots.sort(key=lambda item: -item[1].mass_flow)
    leaks = [leak for _, leak in slots]
    explanations = _alternatives(fits, locations, subset, coef, rss, model, limit, settings)
    if checked is not None and subset in checked:
        residual, jacobian = checked[subset].residual, checked[subset].jacobian
    else:
        residual, jacobian = _signature_residual(search, subset, coef, interacting)
    remainder, spread = _remainder(
        model,
        _plant_deviations(effects, whiten, subset, coef),
        rss,
        following,
        chosen,
        dof,
        limit,
        residual,
        jacobian,
        subset,
        s2,
        explained,
        locations,
        settings,
    )
    order = [slot for slot, _ in slots]
    return Localisation(
        tuple(leaks),
        rss_null,
        float(rss),
        dof,
        float(explained),
        tuple(explanations),
        checked is not None,
        remainder,
        None if spread is None else spread[order],
    )


def _observation(observed: FloatArray, n_features: int) -> FloatArray:
    """The observed change as a checked float array."""
    obs = np.asarray(observed, dtype=np.float64)
    if obs.shape != (n_features,):
        raise InputError(describe("shape of observed feature change", obs.shape, [(n_features,)]))
    if not np.all(np.isfinite(obs)):
        raise InputError(describe("observed feature change", "NaN or infinite", "finite"))
    return obs


def _simulator(
    effects: LeakEffectModel, whiten: Whitener, settings: LocalisationSettings
) -> SimulatedEffect | None:
    """The whitened simulated effect of a set of leaks (None: no check by simulation)."""
    if not (settings.simulate_explanations and effects.can_simulate):
        return None

    def simulate(leaks: Mapping[int, float]) -> FloatArray | None:
        change = effects.simulate(leaks)
        return None if change is None else np.asarray(whiten(change)[0], dtype=np.float64)

    return simulate


def _signature_choice(
    search: SetSearch, fits: Fits, best: Best, dof: int, limit: int, settings: LocalisationSettings
) -> int:
    """How many leaks the signatures explain the run with; sets of three and more
    are grown from the chosen pair (one level further than taken: what a further
    leak would explain)."""
    gain, first = settings.min_relative_gain, settings.first_leak_gain
    chosen = choose_leak_count(best, dof, min(limit, 2), gain, first)
    n_loc = search.model.lo.shape[0]
    if chosen == 2 and n_loc > 2:

        def accept(k: int) -> bool:
            return k <= limit and choose_leak_count(best, dof, k, gain, first) == k

        search.grow(fits, best, min(limit + 1, n_loc), accept)
        chosen = choose_leak_count(best, dof, limit, gain, first)
    elif chosen + 1 not in best and chosen < n_loc and chosen + 1 <= 2:
        # one level further, for what a further leak would explain: the best pair
        pairs = [(fit[1], sub) for sub, fit in fits.items() if len(sub) == 2]
        if not pairs:
            pair_rss = search.model.pair_rss
            first_loc, second = np.unravel_index(int(np.argmin(pair_rss)), pair_rss.shape)
            sub = (int(min(first_loc, second)), int(max(first_loc, second)))
            pairs = [(float(pair_rss[sub]), sub)]
            fits_ahead = {sub: search.model.fit(sub)}
        else:
            fits_ahead = {sub: fits[sub] for _, sub in pairs}
        valid = [
            (rss, sub) for rss, sub in pairs if np.all(fits_ahead[sub][0] >= settings.min_mass_flow)
        ]
        if valid:
            rss, sub = min(valid)
            best[2] = (sub, fits_ahead[sub][0], rss)
    return chosen


def _signature_competitors(
    search: SetSearch,
    fits: Fits,
    subset: Subset,
    sizes: FloatArray,
    rss: float,
    s2: float,
    settings: LocalisationSettings,
) -> None:
    """Fits of the chosen set with one leak swapped, for the ambiguity groups (in place).

    One or two leaks: exact. Three or more: each location in each slot, the others
    kept (:meth:`SetSearch.swaps`), refit when it could join the group (its residual
    within three times the group's margins).
    """
    model = search.model
    if len(subset) <= 2:
        n_loc = model.lo.shape[0]
        for loc in subset:
            others = tuple(x for x in subset if x != loc)
            for alt in range(n_loc):
                if alt not in others:
                    trial = tuple(sorted((*others, alt)))
                    fits.setdefault(trial, model.fit(trial))
        return
    margin = max(settings.relative_tolerance * rss, 2.0 * s2 * np.log(1.0 / settings.group_ratio))
    search.swaps(subset, sizes, fits, refit_below=rss + 3.0 * margin)


def _alternatives(
    fits: Fits,
    locations: tuple[Location, ...],
    subset: Subset,
    sizes: FloatArray,
    rss: float,
    model: WhitenedEffects,
    limit: int,
    settings: LocalisationSettings,
) -> list[Explanation]:
    """Disjoint explanations of at most ``limit`` leaks that fit about as well, and the
    both-lines readings of a supply leak."""
    explanations = alternative_explanations(
        {sub: fit for sub, fit in fits.items() if len(sub) <= limit},
        locations,
        subset,
        rss,
        settings.min_mass_flow,
        settings.relative_tolerance,
        settings.max_alternatives,
    )
    for both_lines in both_lines_alternatives(
        locations,
        subset,
        sizes,
        model,
        rss,
        settings.min_mass_flow,
        settings.both_lines_max_ratio,
        settings.max_alternatives,
    ):
        if all(set(both_lines.locations) != set(e.locations) for e in explanations):
            explanations.append(both_lines)
    return explanations


def _signature_residual(
    search: SetSearch, subset: Subset, sizes: FloatArray, interacting: set[Subset]
) -> tuple[FloatArray, FloatArray]:
    """The signature model's whitened residual of a set and its Jacobian by size."""
    model = search.model
    coupling = search.coupling(subset) if len(subset) > 2 or subset in interacting else None
    residual = model.target - model.set_effect(subset, sizes, coupling)
    columns = [model.derivative(loc, float(x)) for loc, x in zip(subset, sizes, strict=True)]
    jacobian = np.column_stack(columns) if columns else np.zeros((model.target.size, 0))
    if coupling is not None:
        k = len(subset)
        pull = np.einsum("j,ijn->in", sizes, coupling * (1.0 - np.eye(k))[..., None])
        jacobian = jacobian + pull.T
    return residual, jacobian


def _plant_deviations(
    effects: LeakEffectModel, whiten: Whitener, subset: Subset, sizes: FloatArray
) -> FloatArray | None:
    """Whitened deviation of each plausible plant's joint effect of the leaks from the
    twin's, the leaks' deviations summed (None without plausible plants)."""
    parts = [
        effects.signatures.deviations(loc, float(x)) for loc, x in zip(subset, sizes, strict=True)
    ]
    found = [part for part in parts if part is not None]
    if not found or len(found) != len(parts):
        return None
    return np.asarray(whiten(np.sum(found, axis=0)), dtype=np.float64)


def _remainder(
    model: WhitenedEffects,
    deviations: FloatArray | None,
    rss: float,
    following: float,
    chosen: int,
    dof: int,
    limit: int,
    residual: FloatArray,
    jacobian: FloatArray,
    subset: Subset,
    s2: float,
    explained: float,
    locations: tuple[Location, ...],
    settings: LocalisationSettings,
) -> tuple[Remainder, FloatArray | None]:
    """What the chosen leaks leave (:mod:`.remainder`) and the spread of their sizes,
    the fit's and the plausible plants' ``deviations`` (whitened, one row per plant);
    ``following`` is the residual of the best explanation with one leak more [-]."""
    unexplained = max(0.0, rss - (dof - len(subset)))
    bounds, at_cap = hidden_leak_bounds(
        model, residual, jacobian, subset, s2, unexplained=unexplained
    )
    hidden = sorted(
        (
            HiddenLeak(locations[i], float(bounds[i]), bool(at_cap[i]))
            for i in range(len(locations))
            if i not in subset
        ),
        key=lambda leak: -leak.mass_flow,
    )
    reasons = more_leak_reasons(
        rss,
        following,
        chosen,
        dof,
        limit,
        settings.min_relative_gain,
        settings.severe_misfit_ratio,
    )
    remainder = Remainder(
        explained=explained,
        hidden=tuple(hidden),
        more_leaks_possible=bool(reasons),
        reasons=reasons,
        complete_confidence=next_leak_weight(rss, following, chosen, dof),
        next_leak_gain=1.0 - following / rss if math.isfinite(following) and rss > 0 else math.nan,
    )
    if not subset:
        return remainder, None
    spread = size_spread(jacobian, s2)
    if deviations is not None:
        spread = np.hstack([spread, model_error_spread(jacobian, deviations, unexplained)])
    return remainder, spread
