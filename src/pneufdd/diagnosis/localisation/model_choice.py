"""Choosing among leak explanations: how many leaks, which are indistinguishable, what else fits.

Given the fits of every set of one or two candidate locations (sizes and whitened
residual, from the signatures or by simulation), three decisions remain, each a
function here:

- :func:`choose_leak_count`: one more leak only when the residual drops by an
  information-criterion penalty *and* a minimum relative gain;
- :func:`ambiguity_group`: for each chosen leak, the locations the sensors cannot tell
  apart from it (nearly the same residual, Akaike-type weight, or collinear whitened
  signature) and the confidence of the group;
- :func:`alternative_explanations` and :func:`both_lines_alternatives`: explanations
  that share no location with the chosen one yet fit about as well (a supply leak
  versus leaks on both lines of one actuator draw air alike).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects
from pneufdd.location import SUPPLY, Location

__all__ = [
    "Explanation",
    "Fits",
    "Group",
    "alternative_explanations",
    "ambiguity_group",
    "both_lines_alternatives",
    "choose_leak_count",
    "more_leak_reasons",
    "next_leak_weight",
    "same_actuator_pair",
]

Subset = tuple[int, ...]
Fits = dict[Subset, tuple[FloatArray, float]]
"""``subset of location indices -> (sizes [kg/s], whitened residual [-])``."""
Best = dict[int, tuple[Subset, FloatArray, float]]
"""``number of leaks -> (subset, sizes [kg/s], residual [-])`` of the best fit."""


@dataclass(frozen=True)
class Explanation:
    """An alternative set of one or two leaks that explains the data about as well.

    Attributes
    ----------
    locations : tuple of Location
        Leak locations of the explanation.
    mass_flows : tuple of float
        Their fitted flows [kg/s].
    rss : float
        Weighted residual sum of squares of the explanation [-].
    """

    locations: tuple[Location, ...]
    mass_flows: tuple[float, ...]
    rss: float


@dataclass(frozen=True)
class Group:
    """The ambiguity group of one chosen leak.

    Attributes
    ----------
    members : tuple of int
        Location indices, most likely first.
    sizes : tuple of float
        The size each member would need to explain the data [kg/s].
    weight : float
        Share of the Akaike-type weight of all alternatives held by the group [-].
    """

    members: tuple[int, ...]
    sizes: tuple[float, ...]
    weight: float


def _better(best: Best, dof: int, k: int, than: int, gain: float) -> bool:
    """``k`` leaks explain the run better than ``than`` by the penalty and the gain."""
    rss_prev = best[than][2]
    rss_k = best[k][2]
    s2 = max(1.0, rss_k / max(dof - k, 1))
    penalty = 2.0 * np.log(max(dof, 2)) * s2 * (k - than)
    return bool(rss_prev - rss_k > penalty and rss_k < (1.0 - gain) * rss_prev)


def choose_leak_count(
    best: Best,
    dof: int,
    max_leaks: int,
    min_relative_gain: float,
    first_leak_gain: float = 1.0,
    added_gain: float | None = None,
    added_after: int = 0,
) -> int:
    """Number of leaks: more only when the residual drops by the penalty and the gain.

    Against the model chosen so far (at first: no leak), a model with ``k`` leaks is
    taken when its residual is lower by more than ``2 ln(dof) s^2`` per added leak (an
    information criterion with the residual scale ``s^2 = max(1, rss / (dof - k))``
    of the larger model) *and* by at least ``min_relative_gain`` of the chosen one. For
    one and two leaks every ``k`` is tried, so two leaks that only together explain
    the data (their effects interact, or one alone leaves most of the other's misfit)
    are not missed because no single leak did. From three leaks on the choice is a
    forward selection: ``k`` leaks are taken only over the chosen ``k - 1``, and the
    first ``k`` not taken ends it (the sets of three and more are themselves grown
    from the chosen ones, :mod:`pneufdd.diagnosis.localisation.subsets`).

    When that chooses no leak, one leak is still taken if it passes the information
    criterion and lowers the residual by ``first_leak_gain`` (1: no such fallback,
    the residual cannot fall below zero): on a run the detector has flagged, "no
    leak" is already rejected, and the location that explains the deviation best is
    worth reporting with the low confidence its small share of the deviation gives it.

    With ``added_gain``, a model of more than ``added_after`` leaks must lower the
    residual by that fraction instead (the check by simulation asks more of a leak
    the signatures did not ask for).

    Examples
    --------
    >>> best = {0: ((), np.zeros(0), 500.0), 1: ((0,), np.ones(1), 60.0),
    ...         2: ((0, 1), np.ones(2), 57.0)}
    >>> choose_leak_count(best, 50, 2, 0.1)
    1
    >>> choose_leak_count({0: ((), np.zeros(0), 500.0), 1: ((0,), np.ones(1), 490.0),
    ...                    2: ((0, 1), np.ones(2), 60.0)}, 50, 2, 0.1)
    2
    >>> weak = {0: ((), np.zeros(0), 500.0), 1: ((0,), np.ones(1), 420.0)}
    >>> choose_leak_count(weak, 50, 1, 0.25), choose_leak_count(weak, 50, 1, 0.25, 0.0)
    (0, 1)

    Three leaks over two, then a fourth that explains too little:

    >>> more = {**best, 1: ((0,), np.ones(1), 300.0), 2: ((0, 1), np.ones(2), 200.0),
    ...         3: ((0, 1, 2), np.ones(3), 40.0), 4: ((0, 1, 2, 3), np.ones(4), 35.0)}
    >>> choose_leak_count(more, 50, 4, 0.25), choose_leak_count(more, 50, 2, 0.25)
    (3, 2)
    """

    def gain(k: int) -> float:
        return min_relative_gain if added_gain is None or k <= added_after else added_gain

    chosen = 0
    for k in range(1, max_leaks + 1):
        if k >= 3 and (chosen != k - 1 or k not in best):
            break
        if k in best and _better(best, dof, k, chosen, gain(k)):
            chosen = k
        elif k >= 3:
            break
    if chosen == 0 and 1 in best and max_leaks >= 1:
        chosen = int(_better(best, dof, 1, 0, first_leak_gain))
    return chosen


def next_leak_weight(rss: float, rss_next: float, chosen: int, dof: int) -> float:
    """Probability-like weight of "no further leak" against one leak more.

    The Akaike-type weight of the chosen model (residual ``rss``, ``chosen`` leaks)
    against the best with one leak more (``rss_next``; inf: none was fitted), both
    scored like :func:`choose_leak_count` scores them (residual plus
    ``2 ln(dof) s^2`` per leak, ``s^2`` of the larger model): 1 without such a
    model, 0.5 when the added leak lowers the residual by exactly the penalty.

    Examples
    --------
    >>> round(next_leak_weight(60.0, 57.0, 1, 50), 3), next_leak_weight(60.0, math.inf, 2, 50)
    (0.934, 1.0)
    >>> round(next_leak_weight(80.0, 60.0, 1, 50), 3)
    0.016
    """
    if not math.isfinite(rss_next):
        return 1.0
    s2 = max(1.0, rss_next / max(dof - chosen - 1, 1))
    margin = rss - rss_next - 2.0 * np.log(max(dof, 2)) * s2
    return float(1.0 / (1.0 + np.exp(min(margin / (2.0 * s2), 700.0))))


def more_leak_reasons(
    rss: float,
    rss_next: float,
    chosen: int,
    dof: int,
    limit: int,
    min_relative_gain: float,
    misfit_ratio: float = math.inf,
) -> tuple[str, ...]:
    """Why more leaks than the ``chosen`` may be present (empty: no sign of any).

    - the best explanation with one leak more (residual ``rss_next``; inf: none)
      lowers the chosen one's residual ``rss`` by more than the information
      criterion's penalty of :func:`choose_leak_count`, though not by the relative
      gain the choice needs; or by that gain too, as the check by simulation
      predicted it from its probes, yet it was not taken (sized, it explained less,
      or it is what the larger leaks' model error imitates); or the search stopped
      at its ``limit`` of leaks;
    - the chosen explanation leaves more than ``misfit_ratio`` per residual
      component: far more than noise and model error explain (leaks the search
      cannot separate, or another fault).

    Examples
    --------
    >>> more_leak_reasons(400.0, 330.0, 1, 50, 2, 0.25)  # doctest: +NORMALIZE_WHITESPACE
    ('a further leak would lower the residual by 17 %: more than the information
    criterion asks, less than the 25 % the model choice needs',)
    >>> more_leak_reasons(400.0, 390.0, 1, 50, 2, 0.25)
    ()
    >>> more_leak_reasons(400.0, 280.0, 2, 50, 5, 0.25)  # doctest: +NORMALIZE_WHITESPACE
    ('a further leak would lower the residual by 30 % as probed beside the leaks found, but
    was not taken: sized, it explained less, or the model error of the larger leaks imitates a
    leak of its size',)
    >>> more_leak_reasons(4000.0, math.inf, 1, 50, 2, 0.25, 20.0)
    ('the leaks found leave 80 times the residual that noise and model error explain',)
    """
    reasons = []
    if math.isfinite(rss_next) and rss > 0:
        s2 = max(1.0, rss_next / max(dof - chosen - 1, 1))
        drop = 1.0 - rss_next / rss
        if rss - rss_next > 2.0 * np.log(max(dof, 2)) * s2:
            if chosen >= limit:
                reasons.append(
                    f"the search stopped at its limit of {limit} leak(s); one more would "
                    f"lower the residual by {math.floor(100 * drop)} %"
                )
            elif drop < min_relative_gain:
                reasons.append(
                    f"a further leak would lower the residual by {math.floor(100 * drop)} %: more "
                    "than the information criterion asks, less than the "
                    f"{100 * min_relative_gain:.0f} % the model choice needs"
                )
            else:
                # predicted (probed beside the leaks found) but not taken: sized, it
                # explained less, or the larger leaks' model error imitates it
                reasons.append(
                    f"a further leak would lower the residual by {math.floor(100 * drop)} % as "
                    "probed beside the leaks found, but was not taken: sized, it explained "
                    "less, or the model error of the larger leaks imitates a leak of its size"
                )
    if rss > misfit_ratio * max(dof, 1):
        reasons.append(
            f"the leaks found leave {rss / max(dof, 1):.0f} times the residual that noise "
            "and model error explain"
        )
    return tuple(reasons)


def same_actuator_pair(locations: Sequence[Location], subset: Subset) -> bool:
    """True when ``subset`` is the extend and the retract line of one actuator."""
    if len(subset) != 2:
        return False
    a, b = (locations[i] for i in subset)
    return a.is_other_line(b)


def ambiguity_group(
    slot: int,
    subset: Subset,
    sizes: FloatArray,
    fits: Mapping[Subset, tuple[FloatArray, float]],
    n_locations: int,
    column: Callable[[int, float], FloatArray],
    s2: float,
    min_flow: float,
    group_ratio: float,
    relative_tolerance: float,
    collinear_cos: float,
    forced: tuple[int, float] | None = None,
    composite_rss: Sequence[float] = (),
) -> Group:
    """The locations that explain the data as well as the chosen leak in ``slot``.

    Every other location is put in the slot's place (the other chosen leak kept);
    those with a fit in ``fits`` compete. A competitor joins the group when its
    Akaike-type weight ``exp(-(RSS - RSS_min) / 2 s^2)`` is at least ``group_ratio``
    of the best, or its residual is at most ``1 + relative_tolerance`` times the best
    (when model error rather than noise dominates the residual, the weights are
    over-confident), or its whitened signature has cosine similarity at least
    ``collinear_cos`` with the chosen one (the sensors cannot tell them apart).

    Parameters
    ----------
    slot : int
        Position of the leak in ``subset``.
    subset : tuple of int
        Chosen locations.
    sizes : ndarray
        Their sizes [kg/s].
    fits : mapping
        Fits of subsets with one location swapped (missing ones do not compete).
    n_locations : int
        Number of candidate locations.
    column : callable
        ``column(location, size)``: whitened effect per unit size [-].
    s2 : float
        Residual scale [-].
    min_flow : float
        Competitors needing a smaller leak do not join [kg/s].
    group_ratio, relative_tolerance, collinear_cos : float
        The three joining rules above [-].
    forced : (int, float), optional
        A location that joins the group in any case, last, and the size it would
        need [kg/s] when ``fits`` has no fit with it (it then adds no weight): the
        supply for the smaller of two leaks on both lines of one actuator, which
        draw air like a supply leak (see :func:`both_lines_alternatives`).
    composite_rss : sequence of float
        Residuals of explanations that compete with this leak but are not one location
        (two line leaks standing for a supply leak): their weights count against the
        group's share, so the confidence says they fit too [-].

    Returns
    -------
    Group
    """
    loc = subset[slot]
    others = tuple(x for x in subset if x != loc)
    competitors: list[tuple[float, int, float]] = []
    for alt in range(n_locations):
        if alt in others:
            continue
        trial = tuple(sorted((*others, alt)))
        if trial not in fits:
            continue
        alt_sizes, alt_rss = fits[trial]
        competitors.append((alt_rss, alt, float(alt_sizes[trial.index(alt)])))
    rss_min = min(c[0] for c in competitors)
    weights = {alt: float(np.exp(-(r - rss_min) / (2.0 * s2))) for r, alt, _ in competitors}
    rss_of = {alt: r for r, alt, _ in competitors}
    size_of = {alt: size for _, alt, size in competitors}
    chosen_col = column(loc, float(sizes[slot]))
    members = []
    for alt, w in weights.items():
        if size_of[alt] < min_flow and alt != loc:
            continue
        alt_col = column(alt, size_of[alt])
        norm = float(np.linalg.norm(chosen_col) * np.linalg.norm(alt_col))
        cos = float(chosen_col @ alt_col) / norm if norm > 0 else 0.0
        close = rss_of[alt] <= (1.0 + relative_tolerance) * rss_min
        if alt == loc or w >= group_ratio * max(weights.values()) or close or cos >= collinear_cos:
            members.append(alt)
    members.sort(key=lambda a: -weights[a])
    if forced is not None:
        extra, fallback = forced
        if extra not in members:
            members.append(extra)
        if extra not in size_of:
            size_of[extra], weights[extra] = fallback, 0.0
    # a composite may fit better than every single location: cap the exponent
    composite = sum(float(np.exp(min((rss_min - r) / (2.0 * s2), 700.0))) for r in composite_rss)
    total = sum(weights.values()) + composite
    share = sum(weights[a] for a in members) / total if total > 0 else 0.0
    return Group(tuple(members), tuple(size_of[a] for a in members), share)


def alternative_explanations(
    fits: Mapping[Subset, tuple[FloatArray, float]],
    locations: Sequence[Location],
    subset: Subset,
    rss: float,
    min_flow: float,
    relative_tolerance: float,
    max_alternatives: int,
) -> list[Explanation]:
    """Sets of one or two locations disjoint from ``subset`` that fit about as well.

    Those whose sizes are all at least ``min_flow`` and whose residual is at most
    ``1 + relative_tolerance`` times ``rss``, best first, at most ``max_alternatives``.
    """
    if not subset:
        return []
    disjoint = sorted(
        (fit[1], sub, fit[0])
        for sub, fit in fits.items()
        if not set(sub) & set(subset)
        and np.all(fit[0] >= min_flow)
        and fit[1] <= (1.0 + relative_tolerance) * rss
    )[:max_alternatives]
    return [
        Explanation(
            tuple(locations[i] for i in sub), tuple(float(x) for x in flows), float(fit_rss)
        )
        for fit_rss, sub, flows in disjoint
    ]


def both_lines_alternatives(
    locations: Sequence[Location],
    subset: Subset,
    sizes: FloatArray,
    model: WhitenedEffects,
    chosen_rss: float,
    min_flow: float,
    max_ratio: float,
    max_count: int,
) -> tuple[Explanation, ...]:
    """A supply leak re-explained as leaks on both lines of one actuator, best first.

    Leaks on the extend and the retract line of one actuator draw air in every step,
    like a supply leak; with supply sensors (and without line sensors on that
    actuator) the two explanations are physically near-indistinguishable, and their
    simultaneous effect is far from the additive model, so residuals cannot separate
    them, nor one actuator's pair from another's. When the chosen model holds a supply
    leak, each actuator whose two lines fit (additive residual, the same model for
    every actuator) gives an explanation in which that pair replaces it, the best
    ``max_count`` of them in order of residual; the chosen model's other leaks are
    kept (a kept leak on one of those lines adds to its flow). An actuator whose fit
    needs a size at the size cap cannot produce the supply leak's effect and is not
    offered, nor one whose additive residual exceeds ``max_ratio`` times the chosen
    model's ``chosen_rss`` (only the residual of the two line leaks is compared, not
    the kept leaks).

    Why more than one: on festo-dsd plants with only the supply sensors, leaks on both
    lines of HMPL_HZ (199 SLPM each) fitted as a 99 SLPM supply leak; the additive
    residuals of the nine actuators' pairs lay within a factor 1.5 of each other, and
    the best was HMPL_VS's, so one alternative named the wrong actuator
    (``docs/localisation.md``, "Alternative explanations").
    """
    if SUPPLY not in locations or max_count < 1:
        return ()
    supply = locations.index(SUPPLY)
    if supply not in subset:
        return ()
    keep = [i for i in subset if i != supply]
    candidates: list[tuple[float, int, int, FloatArray]] = []
    for a, loc in enumerate(locations):
        if loc.side != "A" or loc.other_line() not in locations:
            continue
        b = locations.index(loc.other_line())
        flows, rss = model.fit((a, b))
        at_cap = np.any(flows >= (1.0 - 1e-9) * model.size_cap[[a, b]])
        if np.all(flows >= min_flow) and not at_cap and rss <= max_ratio * chosen_rss:
            candidates.append((float(rss), a, b, flows))
    candidates.sort(key=lambda c: c[0])
    explanations = []
    for rss, a, b, pair_flows in candidates[:max_count]:
        fitted = {a: float(pair_flows[0]), b: float(pair_flows[1])}
        for i in keep:
            fitted[i] = fitted.get(i, 0.0) + float(sizes[subset.index(i)])
        explanations.append(
            Explanation(tuple(locations[i] for i in fitted), tuple(fitted.values()), rss)
        )
    return tuple(explanations)
