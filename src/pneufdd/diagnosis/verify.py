"""Check the best leak explanations by simulating them (analysis by synthesis).

The signature model of :mod:`pneufdd.diagnosis.localisation` interpolates single-leak
effects and adds a bilinear interaction measured at one pair of sizes. Two large
leaks together break it: a supply drawn down by one leak changes how every other
line fills, exhausts and times out, so the effects are far from additive (on
festo-dsd, with 150-200 SLPM leaks, the weighted residual of the true pair under the
signature model was 2-25 times that of a wrong pair). When the best signature fit
leaves a residual well above the noise (``rss > misfit_ratio * dof``), the best
explanations are simulated as they stand, with the digital twin:

1. **Candidates**: the best single leaks and pairs of the signature model, and, next
   to the best single leak once it is sized by simulation, the locations that best
   explain what it leaves unexplained (a greedy second leak, section 5.3.1.5's
   "remove the supply leak's effect, then read the line leak").
2. **Sizes** by Gauss-Newton on the simulator (:func:`refine_by_simulation`): a
   finite-difference Jacobian of simulations, then Broyden updates, bounded steps.
   The signature model only supplies the starting sizes; the residual that ranks the
   explanations is always the simulated one.

The result maps each checked explanation to its sizes and simulated residual; the
caller chooses among them with the same rules as for the signature fits.
"""

from __future__ import annotations

import heapq
import itertools
import math
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.optimize import lsq_linear

from pneufdd.parallel import thread_map

__all__ = ["SimulatedFit", "refine_all", "refine_by_simulation", "verify_explanations"]

FloatArray = npt.NDArray[np.float64]
Subset = tuple[int, ...]
SimulatedEffect = Callable[[Mapping[int, float]], FloatArray | None]
"""Whitened effect of leaks ``{location index: size [kg/s]}`` by simulation, or None."""
SimulateMany = Callable[[Sequence[Mapping[int, float]]], list[FloatArray | None]]
"""A :data:`SimulatedEffect` of several sets of leaks, results in their order."""


class SimulatedFit(NamedTuple):
    """An explanation sized against the simulator.

    Attributes
    ----------
    sizes : ndarray
        Leak size of each location [kg/s].
    rss : float
        Whitened residual sum of squares of the simulated effect [-].
    jacobian : ndarray, shape (n_components, n_leaks)
        Last estimate of the whitened effect's derivative by size [1/(kg/s)].
    """

    sizes: FloatArray
    rss: float
    jacobian: FloatArray


