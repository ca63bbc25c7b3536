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
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, fields

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects, Whitener
from pneufdd.diagnosis.localisation.check import (
    SimulatedEffect,
    SimulationCheckSettings,
    refine_all,
    verify_explanations,
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
    same_actuator_pair,
)
from pneufdd.errors import InputError, describe
from pneufdd.location import SUPPLY, Location

__all__ = ["Localisation", "LocalisationSettings", "SizedLocation", "locate"]


_SWITCHES = ("simulate_explanations", "group_model_error")
"""The settings that are on or off (the rest are numbers)."""

_FILE_KEYS = {"min_mass_flow": "min_flow"}
"""Settings stored under another key in ``.pnref`` files (the key files have always had)."""


@dataclass(frozen=True)
class LocalisationSettings:
    """Tuning of leak location and sizing, stored with the reference.

    Attributes
    ----------
    max_leaks : int
        Largest number of simultaneous leaks considered (1 or 2) [-].
    min_relative_gain : float
        A model with one more leak must lower the weighted residual by at least this
        fraction: on development plants (seeds 7,800,000+, model error weighted), a
        spurious second leak lowered it by at most 32 % and most true second leaks by
        more than 26 %; 0.25 removed nearly all spurious ones and few true ones [-].
    first_leak_gain : float
        When no model passes ``min_relative_gain``, the best single leak is still
        reported if it passes the information criterion and lowers the residual by
        this fraction (:func:`~pneufdd.diagnosis.localisation.model_choice.choose_leak_count`); its
        confidence is then low. 0: in acceptance testing on a scale-2 press-fit-cell
        plant, a 230 SLPM PRESS_A leak was detected, and PRESS_A fitted best, but it
        explained 20 % of the deviation and nothing was located. 1 turns the
        fallback off (references saved before) [-].
    group_ratio : float
        Alternatives whose Akaike-type weight is at least this fraction of the best
        join the ambiguity group [-].
    collinear_cos : float
        Alternatives whose weighted signature has at least this cosine similarity
        with the chosen one join the group [-].
    min_mass_flow : float
        Smallest leak reported; a model needing a smaller leak is not considered
        (2 SLPM by default, below the leak valve's first turn); ``min_flow`` in the
        ``.pnref`` file [kg/s].
    relative_tolerance : float
        Alternatives whose weighted residual is at most ``1 + relative_tolerance``
        times the best join the group, and disjoint explanations within it are listed:
        the fit barely changes when they are swapped in, which matters when the
        residual is dominated by model error rather than noise [-].
    max_extrapolation : float
        Largest size considered, as a multiple of the largest simulated size: beyond
        the ladder the effects are extrapolated linearly, and an unbounded
        extrapolation lets one huge leak absorb a second, real one [-].
    refine_top : int
        Number of best additive pairs refined with their bilinear interaction before
        the model is chosen [-].
    max_alternatives : int
        Largest number of disjoint alternative explanations reported, and of "both
        lines of one actuator" explanations of a supply leak [-].
    both_lines_max_ratio : float
        A supply leak's alternative "both lines of one actuator" is offered only when
        the additive residual of those two leaks is at most this multiple of the
        chosen model's (the largest multiple among development pairs where it held
        the truth was 27.6) [-].
    simulate_explanations : bool
        Check explanations by simulation when the signatures misfit (needs the
        machine's description) [-].
    misfit_ratio : float
        Residual per component above which the signature model is deemed not to
        describe the run, when the signatures chose two leaks [-].
    severe_misfit_ratio : float
        The same when the signatures chose one leak: single leaks are interpolated
        from simulations of that very leak and fit well (development: at most 51 for
        6-turn leaks), a pair whose interaction the signatures miss leaves 30-1,500 [-].
    added_leak_gain : float
        When the signatures chose one leak, simulated explanations add a second only
        if it lowers the residual by this fraction (on development single leaks a
        spurious 3-7 SLPM second leak lowered it by 10-44 %) [-].
    group_checks : int
        With simulated explanations, alternatives simulated per leak for its
        ambiguity group (the signature model's best in that slot). 1: on 60
        development runs of festo-dsd with two leaks and only supply sensors, 1
        instead of 3 reported the same leaks, groups, sizes, confidences and
        alternatives with fewer simulations (references saved before keep their 3) [-].
    probes : int
        With simulated explanations, second leaks probed by simulation beside the
        best single leak: the locations whose signature-model pair with it fits best
        (0: every location). 6 with ``group_checks`` 1 cut the simulations of those
        60 runs from 2,968 to 1,681 (max per run 89 to 52) with the same results;
        references saved before probe every location [-].
    model_error_floor : float
        Independent model error of every feature, as a fraction of the leak's effect
        on it, beside the coherent error sampled on plausible plants
        (:func:`pneufdd.diagnosis.engine.whitener`): 2 %, the calibration class of the
        sensors (``docs/plant-variation.md``) [-].
    imitation_z : float
        A second leak is reported only when its size exceeds this many times the size
        of it that the larger leak's model error imitates: the RMS over the plausible
        plants of the size a fit of the second leak gives to a plant's deviation from
        the larger leak's signature (:func:`pneufdd.diagnosis.engine.imitated_size`).
        Below it, the two-leak explanation is listed as an alternative. 3: three
        standard deviations, as the band of eq. 5.3; 0 turns the check off (references
        saved before it existed) [-].
    min_leak_confidence : float
        Of two leaks, each must be at least this likely to lie in its ambiguity group
        to be reported; otherwise one leak is reported and the pair is listed as an
        alternative. 0.5: a reported leak is more likely there than not (without the
        check, a scale-2 carton-sorter run in acceptance testing reported a 5 SLPM
        second leak at confidence 0.00005); 0 turns the check off (references saved
        before it) [-].
    group_model_error : bool
        The run's weighting holds the model error of every location in the ambiguity
        groups of the first, noise-weighted explanation, not only of its chosen leaks
        (:func:`pneufdd.diagnosis.engine.run_whitener`). A line held pressurised all
        but one step (a 5/2 monostable valve's B line) differs from the supply only in
        that step, where the twin of a drafted cylinder is least sure; weighted with
        the supply leak's model error alone, that step ruled the line out. When that
        weighting finds one leak, the run is located again with the chosen leaks'
        model error, and two leaks found so are kept unless both lie in the one
        leak's group (``engine._locate_weighted``). False: references saved before [-].
    keep_within : float
        With simulated explanations, one stops being sized by simulation when neither
        its simulated residual nor the one a linear model predicts for its next step
        comes within this multiple of the best simulated residual so far
        (:func:`pneufdd.diagnosis.localisation.check.refine_all`); its start is judged by the
        signature model's slopes before its difference steps are simulated. Beyond
        2 an explanation changes no reported leak, group or alternative (an
        alternative or group member needs at most ``1 + relative_tolerance`` = 1.5
        times the best, a single leak outweighs a pair from 1 / (1 -
        ``added_leak_gain``) = 2 times), though a group member forced in by
        :func:`_forced_member` reports the flow of its pair's fit, stopped or not; 4
        leaves a factor 2 for what the linear model misses. 0 turns it off
        (references saved before) [-].

    Examples
    --------
    >>> LocalisationSettings.from_dict(LocalisationSettings(max_leaks=1).to_dict()).max_leaks
    1
    """

    max_leaks: int = 2
    min_relative_gain: float = 0.25
    first_leak_gain: float = 0.0
    group_ratio: float = 0.05
    collinear_cos: float = 0.995
    min_mass_flow: float = 4.3e-5
    relative_tolerance: float = 0.5
    max_extrapolation: float = 1.25
    refine_top: int = 20
    max_alternatives: int = 3
    both_lines_max_ratio: float = 30.0
    simulate_explanations: bool = True
    misfit_ratio: float = 3.0
    severe_misfit_ratio: float = 20.0
    added_leak_gain: float = 0.5
    group_checks: int = 1
    model_error_floor: float = 0.02
    imitation_z: float = 3.0
    probes: int = 6
    min_leak_confidence: float = 0.5
    group_model_error: bool = True
    keep_within: float = 4.0

    def __post_init__(self) -> None:
        if isinstance(self.max_leaks, bool) or self.max_leaks not in (1, 2):
            raise InputError(describe("max_leaks", self.max_leaks, "1 or 2"))
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("max_leaks", *_SWITCHES):
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(describe(f"localisation setting {f.name}", value, "a number"))
            if not np.isfinite(value) or value < 0:
                raise InputError(
                    describe(f"localisation setting {f.name}", value, "a finite number >= 0")
                )
        for name in _SWITCHES:
            if not isinstance(getattr(self, name), bool):
                raise InputError(describe(name, getattr(self, name), [True, False]))
        if 0 < self.keep_within < 1:
            raise InputError(
                describe("localisation setting keep_within", self.keep_within, "0 (off) or >= 1")
            )

    def to_dict(self) -> dict[str, float | int | bool]:
        """JSON-compatible form, with the keys of the ``.pnref`` file.

        Examples
        --------
        >>> LocalisationSettings(min_mass_flow=1e-4).to_dict()["min_flow"]
        0.0001
        """
        return {_FILE_KEYS.get(name, name): value for name, value in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, object]) -> LocalisationSettings:
        """Inverse of :meth:`to_dict`; unknown keys are an error."""
        known = {_FILE_KEYS.get(f.name, f.name) for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise InputError(describe("localisation settings", unknown, sorted(known)))
        attribute = {key: name for name, key in _FILE_KEYS.items()}
        data = {attribute.get(key, key): value for key, value in data.items()}
        # settings added later take, for references saved before, the behaviour
        # those references were built with
        before = {
            "imitation_z": 0.0,
            "probes": 0,
            "group_checks": 3,
            "min_leak_confidence": 0.0,
            "first_leak_gain": 1.0,
            "group_model_error": False,
            "keep_within": 0.0,
        }
        return cls(**{**before, **data})  # type: ignore[arg-type]


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
    """

    leaks: tuple[SizedLocation, ...]
    rss_null: float
    rss: float
    dof: int
    explained: float
    alternatives: tuple[Explanation, ...] = ()
    checked_by_simulation: bool = False


def _signature_fits(
    model: WhitenedEffects, n_loc: int, max_leaks: int, min_flow: float, rss_null: float
) -> tuple[Fits, Best]:
    """Fits of every set of one or two locations, and the best of each size."""
    best: Best = {0: ((), np.zeros(0), rss_null)}
    fits: Fits = {}
    for k in range(1, min(max_leaks, n_loc) + 1):
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
) -> None:
    """Refit the best additive pairs with their bilinear interaction (in place)."""
    coupling = effects.pair_coupling()
    if coupling is None or 2 not in best:
        return
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
            if rss < best[2][2]:
                best[2] = (sub, fits[sub][0], rss)


def _check_by_simulation(
    target: FloatArray,
    model: WhitenedEffects,
    fits: Fits,
    best: Best,
    chosen: int,
    simulate: SimulatedEffect,
    n_loc: int,
    dof: int,
    settings: LocalisationSettings,
    threads: int = 1,
) -> tuple[Fits, Best, int] | None:
    """Simulated explanations and the choice among them, or None if none ran."""
    pairs_too = settings.max_leaks > 1
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
    sim_fits: Fits = {sub: (fit.sizes, fit.rss) for sub, fit in checked.items()}
    sim_best: Best = {0: best[0]}
    for cand, (cand_sizes, cand_rss) in sim_fits.items():
        k = len(cand)
        if (
            k <= settings.max_leaks
            and np.all(cand_sizes >= settings.min_mass_flow)
            and (k not in sim_best or cand_rss < sim_best[k][2])
        ):
            sim_best[k] = (cand, cand_sizes, cand_rss)
    # a second leak the signatures did not ask for must explain much more: the
    # simulated residual also holds the run's own random conditions, which a small
    # extra leak can partly absorb
    gain = settings.min_relative_gain
    if chosen <= 1:
        gain = max(gain, settings.added_leak_gain)
    count = choose_leak_count(
        sim_best, dof, min(settings.max_leaks, n_loc), gain, settings.first_leak_gain
    )
    return sim_fits, sim_best, count


def _slopes(model: WhitenedEffects) -> Callable[[Subset, FloatArray], FloatArray]:
    """The signature model's derivative of the whitened effect of a subset by size."""

    def slopes(subset: Subset, sizes: FloatArray) -> FloatArray:
        return np.column_stack(
            [model.derivative(loc, float(x)) for loc, x in zip(subset, sizes, strict=True)]
        )

    return slopes


def _simulate_group_competitors(
    target: FloatArray,
    model: WhitenedEffects,
    fits: Fits,
    subset: Subset,
    sizes: FloatArray,
    simulate: SimulatedEffect,
    n_loc: int,
    checks: int,
    threads: int = 1,
) -> None:
    """Size by simulation the locations the signatures rank best in each slot (in place).

    Every competitor is sized to the end: it starts from the size of the leak it
    replaces, often far from its own: in development runs, one whose starting
    residual was 42 times the chosen pair's ended as good as it, so stopping such a
    competitor early would have lost it.
    """
    trials: dict[Subset, FloatArray] = {}
    for slot, loc in enumerate(subset):
        others = tuple(x for x in subset if x != loc)
        ranked = sorted(
            (model.fit(tuple(sorted((*others, alt))))[1], alt)
            for alt in range(n_loc)
            if alt not in subset
        )
        for _, alt in ranked[:checks]:
            trial = tuple(sorted((*others, alt)))
            if trial in fits or trial in trials:
                continue
            trials[trial] = np.array(
                [sizes[subset.index(i)] if i in others else sizes[slot] for i in trial]
            )
    for trial, fit in refine_all(trials, target, simulate, model.size_cap, threads=threads).items():
        fits[trial] = (fit.sizes, fit.rss)


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
    is usually fitted, and the other way round). Returns the location and the size it
    would need [kg/s], or None.
    """
    if len(subset) != 2 or SUPPLY not in locations:
        return None
    supply = locations.index(SUPPLY)
    loc = subset[slot]
    other = subset[1 - slot]
    if same_actuator_pair(locations, subset) and slot == int(np.argmin(sizes)):
        candidate = supply
    elif loc == supply and locations[other].other_line() in locations:
        candidate = locations.index(locations[other].other_line())
    else:
        return None
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
    obs = np.asarray(observed, dtype=np.float64)
    if obs.shape != (signatures.n_features,):
        raise InputError(
            describe("shape of observed feature change", obs.shape, [(signatures.n_features,)])
        )
    if not np.all(np.isfinite(obs)):
        raise InputError(describe("observed feature change", "NaN or infinite", "finite"))
    locations = effects.locations
    n_loc = len(locations)
    target = whiten(obs)[0]
    model = WhitenedEffects(
        signatures.sizes, signatures.deltas, whiten, target, settings.max_extrapolation
    )
    rss_null = float(target @ target)
    dof = int(target.size)
    fits, best = _signature_fits(model, n_loc, settings.max_leaks, settings.min_mass_flow, rss_null)
    _refit_pairs_with_interaction(effects, model, whiten, fits, best, settings)
    chosen = choose_leak_count(
        best,
        dof,
        min(settings.max_leaks, n_loc),
        settings.min_relative_gain,
        settings.first_leak_gain,
    )
    simulate: SimulatedEffect | None = None
    if settings.simulate_explanations and effects.can_simulate:

        def simulate(leaks: Mapping[int, float]) -> FloatArray | None:
            change = effects.simulate(leaks)
            return None if change is None else np.asarray(whiten(change)[0], dtype=np.float64)

    simulated = False
    misfit = best[chosen][2] / max(dof, 1)
    if (
        simulate is not None
        and chosen > 0
        and misfit > settings.misfit_ratio
        and (chosen > 1 or misfit > settings.severe_misfit_ratio)
    ):
        checked = _check_by_simulation(
            target, model, fits, best, chosen, simulate, n_loc, dof, settings, effects.threads
        )
        if checked is not None:
            fits, best, chosen = checked
            simulated = True
    subset, coef, rss = best[chosen]
    if simulated and simulate is not None:
        # only simulated explanations are compared: check the alternatives the
        # signature model ranks best in each slot
        _simulate_group_competitors(
            target,
            model,
            fits,
            subset,
            coef,
            simulate,
            n_loc,
            settings.group_checks,
            effects.threads,
        )
    else:
        for loc in subset:
            others = tuple(x for x in subset if x != loc)
            for alt in range(n_loc):
                if alt not in others:
                    trial = tuple(sorted((*others, alt)))
                    fits.setdefault(trial, model.fit(trial))
    s2 = max(1.0, rss / max(dof - len(subset), 1))
    explained = 0.0 if rss_null <= 0 else max(0.0, 1.0 - rss / rss_null)
    leaks = [
        _sized_location(slot, subset, coef, fits, model, locations, s2, explained, settings)
        for slot in range(len(subset))
    ]
    leaks.sort(key=lambda leak: -leak.mass_flow)
    explanations = alternative_explanations(
        fits,
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
        coef,
        model,
        rss,
        settings.min_mass_flow,
        settings.both_lines_max_ratio,
        settings.max_alternatives,
    ):
        if all(set(both_lines.locations) != set(e.locations) for e in explanations):
            explanations.append(both_lines)
    return Localisation(
        tuple(leaks), rss_null, float(rss), dof, float(explained), tuple(explanations), simulated
    )
