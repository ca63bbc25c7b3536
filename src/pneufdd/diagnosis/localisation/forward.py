"""One more leak beside a simulated explanation: forward selection by simulation (issue 38).

When the signatures misread a run (large leaks that interact), the check by
simulation (:mod:`pneufdd.diagnosis.localisation.check`) sizes single leaks and
pairs with the digital twin; the signature model's sets of three and more leaks are
then as unreliable as its pairs were. A further leak is therefore found the way the
check finds a second one beside the best single leak, one level at a time: beside
the chosen simulated explanation of ``k`` leaks, the ``probes`` locations the
signature model ranks best for what that explanation leaves
(:meth:`~pneufdd.diagnosis.effects.piecewise.WhitenedEffects.additions` of its
simulated residual) are each *probed*: simulated at the probe size beside the ``k``
leaks, which gives the added leak's effect in their presence, interaction included.
A bounded linear fit of all ``k + 1`` sizes (the explanation's Jacobian and the
probe's column) to the data ranks them, and the ``partners`` best sets of ``k + 1``
are sized by simulation (:func:`~pneufdd.diagnosis.localisation.check.refine_all`,
judged before their difference steps by the Jacobian the probe measured).

Cost per level: ``probes`` simulations in one batch, then the sizing of ``partners``
sets of ``k + 1`` leaks (``k + 2`` simulations for the start and the difference
steps, one per Gauss-Newton step, fewer when an explanation stops early).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.localisation.check import (
    SimulatedEffect,
    SimulatedFit,
    refine_all,
)
from pneufdd.diagnosis.localisation.model_choice import Subset
from pneufdd.parallel import thread_map

__all__ = ["extend_by_simulation"]


def _probe(
    target: FloatArray,
    base: Subset,
    fit: SimulatedFit,
    others: Sequence[int],
    simulate: SimulatedEffect,
    upper: FloatArray,
    probe_size: float,
    threads: int,
) -> list[tuple[float, int, FloatArray, FloatArray]]:
    """Added leaks ranked by how well they explain what ``base`` leaves.

    Returns ``(rss [-], location, size changes [kg/s], Jacobian [1/(kg/s)])`` of each
    probed location, best first; the size changes and the Jacobian's columns are
    those of ``base`` then the added leak.
    """
    sizes = {loc: float(x) for loc, x in zip(base, fit.sizes, strict=True)}
    effect = target - fit.residual
    probed = thread_map(lambda other: simulate({**sizes, other: probe_size}), others, threads)
    lower = np.append(-fit.sizes, 0.0)
    ranked = []
    for other, change in zip(others, probed, strict=True):
        if change is None:
            continue
        columns = np.column_stack([fit.jacobian, (change - effect) / probe_size])
        higher = np.append(upper[list(base)] - fit.sizes, upper[other])
        step = lsq_linear(columns, fit.residual, bounds=(lower, np.maximum(higher, lower))).x
        residual = fit.residual - columns @ step
        ranked.append((float(residual @ residual), other, step, columns))
    return sorted(ranked, key=lambda r: r[0])


def extend_by_simulation(
    target: FloatArray,
    checked: dict[Subset, SimulatedFit],
    base: Subset,
    others: Sequence[int],
    simulate: SimulatedEffect,
    upper: FloatArray,
    probe_size: float,
    partners: int = 2,
    max_iterations: int = 3,
    keep_within: float = math.inf,
    threads: int = 1,
    size_below: float = math.inf,
) -> tuple[list[Subset], float]:
    """Size by simulation the best sets of one leak more than ``base`` (``checked`` in place).

    Parameters
    ----------
    target : ndarray
        Whitened observed change [-].
    checked : dict
        ``subset -> SimulatedFit`` of the explanations sized so far; holds ``base``.
    base : tuple of int
        The chosen simulated explanation.
    others : sequence of int
        Locations to probe beside it, best first.
    simulate : callable
        Whitened simulated effect of ``{location: size}`` (None: the machine cannot
        run).
    upper : ndarray, shape (n_locations,)
        Largest size of every location [kg/s].
    probe_size : float
        Size at which the added leaks are probed [kg/s].
    partners : int
        Best probed sets sized by simulation [-].
    max_iterations, keep_within, threads
        As for :func:`~pneufdd.diagnosis.localisation.check.refine_all`.
    size_below : float
        Only sets whose probe predicts a residual below this are sized: a further
        leak that cannot explain enough to be chosen costs its probes alone [-].

    Returns
    -------
    list of tuple of int
        The sets of one leak more that were sized, best probe first.
    float
        The residual the best probe predicts for one leak more (inf: none probed) [-].

    Examples
    --------
    Three "locations" whose simulated effects interact; beside the sized pair (0, 1)
    the probe finds the third and sizes it:

    >>> S = np.array([[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.5]])
    >>> def sim(leaks):
    ...     x = np.array([leaks.get(i, 0.0) for i in range(3)])
    ...     return x @ S + np.array([0.0, 0.0, 0.0, 0.2 * x[0] * x[2]])
    >>> y = sim({0: 2.0, 1: 1.0, 2: 1.5})
    >>> pair = refine_all({(0, 1): np.array([2.0, 1.0])}, y, sim, np.full(3, 9.0))
    >>> added = extend_by_simulation(y, pair, (0, 1), [2], sim, np.full(3, 9.0), 0.5,
    ...                              max_iterations=10)
    >>> added[0], [round(float(v), 3) for v in pair[(0, 1, 2)].sizes]
    ([(0, 1, 2)], [2.0, 1.0, 1.5])
    """
    fit = checked[base]
    ranked = _probe(target, base, fit, others, simulate, upper, probe_size, threads)
    predicted = ranked[0][0] if ranked else math.inf
    starts: dict[Subset, FloatArray] = {}
    estimates: dict[Subset, FloatArray] = {}
    for rss, other, step, columns in ranked[:partners]:
        if rss >= size_below:
            continue
        sizes = {loc: float(x) for loc, x in zip(base, fit.sizes + step[:-1], strict=True)}
        sizes[other] = float(step[-1])
        grown = tuple(sorted(sizes))
        if grown in checked:
            continue
        order = [list(base).index(i) if i in base else len(base) for i in grown]
        starts[grown] = np.array([sizes[i] for i in grown])
        estimates[grown] = columns[:, order]
    leader = min((f.rss for f in checked.values()), default=math.inf)
    checked.update(
        refine_all(
            starts,
            target,
            simulate,
            upper,
            max_iterations,
            threads,
            keep_within,
            leader,
            estimates,
        )
    )
    return list(starts), predicted