def refine_by_simulation(
    subset: Subset,
    start: FloatArray,
    target: FloatArray,
    simulate: SimulatedEffect,
    upper: FloatArray,
    max_iterations: int = 4,
    tolerance: float = 0.02,
    min_step: float = 1e-4,
    simulate_many: SimulateMany | None = None,
) -> SimulatedFit | None:
    """Size an explanation against the simulator (Gauss-Newton, Broyden updates).

    The first Jacobian is a forward difference of simulations (one per leak, steps of
    15 % of the size but at least ``min_step``: the step durations are quantised by
    the PLC's 100 Hz signals, so smaller steps see noise); later ones are Broyden
    rank-one updates from the steps taken, so an iteration costs one simulation.
    Each step is the bounded linear least-squares step
    (:func:`scipy.optimize.lsq_linear`) within ``0 <= size <= upper``. With
    ``simulate_many`` the starting point and the difference steps, which do not
    depend on each other, are simulated in one call (at once on several threads);
    the result is the same.

    Parameters
    ----------
    subset : tuple of int
        Location indices of the explanation.
    start : ndarray
        Starting sizes, one per location [kg/s].
    target : ndarray
        Whitened observed change [-].
    simulate : callable
        Whitened simulated effect of ``{location: size}``; None when the machine
        cannot run with it.
    upper : ndarray
        Largest size of each location [kg/s].
    max_iterations : int
        Gauss-Newton steps at most [-].
    tolerance : float
        Stop when no size moves by more than this fraction [-].
    min_step : float
        Smallest finite-difference step [kg/s].
    simulate_many : callable, optional
        ``simulate`` of a list of leak sets, results in the same order.

    Returns
    -------
    SimulatedFit or None
        The simulated explanation with the smallest residual met on the way; None
        when the machine could not run with it.

    Examples
    --------
    A smooth nonlinear "simulator" of two leaks is fitted from a poor start:

    >>> S = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    >>> sim = lambda x: (x[0] * S[0] + x[1] * S[1] + np.array([0, 0, 0.3 * x[0] * x[1]]))
    >>> y = sim({0: 2.0, 1: 1.0})
    >>> sizes, rss, _ = refine_by_simulation((0, 1), np.array([1.0, 3.0]), y, sim,
    ...                                      np.array([10.0, 10.0]), max_iterations=20,
    ...                                      tolerance=1e-6)
    >>> [round(float(v), 4) for v in sizes], rss < 1e-12
    ([2.0, 1.0], True)
    """
    upper = np.asarray(upper, dtype=np.float64)
    sizes = np.clip(np.asarray(start, dtype=np.float64), 0.0, upper)

    def leaks(x: FloatArray) -> dict[int, float]:
        return dict(zip(subset, (float(v) for v in x), strict=True))

    def run(x: FloatArray) -> FloatArray | None:
        return simulate(leaks(x))

    def difference_steps(x: FloatArray) -> list[tuple[float, FloatArray]]:
        out = []
        for i in range(x.size):
            step = max(0.15 * x[i], min_step)
            if x[i] + step > upper[i]:
                step = -step
            trial = x.copy()
            trial[i] += step
            out.append((step, trial))
        return out

    for attempt in range(3):
        if attempt > 0:
            sizes = 0.7 * sizes  # the machine stalls: the explanation is too large
        steps = difference_steps(sizes)
        moved_all: list[FloatArray | None] | None = None
        if simulate_many is None:
            effect = run(sizes)
        else:
            effect, *moved_all = simulate_many([leaks(sizes), *(leaks(t) for _, t in steps)])
        if effect is not None:
            break
    if effect is None:
        return None
    residual = target - effect
    jacobian = np.zeros((target.size, sizes.size))
    best = SimulatedFit(sizes.copy(), float(residual @ residual), jacobian)
    for i, (step, trial) in enumerate(steps):
        moved = run(trial) if moved_all is None else moved_all[i]
        if moved is None:
            return best
        jacobian[:, i] = (moved - effect) / step
    for _ in range(max_iterations):
        step_x = lsq_linear(jacobian, residual, bounds=(-sizes, upper - sizes)).x
        new = sizes + step_x
        new_effect = run(new)
        if new_effect is None:
            break
        # Broyden's rank-one update: the Jacobian reproduces the change just seen
        change = new_effect - effect
        denom = float(step_x @ step_x)
        if denom > 0:
            jacobian = jacobian + np.outer(change - jacobian @ step_x, step_x) / denom
        new_residual = target - new_effect
        rss = float(new_residual @ new_residual)
        if rss < best.rss:
            best = SimulatedFit(new.copy(), rss, jacobian)
        sizes, effect, residual = new, new_effect, new_residual
        if np.all(np.abs(step_x) <= tolerance * np.maximum(np.abs(sizes), min_step)):
            break
    return best


def refine_all(
    starts: Mapping[Subset, FloatArray],
    target: FloatArray,
    simulate: SimulatedEffect,
    upper: FloatArray,
    max_iterations: int = 4,
    threads: int = 1,
) -> dict[Subset, SimulatedFit]:
    """Size several explanations by simulation (:func:`refine_by_simulation`) at once.

    Each is sized from its own start (``simulate`` must be thread-safe when
    ``threads > 1``): every explanation on its own thread and, within one, the start
    and the difference steps at once, with at most ``threads`` simulations running at
    any time; the result is the same on any number of threads.

    Parameters
    ----------
    starts : mapping
        ``subset -> starting sizes [kg/s]``.
    target, simulate, max_iterations
        As for :func:`refine_by_simulation`.
    upper : ndarray, shape (n_locations,)
        Largest size of every location [kg/s].
    threads : int
        Threads that size explanations at once [-].

    Returns
    -------
    dict
        ``subset -> SimulatedFit`` in the order of ``starts``, for those the machine
        could run.
    """
    jobs = list(starts.items())
    if threads <= 1:
        fits = [
            refine_by_simulation(sub, start, target, simulate, upper[list(sub)], max_iterations)
            for sub, start in jobs
        ]
    else:
        gate = _FairGate(threads, len(jobs))

        def size(k: int) -> SimulatedFit | None:
            def one(leaks: Mapping[int, float]) -> FloatArray | None:
                return gate.run(k, simulate, leaks)

            def many(calls: Sequence[Mapping[int, float]]) -> list[FloatArray | None]:
                return thread_map(one, calls, len(calls))

            sub, start = jobs[k]
            return refine_by_simulation(
                sub,
                start,
                target,
                one,
                upper[list(sub)],
                max_iterations,
                simulate_many=many,
            )

        fits = thread_map(size, range(len(jobs)), len(jobs))
    return {sub: fit for sub, fit in zip(starts, fits, strict=True) if fit is not None}


