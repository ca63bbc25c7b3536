"""Check the best leak explanations by simulating them (analysis by synthesis).

The signature model of :mod:`pneufdd.diagnosis.localisation.search` interpolates single-leak
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

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.optimize import lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.localisation.model_choice import Subset
from pneufdd.errors import InputError, describe
from pneufdd.parallel import thread_map

__all__ = [
    "SimulatedFit",
    "SimulationCheckSettings",
    "refine_all",
    "refine_by_simulation",
    "verify_explanations",
]

SimulatedEffect = Callable[[Mapping[int, float]], FloatArray | None]
"""Whitened effect of leaks ``{location index: size [kg/s]}`` by simulation, or None."""
SimulateMany = Callable[[Sequence[Mapping[int, float]]], list[FloatArray | None]]
"""A :data:`SimulatedEffect` of several sets of leaks, results in their order."""
Slopes = Callable[[Subset, FloatArray], FloatArray]
"""Estimated derivative of the whitened effect of ``subset`` by size at ``sizes``."""

_TOLERANCE = 0.02
"""Gauss-Newton stops when no size moves by more than this fraction [-]."""
_MIN_STEP = 1e-4
"""Smallest finite-difference step [kg/s]."""


def _leak_set(subset: Subset, sizes: FloatArray) -> dict[int, float]:
    """``{location index: size [kg/s]}`` of an explanation."""
    return dict(zip(subset, (float(v) for v in sizes), strict=True))


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
    residual : ndarray, shape (n_components,)
        What the simulated effect leaves of the whitened observed change [-].
    """

    sizes: FloatArray
    rss: float
    jacobian: FloatArray
    residual: FloatArray


class _SizeSearch:
    """Gauss-Newton sizing of one explanation, one batch of simulations at a time.

    :meth:`requests` gives the sizes to simulate next, :meth:`receive` takes their
    whitened effects in the same order (None: the machine could not run): the start
    and the difference steps at once, then one Gauss-Newton step at a time. With an
    ``estimate`` of the Jacobian, the start is simulated alone first and the
    difference steps follow only if the search goes on (:attr:`predicted_rss` is
    then the estimate's prediction); the steps taken are the same. The sequence of
    sizes depends only on the results, never on when they arrive.
    """

    def __init__(
        self,
        start: FloatArray,
        target: FloatArray,
        upper: FloatArray,
        max_iterations: int,
        tolerance: float,
        min_step: float,
        estimate: FloatArray | None = None,
    ) -> None:
        self.target = target
        self.upper = np.asarray(upper, dtype=np.float64)
        self.sizes = np.clip(np.asarray(start, dtype=np.float64), 0.0, self.upper)
        self.max_iterations = max_iterations
        self.tolerance = tolerance
        self.min_step = min_step
        self.best: SimulatedFit | None = None
        self.done = False
        self.predicted_rss = math.inf
        """Residual the linearised model predicts for the next step [-]."""
        self._estimate = estimate
        self._attempt = 0
        self._iteration = 0
        self._steps: list[tuple[float, FloatArray]] = []
        self._proposal: FloatArray | None = None
        self._step = np.zeros(0)
        self._effect = np.zeros(0)
        self._residual = np.zeros(0)
        self._jacobian = np.zeros((0, 0))

    def _difference_steps(self) -> list[tuple[float, FloatArray]]:
        out = []
        for i in range(self.sizes.size):
            step = max(0.15 * self.sizes[i], self.min_step)
            if self.sizes[i] + step > self.upper[i]:
                step = -step
            trial = self.sizes.copy()
            trial[i] += step
            out.append((step, trial))
        return out

    def requests(self) -> list[FloatArray]:
        """Sizes to simulate next, each [kg/s]; empty when the search has ended."""
        if self.done:
            return []
        if self._proposal is not None:
            return [self._proposal]
        self._steps = self._difference_steps()
        trials = [trial for _, trial in self._steps]
        if self.best is not None:  # the start ran alone: its difference steps
            return trials
        return [self.sizes] if self._estimate is not None else [self.sizes, *trials]

    def stop(self) -> None:
        """End the search; :attr:`best` stays the best explanation met so far."""
        self.done = True

    def receive(self, effects: Sequence[FloatArray | None]) -> None:
        """Take the simulated effects of the last :meth:`requests`, in its order."""
        if self._proposal is not None:
            self._take_step(effects[0])
        elif self.best is not None:
            self._take_differences(effects)
        else:
            self._take_start(effects)

    def _take_start(self, effects: Sequence[FloatArray | None]) -> None:
        effect, *moved = effects
        if effect is None:
            self._attempt += 1
            if self._attempt == 3:
                self.done = True
            self.sizes = 0.7 * self.sizes  # the machine stalls: the explanation is too large
            return
        self._effect = effect
        self._residual = self.target - effect
        self._jacobian = np.zeros((self.target.size, self.sizes.size))
        rss = float(self._residual @ self._residual)
        self.best = SimulatedFit(self.sizes.copy(), rss, self._jacobian, self._residual)
        if self._estimate is None:
            self._take_differences(moved)
            return
        bounds = (-self.sizes, self.upper - self.sizes)
        self.predicted_rss = 2.0 * float(lsq_linear(self._estimate, self._residual, bounds).cost)

    def _take_differences(self, moved_all: Sequence[FloatArray | None]) -> None:
        for i, ((step, _), moved) in enumerate(zip(self._steps, moved_all, strict=True)):
            if moved is None:
                self.done = True
                return
            self._jacobian[:, i] = (moved - self._effect) / step
        self._propose()

    def _propose(self) -> None:
        if self._iteration == self.max_iterations:
            self.done = True
            return
        solution = lsq_linear(
            self._jacobian, self._residual, bounds=(-self.sizes, self.upper - self.sizes)
        )
        self._step = solution.x
        self._proposal = self.sizes + self._step
        self.predicted_rss = 2.0 * float(solution.cost)

    def _take_step(self, new_effect: FloatArray | None) -> None:
        assert self._proposal is not None
        assert self.best is not None
        self._iteration += 1
        if new_effect is None:
            self.done = True
            return
        new, step_x = self._proposal, self._step
        # Broyden's rank-one update: the Jacobian reproduces the change just seen
        change = new_effect - self._effect
        denom = float(step_x @ step_x)
        if denom > 0:
            self._jacobian = (
                self._jacobian + np.outer(change - self._jacobian @ step_x, step_x) / denom
            )
        new_residual = self.target - new_effect
        rss = float(new_residual @ new_residual)
        if rss < self.best.rss:
            self.best = SimulatedFit(new.copy(), rss, self._jacobian, new_residual)
        self.sizes, self._effect, self._residual = new, new_effect, new_residual
        if np.all(np.abs(step_x) <= self.tolerance * np.maximum(np.abs(new), self.min_step)):
            self.done = True
            return
        self._propose()


