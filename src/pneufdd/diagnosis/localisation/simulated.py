"""The check by simulation inside :func:`~pneufdd.diagnosis.localisation.search.locate`.

When the signature fit leaves a residual well above noise, the best explanations are
sized with the digital twin (:mod:`.check`: single leaks, partners probed beside the
best one, the signature model's best pairs); beyond two leaks one more leak at a time
is probed beside the chosen simulated explanation (:mod:`.forward`); a supply leak
among the chosen ones is tried as the lines it may stand for (:func:`supply_swaps`);
then the choice of how many leaks is made again on the simulated residuals, and the
alternatives of each chosen leak are simulated for its ambiguity group.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects
from pneufdd.diagnosis.localisation.check import (
    SimulatedEffect,
    SimulatedFit,
    SimulationCheckSettings,
    refine_all,
    verify_explanations,
)
from pneufdd.diagnosis.localisation.forward import extend_by_simulation
from pneufdd.diagnosis.localisation.model_choice import Best, Fits, Subset, choose_leak_count
from pneufdd.diagnosis.localisation.settings import LocalisationSettings
from pneufdd.diagnosis.localisation.subsets import SetSearch
from pneufdd.location import SUPPLY, Location
from pneufdd.parallel import thread_map

__all__ = ["Imitation", "check_by_simulation", "simulate_group_competitors", "supply_swaps"]

Imitation = Callable[[Sequence[tuple[int, float]], tuple[int, float]], float | None]
"""Size [kg/s] of leak ``smaller`` the model error of leaks ``larger`` imitates, or None."""


def check_by_simulation(
    target: FloatArray,
    model: WhitenedEffects,
    fits: Fits,
    best: Best,
    chosen: int,
    simulate: SimulatedEffect,
    n_loc: int,
    dof: int,
    limit: int,
    settings: LocalisationSettings,
    threads: int = 1,
    locations: tuple[Location, ...] | None = None,
    imitation: Imitation | None = None,
) -> tuple[Fits, Best, int, dict[Subset, SimulatedFit], float] | None:
    """Simulated explanations and the choice among them, or None if none ran.

    Beyond two leaks, one more leak at a time is probed beside the chosen simulated
    explanation (:func:`~pneufdd.diagnosis.localisation.forward.extend_by_simulation`);
    the probes of the level not taken say how far one leak more would lower the
    residual (the last value returned, inf when none was probed). A set of three or
    more leaks counts only when its smallest leak is more than ``imitation_z`` times
    what the others' model error imitates (``imitation``), as the engine asks of a
    second leak the signatures chose.
    """
    pairs_too = limit > 1
    if pairs_too:
        for sub in itertools.combinations(range(n_loc), 2):
            fits.setdefault(sub, model.fit(sub))
    check = SimulationCheckSettings(
        partners=3 if pairs_too else 0,
        probed_locations=settings.probes,
        top_pairs=3 if pairs_too else 0,
        min_pair_flow=settings.min_mass_flow,
        keep_within=settings.keep_within or math.inf,
    )
    checked = verify_explanations(
        target,
        fits,
        n_loc,
        simulate,
        model.size_cap,
        check,
        slopes=_slopes(model) if settings.keep_within else None,
        threads=threads,
    )
    if not checked:
        return None
    # a leak the signatures did not ask for must explain much more: the simulated
    # residual also holds the run's own random conditions, which a small extra leak
    # can partly absorb
    gain = settings.min_relative_gain
    added = max(gain, settings.added_leak_gain)

    imitated: dict[Subset, bool] = {}

    def real(sub: Subset, sizes: FloatArray) -> bool:
        """False when the smallest of three or more leaks is what the others imitate."""
        if len(sub) < 3 or imitation is None or settings.imitation_z <= 0:
            return True
        if sub not in imitated:
            small = int(np.argmin(sizes))
            pairs = enumerate(zip(sub, sizes, strict=True))
            others = [(loc, float(x)) for i, (loc, x) in pairs if i != small]
            size = imitation(others, (sub[small], float(sizes[small])))
            imitated[sub] = size is None or float(sizes[small]) > settings.imitation_z * size
        return imitated[sub]

    def choice() -> tuple[Fits, Best, int]:
        sim_fits: Fits = {sub: (fit.sizes, fit.rss) for sub, fit in checked.items()}
        sim_best = _best_of(
            {sub: fit for sub, fit in sim_fits.items() if real(sub, fit[0])},
            limit,
            settings.min_mass_flow,
            best[0],
        )
        # the stricter gain holds for one and two leaks when the signatures chose one
        # (today's rule); from three leaks on, found beside the chosen ones by probing,
        # the usual gain
        first_two = added if chosen <= 1 else gain
        count = choose_leak_count(
            sim_best, dof, limit, first_two, settings.first_leak_gain, gain, 2
        )
        return sim_fits, sim_best, count

    sim_fits, sim_best, count = choice()
    # more leaks one at a time, each probed beside the chosen ones (.forward); one
    # level beyond the choice is probed: what a further leak would explain. A supply
    # leak among the chosen is tried as the lines it may stand for, once per set.
    following = math.inf
    swapped: set[Subset] = set()
    while 2 <= count < n_loc and sim_best[count][0] in checked:
        base = sim_best[count][0]
        if base not in swapped and locations is not None and SUPPLY in locations:
            swapped.add(base)
            if supply_swaps(target, checked, base, locations, model, simulate, check, threads):
                sim_fits, sim_best, swapped_count = choice()
                if sim_best[count][0] != base or swapped_count != count:
                    count = max(swapped_count, 2)
                    continue
        sized, following = extend_by_simulation(
            target,
            checked,
            base,
            _ranked_additions(model, checked[base].residual, base)[: settings.probes or n_loc],
            simulate,
            model.size_cap,
            check.probe_size,
            partners=2,
            max_iterations=check.max_iterations,
            keep_within=check.keep_within,
            threads=threads,
            size_below=(1.0 - 0.5 * gain) * sim_best[count][2] if count < limit else 0.0,
        )
        sim_fits, sim_best, grown = choice()
        if sized:  # what one leak more explains, when it is a leak (not imitated)
            following = sim_best[count + 1][2] if count + 1 in sim_best else math.inf
        if grown <= count:
            break
        count = grown
        following = math.inf
    return sim_fits, sim_best, count, checked, following


def supply_swaps(
    target: FloatArray,
    checked: dict[Subset, SimulatedFit],
    base: Subset,
    locations: tuple[Location, ...],
    model: WhitenedEffects,
    simulate: SimulatedEffect,
    check: SimulationCheckSettings,
    threads: int = 1,
    actuators: int = 3,
) -> list[Subset]:
    """Size by simulation the lines a chosen supply leak may stand for (``checked`` in place).

    Leaks on both lines of one actuator draw air in every step like a supply leak, and
    a small leak on one line next to a large one on the other reads as that large
    leak plus a supply leak. Of a chosen set holding a supply leak, the sets in which
    the supply leak is replaced by the other line of each of the two largest chosen
    line leaks (that line at the supply leak's size, the line leak larger by it), and
    by both lines of each of the ``actuators`` actuators whose two lines best make the
    supply leak's effect (the signature model, additive) are sized by simulation, judged
    first by their start (the chosen set's Jacobian for the kept leaks, the signature
    slopes for the new ones) and stopped early like every simulated explanation. Returns
    the sets sized.

    Three actuators, as the both-lines alternatives list three
    (:func:`~pneufdd.diagnosis.localisation.model_choice.both_lines_alternatives`): the
    additive signature fit often ranks another actuator's lines first (on development
    runs of press-fit-cell, seeds 9,630,001+, with one actuator a supply leak of 78
    SLPM stood for EJECT_A + EJECT_B, and one of 36 SLPM was reported beside the true
    four leaks; with three, both runs were explained by their true leaks).
    """
    supply = locations.index(SUPPLY)
    if supply not in base:
        return []
    fit = checked[base]
    kept = {loc: float(x) for loc, x in zip(base, fit.sizes, strict=True) if loc != supply}
    size = float(fit.sizes[base.index(supply)])
    trials: list[dict[int, float]] = []
    for loc in sorted(kept, key=lambda i: -kept[i])[:2]:
        other = locations[loc].other_line()
        if other in locations and locations.index(other) not in kept:
            # the supply leak stands for the small other line, the line leak for
            # less than it is: both start larger
            trials.append({**kept, loc: kept[loc] + size, locations.index(other): size})
    effect = model.secant(supply, size) * size
    ranked = []
    for a, line in enumerate(locations):
        if line.side != "A" or line.other_line() not in locations:
            continue
        b = locations.index(line.other_line())
        columns = np.column_stack([model.secant(a, size), model.secant(b, size)])
        step = lsq_linear(columns, effect, bounds=(0.0, np.inf))
        ranked.append((2.0 * float(step.cost), a, b, step.x))
    for _, a, b, flows in sorted(ranked, key=lambda r: r[0])[:actuators]:
        trial = dict(kept)
        trial[a] = trial.get(a, 0.0) + float(flows[0])
        trial[b] = trial.get(b, 0.0) + float(flows[1])
        trials.append(trial)
    starts: dict[Subset, FloatArray] = {}
    estimates: dict[Subset, FloatArray] = {}
    for trial in trials:
        sub = tuple(sorted(trial))
        if sub in checked or sub in starts or min(trial.values()) <= 0:
            continue
        starts[sub] = np.array([trial[i] for i in sub])
        estimates[sub] = np.column_stack(
            [
                fit.jacobian[:, base.index(i)] if i in base else model.derivative(i, trial[i])
                for i in sub
            ]
        )
    leader = min((f.rss for f in checked.values()), default=math.inf)
    checked.update(
        refine_all(
            starts,
            target,
            simulate,
            model.size_cap,
            check.max_iterations,
            threads,
            check.keep_within,
            leader,
            estimates,
        )
    )
    return list(starts)


def _ranked_additions(model: WhitenedEffects, residual: FloatArray, base: Subset) -> list[int]:
    """Locations not in ``base``, the best signature-model addition to ``residual`` first."""
    _, rss = model.additions(residual)
    return [int(i) for i in np.argsort(rss, kind="stable") if int(i) not in base]


def _best_of(
    fits: Fits, limit: int, min_flow: float, none: tuple[Subset, FloatArray, float]
) -> Best:
    """The best fit of each number of leaks up to ``limit`` with every size >= ``min_flow``."""
    best: Best = {0: none}
    for cand, (cand_sizes, cand_rss) in fits.items():
        k = len(cand)
        if (
            k <= limit
            and np.all(cand_sizes >= min_flow)
            and (k not in best or cand_rss < best[k][2])
        ):
            best[k] = (cand, cand_sizes, cand_rss)
    return best


def _slopes(model: WhitenedEffects) -> Callable[[Subset, FloatArray], FloatArray]:
    """The signature model's derivative of the whitened effect of a subset by size."""

    def slopes(subset: Subset, sizes: FloatArray) -> FloatArray:
        return np.column_stack(
            [model.derivative(loc, float(x)) for loc, x in zip(subset, sizes, strict=True)]
        )

    return slopes