class _FairGate:
    """At most ``slots`` simulations at once; a free slot goes to the explanation
    that has run the fewest so far (then the first), so that explanations progress
    together and the batch does not end with one long chain on one core."""

    def __init__(self, slots: int, jobs: int) -> None:
        self._cond = threading.Condition()
        self._free = slots
        self._done = [0] * jobs
        self._waiting: list[tuple[int, int, int]] = []
        self._tickets = itertools.count()

    def run(
        self, job: int, simulate: SimulatedEffect, leaks: Mapping[int, float]
    ) -> FloatArray | None:
        """``simulate(leaks)`` for explanation ``job``, when its turn comes."""
        with self._cond:
            ticket = (self._done[job], job, next(self._tickets))
            heapq.heappush(self._waiting, ticket)
            while self._free == 0 or self._waiting[0] != ticket:
                self._cond.wait()
            heapq.heappop(self._waiting)
            self._free -= 1
            self._cond.notify_all()
        try:
            return simulate(leaks)
        finally:
            with self._cond:
                self._free += 1
                self._done[job] += 1
                self._cond.notify_all()


def _pair_rss(fits: Mapping[Subset, tuple[FloatArray, float]], a: int, b: int) -> float:
    """Signature-model residual of the pair ``a, b`` (inf when it was not fitted) [-]."""
    fit = fits.get((min(a, b), max(a, b)))
    return math.inf if fit is None else fit[1]