def refine_by_simulation(
    subset: Subset,
    start: FloatArray,
    target: FloatArray,
    simulate: SimulatedEffect,
    upper: FloatArray,
    max_iterations: int = 4,
    tolerance: float = _TOLERANCE,
    min_step: float = _MIN_STEP,
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
    >>> sizes, rss, *_ = refine_by_simulation((0, 1), np.array([1.0, 3.0]), y, sim,
    ...                                      np.array([10.0, 10.0]), max_iterations=20,
    ...                                      tolerance=1e-6)
    >>> [round(float(v), 4) for v in sizes], rss < 1e-12
    ([2.0, 1.0], True)
    """
    search = _SizeSearch(start, target, upper, max_iterations, tolerance, min_step)
    while calls := search.requests():
        if simulate_many is not None and len(calls) > 1:
            search.receive(simulate_many([_leak_set(subset, x) for x in calls]))
            continue
        effects: list[FloatArray | None] = []
        for x in calls:  # one at a time: nothing more once the machine cannot run
            effects.append(simulate(_leak_set(subset, x)))
            if effects[-1] is None:
                break
        search.receive(effects + [None] * (len(calls) - len(effects)))
    return search.best


def refine_all(
    starts: Mapping[Subset, FloatArray],
    target: FloatArray,
    simulate: SimulatedEffect,
    upper: FloatArray,
    max_iterations: int = 4,
    threads: int = 1,
    keep_within: float = math.inf,
    leader: float = math.inf,
    estimates: Mapping[Subset, FloatArray] | None = None,
) -> dict[Subset, SimulatedFit]:
    """Size several explanations by simulation (:func:`refine_by_simulation`) at once.

    The explanations advance in rounds: in each, every one still being sized runs
    what it needs next (its start and difference steps, then one Gauss-Newton step),
    all on up to ``threads`` threads (``simulate`` must be thread-safe when
    ``threads > 1``). Between rounds, an explanation stops being sized when neither
    its residual so far nor the one its linearised model predicts for its next step
    comes within ``keep_within`` times the best residual met (``leader`` included):
    it can no longer become the chosen explanation or an alternative, and its steps
    would cost simulations that change no reported location or group (a member forced
    into a group reports its fit's size, stopped or not). The result does not depend
    on ``threads``.

    Parameters
    ----------
    starts : mapping
        ``subset -> starting sizes [kg/s]``.
    target, simulate, max_iterations
        As for :func:`refine_by_simulation`.
    upper : ndarray, shape (n_locations,)
        Largest size of every location [kg/s].
    threads : int
        Simulations that run at once [-].
    keep_within : float
        Ratio to the best residual beyond which an explanation stops being sized
        (inf: every explanation is sized to the end) [-].
    leader : float
        Best simulated residual of explanations sized before these [-].
    estimates : mapping, optional
        ``subset -> estimate of the whitened effect's derivative by size
        [1/(kg/s)]`` (the signature model's, or one measured by earlier
        simulations): such an explanation's start is simulated alone, and its
        difference steps only if the estimate's prediction keeps it in the running.

    Returns
    -------
    dict
        ``subset -> SimulatedFit`` in the order of ``starts``, for those the machine
        could run.

    Examples
    --------
    Two candidate "leaks" with effects along different directions; the wrong one
    stops after its start and difference step (2 simulations), the right one is
    sized:

    >>> S = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    >>> runs = []
    >>> def sim(leaks):
    ...     runs.append(dict(leaks))
    ...     return sum(v * S[k] for k, v in leaks.items())
    >>> y = 2.0 * S[1] + np.array([0.01, 0.0, 0.0])
    >>> out = refine_all({(0,): np.array([1.0]), (1,): np.array([1.9])}, y, sim,
    ...                  np.array([9.0, 9.0]), keep_within=4.0)
    >>> round(float(out[(1,)].sizes[0]), 3), sum(0 in r for r in runs)
    (2.0, 2)
    """
    jobs = list(starts.items())
    upper = np.asarray(upper, dtype=np.float64)
    searches = [
        _SizeSearch(
            start,
            target,
            upper[list(sub)],
            max_iterations,
            _TOLERANCE,
            _MIN_STEP,
            None if estimates is None else estimates.get(sub),
        )
        for sub, start in jobs
    ]

    def run(call: tuple[int, FloatArray]) -> FloatArray | None:
        return simulate(_leak_set(jobs[call[0]][0], call[1]))

    while True:
        fits = [s.best.rss for s in searches if s.best is not None]
        bar = keep_within * min([leader, *fits])
        for search in searches:
            if search.best is not None and min(search.best.rss, search.predicted_rss) > bar:
                search.stop()
        calls = [(k, x) for k, search in enumerate(searches) for x in search.requests()]
        if not calls:
            break
        results = thread_map(run, calls, threads)
        for k, search in enumerate(searches):
            mine = [r for (j, _), r in zip(calls, results, strict=True) if j == k]
            if mine:
                search.receive(mine)
    return {sub: s.best for (sub, _), s in zip(jobs, searches, strict=True) if s.best is not None}


def _pair_rss(fits: Mapping[Subset, tuple[FloatArray, float]], a: int, b: int) -> float:
    """Signature-model residual of the pair ``a, b`` (inf when it was not fitted) [-]."""
    fit = fits.get((min(a, b), max(a, b)))
    return math.inf if fit is None else fit[1]


_COUNTS = ("top_singles", "partners", "probed_locations", "top_pairs", "max_iterations")
"""The settings of :class:`SimulationCheckSettings` that count something."""


@dataclass(frozen=True)
class SimulationCheckSettings:
    """Which explanations :func:`verify_explanations` checks, and how far it sizes them.

    Attributes
    ----------
    top_singles : int
        Best single leaks of the signature model sized by simulation (step 1) [-].
    partners : int
        Best pairs found by probing beside the best single leak that are then sized
        by simulation (step 2) [-].
    probed_locations : int
        Second leaks probed in step 2: the locations whose signature-model pair with
        the first leak fits best (0: every location) [-].
    probe_size : float
        Size at which second leaks are probed (40 SLPM by default) [kg/s].
    top_pairs : int
        Best pairs of the signature model sized by simulation (step 3) [-].
    min_pair_flow : float
        Smallest leak of a signature-model pair worth checking in step 3 [kg/s].
    max_iterations : int
        Gauss-Newton steps per explanation at most [-].
    keep_within : float
        An explanation stops being sized when it cannot come within this ratio of
        the best simulated residual so far (:func:`refine_all`; inf: never) [-].

    Examples
    --------
    >>> SimulationCheckSettings(top_pairs=0).partners
    3
    >>> SimulationCheckSettings(keep_within=0.5)
    Traceback (most recent call last):
    ...
    pneufdd.errors.InputError: check setting keep_within: received 0.5; allowed: >= 1 (inf: off)
    """

    top_singles: int = 2
    partners: int = 3
    probed_locations: int = 0
    probe_size: float = 8.6e-4
    top_pairs: int = 3
    min_pair_flow: float = 0.0
    max_iterations: int = 3
    keep_within: float = math.inf

    def __post_init__(self) -> None:
        for name in _COUNTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InputError(describe(f"check setting {name}", value, "an integer >= 0"))
        if not (math.isfinite(self.probe_size) and self.probe_size > 0):
            raise InputError(
                describe("check setting probe_size", self.probe_size, "a finite size > 0 [kg/s]")
            )
        if not (math.isfinite(self.min_pair_flow) and self.min_pair_flow >= 0):
            raise InputError(
                describe("check setting min_pair_flow", self.min_pair_flow, "a finite flow >= 0")
            )
        if not self.keep_within >= 1:
            raise InputError(
                describe("check setting keep_within", self.keep_within, ">= 1 (inf: off)")
            )


def _best_first(
    model_fits: Mapping[Subset, tuple[FloatArray, float]],
    n_leaks: int,
    min_flow: float | None = None,
) -> list[Subset]:
    """Subsets of ``n_leaks`` locations, smallest signature-model residual first.

    With ``min_flow``, only those whose sizes are all at least that [kg/s].
    """
    return [
        sub
        for _, sub in sorted(
            (fit[1], sub)
            for sub, fit in model_fits.items()
            if len(sub) == n_leaks and (min_flow is None or np.all(fit[0] >= min_flow))
        )
    ]


def _probed_locations(
    model_fits: Mapping[Subset, tuple[FloatArray, float]],
    first: int,
    n_locations: int,
    probes: int,
) -> list[int]:
    """The second leaks to probe beside ``first``: all, or the ``probes`` best partners."""
    others = [o for o in range(n_locations) if o != first]
    if 0 < probes < len(others):
        # the signature model's best partners of the first leak
        others.sort(key=lambda o: _pair_rss(model_fits, first, o))
        others = others[:probes]
    return others


class _Check:
    """The explanations of one run sized by simulation so far, in the order sized."""

    def __init__(
        self,
        target: FloatArray,
        simulate: SimulatedEffect,
        upper: FloatArray,
        settings: SimulationCheckSettings,
        slopes: Slopes | None,
        threads: int,
    ) -> None:
        self.target = target
        self.simulate = simulate
        self.upper = upper
        self.settings = settings
        self.slopes = slopes
        self.threads = threads
        self.checked: dict[Subset, SimulatedFit] = {}

    def size(
        self,
        candidates: Iterable[tuple[Subset, FloatArray]],
        measured: Mapping[Subset, FloatArray] | None = None,
    ) -> None:
        """Size the ``(subset, start)`` not sized yet as one batch (:func:`refine_all`).

        ``measured``: Jacobians measured by earlier simulations, used instead of the
        signature model's slopes to judge a start.
        """
        todo: dict[Subset, FloatArray] = {}
        for sub, start in candidates:
            if sub not in self.checked and sub not in todo:
                todo[sub] = start
        estimates = None
        if self.slopes is not None:
            known = measured or {}
            estimates = {
                sub: known[sub] if sub in known else self.slopes(sub, start)
                for sub, start in todo.items()
            }
        leader = min((fit.rss for fit in self.checked.values()), default=math.inf)
        self.checked.update(
            refine_all(
                todo,
                self.target,
                self.simulate,
                self.upper,
                self.settings.max_iterations,
                self.threads,
                self.settings.keep_within,
                leader,
                estimates,
            )
        )

    def partners_of_best_single(
        self, model_fits: Mapping[Subset, tuple[FloatArray, float]], n_locations: int
    ) -> tuple[list[tuple[Subset, FloatArray]], dict[Subset, FloatArray]]:
        """Step 2: the best pairs found by probing beside the best single leak.

        Returns their starts ``(pair, sizes [kg/s])``, best first, and the Jacobian
        each probe measured [1/(kg/s)].
        """
        firsts = sorted((fit.rss, sub) for sub, fit in self.checked.items() if len(sub) == 1)
        if not firsts or self.settings.partners <= 0:
            return [], {}
        first = firsts[0][1][0]
        size = float(self.checked[(first,)].sizes[0])
        base = self.simulate({first: size})
        if base is None:
            return [], {}
        others = _probed_locations(model_fits, first, n_locations, self.settings.probed_locations)
        ranked = self._probe(first, base, others)
        starts: list[tuple[Subset, FloatArray]] = []
        jacobians: dict[Subset, FloatArray] = {}
        for _, other, step, columns in ranked[: self.settings.partners]:
            sizes = {first: float(size + step[0]), other: float(step[1])}
            pair = tuple(sorted(sizes))
            starts.append((pair, np.array([sizes[i] for i in pair])))
            jacobians[pair] = columns if pair[0] == first else columns[:, ::-1]
        return starts, jacobians

    def _probe(
        self, first: int, base: FloatArray, others: Sequence[int]
    ) -> list[tuple[float, int, FloatArray, FloatArray]]:
        """Second leaks ranked by how well they explain what ``first`` leaves.

        Each is simulated at the probe size beside the first leak as sized; a bounded
        linear fit of both sizes to the rest of the data gives ``(rss [-], location,
        size changes [kg/s], Jacobian [1/(kg/s)])``, best first.
        """
        size, _, slope, _ = self.checked[(first,)]
        probe = self.settings.probe_size
        rest = self.target - base
        probed_all = thread_map(
            lambda other: self.simulate({first: float(size[0]), other: probe}),
            others,
            self.threads,
        )
        ranked = []
        for other, probed in zip(others, probed_all, strict=True):
            if probed is None:
                continue
            columns = np.column_stack([slope[:, 0], (probed - base) / probe])
            step = lsq_linear(
                columns,
                rest,
                bounds=([-size[0], 0.0], [self.upper[first] - size[0], self.upper[other]]),
            ).x
            residual = rest - columns @ step
            ranked.append((float(residual @ residual), other, step, columns))
        return sorted(ranked, key=lambda r: r[0])


def verify_explanations(
    target: FloatArray,
    model_fits: Mapping[Subset, tuple[FloatArray, float]],
    n_locations: int,
    simulate: SimulatedEffect,
    upper: FloatArray,
    settings: SimulationCheckSettings | None = None,
    *,
    slopes: Slopes | None = None,
    threads: int = 1,
) -> dict[Subset, SimulatedFit]:
    """Simulate and size the most promising explanations of one or two leaks.

    1. The ``top_singles`` best single leaks of the signature model, sized by
       simulation.
    2. Next to the best of them, the other locations are *probed* (the
       ``probed_locations`` whose signature-model pair with it fits best, or all):
       simulated at size ``probe_size`` beside it, which gives its effect in the
       presence of the first leak (the interaction included); a bounded linear fit of
       both sizes to the data ranks the second leaks, and the ``partners`` best pairs
       are sized by simulation.
    3. The ``top_pairs`` best pairs of the signature model whose sizes are all at
       least ``min_pair_flow``, sized by simulation.

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
    settings : SimulationCheckSettings, optional
        How many explanations of each step are checked and how far they are sized
        (None: the defaults).
    slopes : callable, optional
        ``slopes(subset, sizes)``: the signature model's derivative of the whitened
        effect by size at ``sizes`` [1/(kg/s)]. With it, each explanation's start
        is simulated alone and judged before its difference steps are simulated
        (``estimates`` of :func:`refine_all`): by these slopes, and a partner of
        step 2 by the Jacobian its probe measured (the first leak's from its own
        sizing, the second's from the probe's change).
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
    >>> out = verify_explanations(y, fits, 2, sim, np.array([9.0, 9.0]),
    ...                           SimulationCheckSettings(probe_size=0.5))
    >>> sizes, rss, *_ = out[(0, 1)]
    >>> [round(float(v), 2) for v in sizes], rss < 1e-4
    ([2.0, 1.0], True)
    """
    settings = SimulationCheckSettings() if settings is None else settings
    check = _Check(target, simulate, upper, settings, slopes, threads)
    singles = _best_first(model_fits, 1)[: settings.top_singles]
    check.size((single, model_fits[single][0]) for single in singles)
    partner_starts, partner_jacobians = check.partners_of_best_single(model_fits, n_locations)
    pairs = _best_first(model_fits, 2, settings.min_pair_flow)[: settings.top_pairs]
    model_pairs = [(pair, model_fits[pair][0]) for pair in pairs]
    # the partners and the signature model's pairs are independent: one batch, a
    # partner's start first (as if sized before the model pairs); a model pair that
    # was also a partner the machine could not run is then sized from its own start
    check.size([*partner_starts, *model_pairs], partner_jacobians)
    partner_pairs = {sub for sub, _ in partner_starts}
    check.size((sub, start) for sub, start in model_pairs if sub in partner_pairs)
    return check.checked
