"""Explanations of many leaks: a beam search over sets of locations (issue 38).

The fits of one and two leaks are exhaustive and exact
(:class:`~pneufdd.diagnosis.effects.piecewise.WhitenedEffects`); beyond two, the
number of sets explodes (festo-dsd: 969 sets of three of its 19 locations, 11,628 of
four, 27,132 of six). A run with ``k + 1`` leaks is explained by adding one leak to a
good explanation of ``k``: from the ``beam`` best sets of ``k`` leaks, every other
location is tried as the added leak (its exact best size against what the set
leaves, all locations in one pass: :meth:`WhitenedEffects.additions`), the
``expand`` best additions of each are refit with every size free and the pairwise
interaction (:meth:`WhitenedEffects.fit_set`), and the ``beam`` best sets of
``k + 1`` go on. After each level the best set is improved by swaps: each leak in
turn is replaced by the location that best explains what the others leave (a wrong
early choice, a supply leak standing for two line leaks, is undone when the later
leaks make it worse than the pair it stood for). The search stops at the first
level whose best set the model choice does not take
(:func:`~pneufdd.diagnosis.localisation.model_choice.choose_leak_count`): that
level is kept, it says how much a further leak would explain.

Cost per level: ``beam`` residual evaluations, ``beam`` additions passes (two matrix
products of the whitened pieces each) and ``beam x expand`` set fits, plus the swaps;
linear in the number of leaks, not combinatorial.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects
from pneufdd.diagnosis.localisation.model_choice import Best, Fits, Subset

__all__ = ["SetSearch"]

PairTerm = Callable[[int, int], FloatArray | None]
"""Whitened interaction of two locations per unit of both sizes, or None [1/(kg/s)^2]."""


class SetSearch:
    """Fits of sets of leaks of any size against one run (one weighting).

    Parameters
    ----------
    model : WhitenedEffects
        The run's whitened effects.
    pair_term : callable, optional
        Whitened interaction of two locations (:meth:`LeakEffectModel.pair_coupling`
        through the run's weighting); None: additive.
    min_flow : float
        Smallest leak a reported set may hold [kg/s].
    beam, expand : int
        Sets kept per level, additions refit per set [-].
    """

    def __init__(
        self,
        model: WhitenedEffects,
        pair_term: PairTerm | None,
        min_flow: float,
        beam: int = 3,
        expand: int = 3,
    ) -> None:
        self.model = model
        self.pair_term = pair_term
        self.min_flow = min_flow
        self.beam = beam
        self.expand = expand
        self._terms: dict[tuple[int, int], FloatArray] = {}

    def coupling(self, subset: Subset) -> FloatArray | None:
        """The pairwise interaction of ``subset``, shape ``(k, k, n)``; None if additive."""
        if self.pair_term is None or len(subset) < 2:
            return None
        k, n = len(subset), self.model.target.size
        out = np.zeros((k, k, n))
        for i in range(k):
            for j in range(i + 1, k):
                key = (subset[i], subset[j])
                if key not in self._terms:
                    term = self.pair_term(*key)
                    self._terms[key] = np.zeros(n) if term is None else term
                out[i, j] = out[j, i] = self._terms[key]
        return out

    def residual(self, subset: Subset, sizes: FloatArray) -> FloatArray:
        """What the set leaves of the run's whitened change [-]."""
        return self.model.target - self.model.set_effect(subset, sizes, self.coupling(subset))

    def fit(self, subset: Subset, start: FloatArray) -> tuple[FloatArray, float]:
        """Sizes [kg/s] and whitened residual [-] of ``subset`` from ``start``."""
        return self.model.fit_set(subset, start, self.coupling(subset))

    def _valid(self, sizes: FloatArray) -> bool:
        return bool(np.all(sizes >= self.min_flow))

    def _add(
        self, subset: Subset, sizes: FloatArray, count: int
    ) -> list[tuple[Subset, FloatArray]]:
        """The ``count`` best one-leak additions to a set: (new set, starting sizes)."""
        add_sizes, add_rss = self.model.additions(self.residual(subset, sizes))
        order = [int(m) for m in np.argsort(add_rss) if int(m) not in subset][:count]
        out = []
        for m in order:
            new = tuple(sorted((*subset, m)))
            start = np.array(
                [add_sizes[m] if i == m else sizes[subset.index(i)] for i in new], dtype=np.float64
            )
            out.append((new, start))
        return out

    def swaps(
        self, subset: Subset, sizes: FloatArray, fits: Fits, refit_below: float = np.inf
    ) -> None:
        """Fits of ``subset`` with each leak replaced by each other location (in place).

        For each leak, the others keep their sizes and every other location is fitted
        in its place alone (one pass of :meth:`WhitenedEffects.additions`); the sets
        whose residual then is below ``refit_below`` are refit with every size free,
        the others keep that residual (an upper bound of their best). Sets already in
        ``fits`` are left.
        """
        for slot, loc in enumerate(subset):
            others = tuple(x for x in subset if x != loc)
            kept = np.delete(sizes, slot)
            residual = self.residual(others, kept) if others else self.model.target
            add_sizes, add_rss = self.model.additions(residual)
            for alt in range(add_sizes.size):
                if alt in others:
                    continue
                trial = tuple(sorted((*others, alt)))
                if trial in fits:
                    continue
                start = np.array(
                    [add_sizes[alt] if i == alt else kept[others.index(i)] for i in trial]
                )
                if add_rss[alt] < refit_below:
                    fits[trial] = self.fit(trial, start)
                else:
                    fits[trial] = (start, float(add_rss[alt]))

    def _improve(self, subset: Subset, fits: Fits) -> tuple[Subset, FloatArray, float]:
        """``subset`` improved by swaps until no swap lowers its residual."""
        sizes, rss = fits[subset]
        for _ in range(len(subset) + 1):
            self.swaps(subset, sizes, fits, refit_below=rss)
            better = [
                (fit[1], sub)
                for sub, fit in fits.items()
                if len(sub) == len(subset)
                and len(set(sub) & set(subset)) == len(subset) - 1
                and fit[1] < rss
                and self._valid(fit[0])
            ]
            if not better:
                break
            rss, subset = min(better)
            sizes = fits[subset][0]
        return subset, sizes, rss

    def grow(
        self,
        fits: Fits,
        best: Best,
        largest: int,
        accept: Callable[[int], bool],
    ) -> None:
        """Sets of three to ``largest`` leaks, level by level (``fits``, ``best`` in place).

        ``fits`` holds the exact fits of one and two leaks; ``accept(k)`` says whether
        the model choice would take the best set of ``k`` leaks over that of
        ``k - 1``: the first level it does not take is the last searched.
        """
        k = 2
        level = self._level(fits, k)
        while level and k < largest:
            k += 1
            found: Fits = {}
            for subset, sizes in level:
                for new, start in self._add(subset, sizes, self.expand):
                    if new not in fits and new not in found:
                        found[new] = self.fit(new, start)
            fits.update(found)
            if not any(self._valid(fit[0]) for fit in found.values()):
                return
            top = min((fit[1], sub) for sub, fit in found.items() if self._valid(fit[0]))[1]
            subset, sizes, rss = self._improve(top, fits)
            best[k] = (subset, sizes, rss)
            if not accept(k):
                return
            level = self._level(fits, k)

    def _level(self, fits: Fits, k: int) -> list[tuple[Subset, FloatArray]]:
        """The ``beam`` best valid sets of ``k`` leaks in ``fits``."""
        ranked = sorted(
            (fit[1], sub) for sub, fit in fits.items() if len(sub) == k and self._valid(fit[0])
        )
        return [(sub, fits[sub][0]) for _, sub in ranked[: self.beam]]