def verify_explanations(
    target: FloatArray,
    model_fits: Mapping[Subset, tuple[FloatArray, float]],
    n_locations: int,
    simulate: SimulatedEffect,
    upper: FloatArray,
    min_flow: float = 0.0,
    top_singles: int = 2,
    top_pairs: int = 3,
    partners: int = 3,
    probe: float = 8.6e-4,
    max_iterations: int = 3,
    probes: int = 0,
    threads: int = 1,
) -> dict[Subset, SimulatedFit]:
    """Simulate and size the most promising explanations of one or two leaks.

    1. The ``top_singles`` best single leaks of the signature model, sized by
       simulation.
    2. Next to the best of them, the other locations are *probed* (the ``probes``
       whose signature-model pair with it fits best, or all): simulated at size
       ``probe`` beside it, which gives its effect in the presence of the first leak
       (the interaction included); a bounded linear fit of both sizes to the data
       ranks the second leaks, and the ``partners`` best pairs are sized by
       simulation.
    3. The ``top_pairs`` best pairs of the signature model whose sizes are all at
       least ``min_flow``, sized by simulation.

    Parameters
    ----------
    target : ndarray
        Whitened observed change [-].
    model_fits : mapping
        Signature-model fits of every subset of one or two locations:
        ``subset -> (sizes [kg/s], rss [-])``.
    n_locations : int
        Number of candidate locations [-].
    simulate : callable
        See :func:`refine_by_simulation`.
    upper : ndarray, shape (n_locations,)
        Largest size of each location [kg/s].
    min_flow : float
        Smallest leak of a signature-model pair worth checking [kg/s].
    top_singles, top_pairs, partners : int
        Numbers of explanations checked in steps 1, 3 and 2 [-].
    probe : float
        Size at which second leaks are probed (40 SLPM by default) [kg/s].
    max_iterations : int
        Gauss-Newton steps per explanation at most [-].
    probes : int
        Second leaks probed in step 2 (0: every location) [-].
    threads : int
        Simulations that run at once (:func:`refine_all`; the probes); the partners
        of step 2 and the pairs of step 3 are one batch. ``simulate`` must then be
        thread-safe. The result does not depend on it: every explanation is sized
        from the same start and kept in the same order as on one thread.

    Returns
    -------
    dict
        ``subset -> SimulatedFit`` for every explanation the simulator could run.

    Examples
    --------
    Two "locations" whose simulated effects interact (the product term), which the
    additive signature model misses; the true pair is found with its sizes:

    >>> S = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    >>> def sim(leaks):
    ...     a, b = leaks.get(0, 0.0), leaks.get(1, 0.0)
    ...     return a * S[0] + b * S[1] + np.array([0.0, 0.0, 0.3 * a * b])
    >>> def fit(sub, t):
    ...     A = S[list(sub)].T
    ...     return np.clip(np.linalg.lstsq(A, t, rcond=None)[0], 0.0, None)
    >>> y = sim({0: 2.0, 1: 1.0})
    >>> fits = {s: (fit(s, y), 1.0) for s in [(0,), (1,), (0, 1)]}
    >>> out = verify_explanations(y, fits, 2, sim, np.array([9.0, 9.0]), probe=0.5)
    >>> sizes, rss, _ = out[(0, 1)]
    >>> [round(float(v), 2) for v in sizes], rss < 1e-4
    ([2.0, 1.0], True)
    """
    singles = sorted((fit[1], sub) for sub, fit in model_fits.items() if len(sub) == 1)
    pairs = sorted(
        (fit[1], sub)
        for sub, fit in model_fits.items()
        if len(sub) == 2 and np.all(fit[0] >= min_flow)
    )
    checked: dict[Subset, SimulatedFit] = {}

    def check(candidates: Iterable[tuple[Subset, FloatArray]]) -> None:
        todo: dict[Subset, FloatArray] = {}
        for sub, start in candidates:
            if sub not in checked and sub not in todo:
                todo[sub] = start
        checked.update(refine_all(todo, target, simulate, upper, max_iterations, threads))

    check((single, model_fits[single][0]) for _, single in singles[:top_singles])
    firsts = sorted((fit.rss, sub) for sub, fit in checked.items() if len(sub) == 1)
    partner_starts: list[tuple[Subset, FloatArray]] = []
    if firsts and partners > 0:
        first = firsts[0][1][0]
        size, _, slope = checked[(first,)]
        base = simulate({first: float(size[0])})
        if base is not None:
            rest = target - base
            ranked = []
            others = [o for o in range(n_locations) if o != first]
            if 0 < probes < len(others):
                # the signature model's best partners of the first leak
                others.sort(key=lambda o: _pair_rss(model_fits, first, o))
                others = others[:probes]
            probed_all = thread_map(
                lambda other: simulate({first: float(size[0]), other: probe}), others, threads
            )
            for other, probed in zip(others, probed_all, strict=True):
                if probed is None:
                    continue
                columns = np.column_stack([slope[:, 0], (probed - base) / probe])
                step = lsq_linear(
                    columns,
                    rest,
                    bounds=([-size[0], 0.0], [upper[first] - size[0], upper[other]]),
                ).x
                residual = rest - columns @ step
                ranked.append((float(residual @ residual), other, step))
            for _, other, step in sorted(ranked, key=lambda r: r[0])[:partners]:
                sizes = {first: float(size[0] + step[0]), other: float(step[1])}
                pair = tuple(sorted(sizes))
                partner_starts.append((pair, np.array([sizes[i] for i in pair])))
    # the partners and the signature model's pairs are independent: one batch, a
    # partner's start first (as if sized before the model pairs); a model pair that
    # was also a partner the machine could not run is then sized from its own start
    model_pairs = [(couple, model_fits[couple][0]) for _, couple in pairs[:top_pairs]]
    check([*partner_starts, *model_pairs])
    partner_pairs = {sub for sub, _ in partner_starts}
    check((sub, start) for sub, start in model_pairs if sub in partner_pairs)
    return checked