def simulate_group_competitors(
    target: FloatArray,
    search: SetSearch,
    fits: Fits,
    subset: Subset,
    sizes: FloatArray,
    simulate: SimulatedEffect,
    n_loc: int,
    checks: int,
    threads: int = 1,
    chosen_fit: SimulatedFit | None = None,
) -> None:
    """Size by simulation the locations the signatures rank best in each slot (in place).

    Every competitor is sized to the end: it starts from the size of the leak it
    replaces, often far from its own: in development runs, one whose starting
    residual was 42 times the chosen pair's ended as good as it, so stopping such a
    competitor early would have lost it. Of three or more leaks the signatures rank
    a slot's alternatives with the other leaks at their simulated sizes
    (:meth:`SetSearch.swaps`, not refit), and each competitor costs one simulation
    (:func:`_estimated_competitors`, with the chosen explanation ``chosen_fit``).
    """
    model = search.model
    ranking: Fits = {}
    if len(subset) > 2:
        search.swaps(subset, sizes, ranking, refit_below=0.0)
    trials: dict[Subset, FloatArray] = {}
    for slot, loc in enumerate(subset):
        others = tuple(x for x in subset if x != loc)

        def rss_of(alt: int, others: Subset = others) -> float:
            trial = tuple(sorted((*others, alt)))
            return ranking[trial][1] if trial in ranking else model.fit(trial)[1]

        ranked = sorted((rss_of(alt), alt) for alt in range(n_loc) if alt not in subset)
        for _, alt in ranked[:checks]:
            trial = tuple(sorted((*others, alt)))
            if trial in fits or trial in trials:
                continue
            trials[trial] = np.array(
                [sizes[subset.index(i)] if i in others else sizes[slot] for i in trial]
            )
    if len(subset) > 2 and chosen_fit is not None:
        fits.update(_estimated_competitors(trials, subset, chosen_fit, model, simulate, threads))
        return
    for trial, fit in refine_all(trials, target, simulate, model.size_cap, threads=threads).items():
        fits[trial] = (fit.sizes, fit.rss)


def _estimated_competitors(
    trials: Mapping[Subset, FloatArray],
    subset: Subset,
    chosen: SimulatedFit,
    model: WhitenedEffects,
    simulate: SimulatedEffect,
    threads: int,
) -> Fits:
    """Competitors in the slots of three or more leaks, each from one simulation.

    Each competitor is simulated at its start (the replaced leak's size in its place)
    and moved by one bounded linear step: the chosen explanation's Jacobian for the
    kept leaks, the signature model's slope for the one swapped in. Its residual is
    the smaller of the simulated start's and the step's prediction: sizing every slot's
    competitor to the end would cost ``k (k + 4)`` simulations, and a predicted
    residual that errs low only widens a group.
    """
    starts = list(trials.items())
    effects = thread_map(
        lambda item: simulate(dict(zip(item[0], (float(x) for x in item[1]), strict=True))),
        starts,
        threads,
    )
    out: Fits = {}
    for (trial, start), effect in zip(starts, effects, strict=True):
        if effect is None:
            continue
        residual = model.target - effect
        columns = np.column_stack(
            [
                chosen.jacobian[:, subset.index(i)] if i in subset else model.derivative(i, x)
                for i, x in zip(trial, start, strict=True)
            ]
        )
        upper = model.size_cap[list(trial)]
        step = lsq_linear(
            columns, residual, bounds=(-start, np.maximum(upper - start, -start + 1e-300))
        )
        predicted = 2.0 * float(step.cost)
        rss = float(residual @ residual)
        out[trial] = (start + step.x, predicted) if predicted < rss else (start, rss)
    return out
