"""Diagnose a run against a reference: detect, locate, size and cost leaks.

1. **Detect** (section 5.3.2 and 4.4.1): the per-cycle statistic of
   :class:`~pneufdd.diagnosis.detection.statistic.CycleDistanceDetector`, decided over the whole
   run (mean of its cycles); the band method of eq. 5.21 is reported alongside.
2. **Locate and size** (sections 5.3.1.2-5.3.1.5, eqs. 5.23-5.24): the run's mean
   feature change is decomposed into non-negative leak effects
   (:func:`~pneufdd.diagnosis.localisation.search.locate`) of the reference's
   :class:`~pneufdd.diagnosis.effects.model.LeakEffectModel`.
3. **Cost** (eq. 1.1): :mod:`pneufdd.diagnosis.cost`, one
   :class:`~pneufdd.diagnosis.findings.LeakFinding` per leak in the
   :class:`~pneufdd.diagnosis.findings.Diagnosis`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.cost import CostSettings, LeakTotals
from pneufdd.diagnosis.costing import cost_localisation
from pneufdd.diagnosis.detection.residuals import supply_check
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects, Whitener
from pneufdd.diagnosis.fault_choice import (
    FAULT_MODEL_ERROR,
    judge_faults,
    leak_findings,
    needs_fault_check,
)
from pneufdd.diagnosis.findings import Diagnosis, Finding, LeakFinding
from pneufdd.diagnosis.localisation.model_choice import Explanation
from pneufdd.diagnosis.localisation.remainder import HiddenLeak, Remainder, hidden_leak_bounds
from pneufdd.diagnosis.localisation.search import (
    Localisation,
    LocalisationSettings,
    SizedLocation,
    locate,
)
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.diagnosis.reference.sensor_sets import sensor_set_report
from pneufdd.errors import ChannelError, InputError, MachineError, describe
from pneufdd.features.step_table import StepTable
from pneufdd.parallel import resolve_threads
from pneufdd.physics.units import kg_s_to_slpm

if TYPE_CHECKING:
    pass

__all__ = [
    "check_compatible",
    "diagnose",
    "imitated_size",
    "run_whitener",
    "undetected_remainder",
    "whitener",
]


_LEAK_ONLY_NOTES = (
    "leak detected but no combination",
    "the leak model explains only",
    "more leaks may be present",
)
"""Notes that read the deviation as a leak, left out when another fault explains it."""


def check_compatible(reference: ReferenceModel, run: StepTable, where: str = "run") -> StepTable:
    """Check that ``run`` comes from the reference's machine and has its channels.

    Returns
    -------
    StepTable
        ``run`` restricted to the reference's analog channels.

    Raises
    ------
    MachineError
        If the machines differ.
    ChannelError
        If the run lacks a channel of the reference's sensor set.
    InputError
        If the number of steps differs or there is no complete cycle.
    """
    if run.machine != reference.machine:
        raise MachineError(
            describe(f"machine of {where}", run.machine, [reference.machine])
            + " (the reference was built for another machine)"
        )
    missing = [c for c in reference.channels if c not in run.channels]
    if missing:
        raise ChannelError(
            f"{where} lacks channel(s) {missing} of the reference's sensor set "
            f"{list(reference.channels)}; it has {list(run.channels)}"
        )
    if run.n_steps != reference.n_steps:
        raise InputError(describe(f"steps per cycle in {where}", run.n_steps, [reference.n_steps]))
    if run.n_cycles < 1:
        raise InputError(describe(f"complete cycles in {where}", 0, ">= 1"))
    return run.select(list(reference.channels))


def whitener(
    reference: ReferenceModel,
    n_cycles: int,
    magnitude: FloatArray | None = None,
    leaks: Sequence[tuple[int, float]] = (),
    model_error_floor: float = 0.0,
    predicted_cycles: int = 0,
) -> Whitener:
    r"""Weighting of a run's mean feature change: unit variance per residual component.

    The change :math:`\Delta x` a correct leak model leaves unexplained has three
    parts; the weighting divides by their covariance :math:`C` (``W^T W = C^{-1}``):

    - noise: the mean of ``m`` run cycles against the mean of the reference's ``n``
      cycles, :math:`\sigma_j^2 (1/m + 1/n)` with :math:`\sigma_j` the reference
      spread (floored at the sensor resolution);
    - the model error of the signatures on a real machine, sampled on ``K``
      plausible plants (:attr:`SignatureSet.plant_deviations`): for each leak
      ``(location, size)`` of ``leaks`` the plants' deviations :math:`d^{(k)}` from
      its signature, coherent across features;
    - a floor of independent error per feature, ``model_error_floor`` of the effect's
      size :math:`|e_j|` (``magnitude`` [feature unit]):

    .. math::

        C = \operatorname{diag}\left(\sigma_j^2 \left(\frac{1}{m} + \frac{1}{n}\right)
            + (\rho\, e_j)^2\right)
            + \sum_{l} \frac{1}{K} \sum_k d^{(k)}_l d^{(k)T}_l

    Then the house-air fluctuation directions (section 4.4.1) are projected out in the
    weighted space (free nuisance amplitudes). Without ``leaks`` and ``magnitude`` this
    is the detector's statistic scaled to unit noise.

    With ``predicted_cycles`` :math:`c > 0` the noise of a prediction simulated over
    :math:`c` cycles is added, :math:`\sigma_j^2 / c`: a fault that shifts the timing
    of a step decorrelates the twin's sensor noise from its baseline's, so its
    simulated change is no better known than that (the fault hypotheses,
    :mod:`pneufdd.diagnosis.fault_choice`).
    """
    det = reference.detector
    sigma = np.asarray(det.scale_, dtype=np.float64)
    variance = sigma**2 * (1.0 / n_cycles + 1.0 / reference.n_cycles)
    if predicted_cycles > 0:
        variance = variance + sigma**2 / predicted_cycles
    if magnitude is not None:
        variance = variance + (model_error_floor * magnitude) ** 2
    sig = reference.signatures
    blocks = []
    for location, size in leaks:
        deviations = None if sig is None else sig.deviations(location, size)
        if deviations is not None:
            blocks.append(deviations.T / np.sqrt(deviations.shape[0]))
    columns = np.hstack(blocks) if blocks else np.zeros((sigma.size, 0))
    weight = 1.0 / np.sqrt(variance)
    # (A + B B^T)^(-1/2) applied as (I + B~ B~^T)^(-1/2) A^(-1/2), B~ = A^(-1/2) B
    basis_b, singular, _ = np.linalg.svd(columns * weight[:, None], full_matrices=False)
    shrink = 1.0 / np.sqrt(1.0 + singular**2) - 1.0

    def weighted(delta: FloatArray) -> FloatArray:
        r = np.atleast_2d(delta) * weight
        return np.asarray(r + ((r @ basis_b) * shrink) @ basis_b.T)

    nuisance = weighted(det.components_ * sigma).T  # fluctuation directions, weighted
    basis = np.linalg.qr(nuisance)[0] if nuisance.size else nuisance

    def whiten(delta: FloatArray) -> FloatArray:
        r = weighted(delta)
        return np.asarray(r - (r @ basis) @ basis.T)

    return whiten


def undetected_remainder(
    reference: ReferenceModel, observed: FloatArray, n_cycles: int
) -> Remainder | None:
    """For a run without a detected leak: the largest leak each location could hide.

    The run's change under the noise weighting (:func:`whitener`), no leak fitted:
    :func:`~pneufdd.diagnosis.localisation.remainder.hidden_leak_bounds` with the
    residual scale of the change itself (at least 1). None without signatures.
    """
    sig = reference.signatures
    if sig is None:
        return None
    whiten = whitener(reference, n_cycles)
    target = np.asarray(whiten(observed)[0], dtype=np.float64)
    model = WhitenedEffects(
        sig.sizes, sig.deltas, whiten, target, reference.localisation.max_extrapolation
    )
    s2 = max(1.0, float(target @ target) / max(target.size, 1))
    unexplained = max(0.0, float(target @ target) - target.size)
    bounds, cap = hidden_leak_bounds(model, target, None, (), s2, unexplained=unexplained)
    hidden = sorted(
        (HiddenLeak(loc, float(bounds[i]), bool(cap[i])) for i, loc in enumerate(sig.locations)),
        key=lambda leak: -leak.mass_flow,
    )
    return Remainder(0.0, tuple(hidden))


def run_whitener(
    reference: ReferenceModel,
    effects: LeakEffectModel,
    observed: FloatArray,
    n_cycles: int,
    settings: LocalisationSettings,
) -> Whitener:
    """The weighting of one run's change, with the model error of the leaks behind it.

    Without plausible-plant deviations in the signatures: noise only. With them, the
    model error belongs to the leaks that may be behind the change: first the best
    explanation under noise-only weights, then the weighting with the model error of
    those leaks (what plausible plants do differently from the twin) and a floor
    relative to the larger of the predicted and the observed change (a feature the
    twin expects to move but the plant barely moves is model error too, not evidence
    at noise level).

    With :attr:`LocalisationSettings.group_model_error` the leaks are every location in
    the first explanation's ambiguity groups, each at the size it would need, not only
    its chosen leaks: were it the chosen leak's alone, a competitor would be judged
    against another location's model error. A leak on a line held pressurised all but
    one step (a 5/2 monostable valve's B line) differs from a supply leak only in that
    step, where a drafted cylinder's dynamics are least known; weighted with the supply
    leak's model error, that step decided against the line (docs/diagnosis.md).
    """
    chosen, grouped = _weightings(reference, effects, observed, n_cycles, settings)
    return grouped if settings.group_model_error else chosen


def _weightings(
    reference: ReferenceModel,
    effects: LeakEffectModel,
    observed: FloatArray,
    n_cycles: int,
    settings: LocalisationSettings,
) -> tuple[Whitener, Whitener]:
    """The run's weighting with the chosen leaks' and with their groups' model error."""
    whiten = whitener(reference, n_cycles)
    if not effects.signatures.n_plants:
        return whiten, whiten
    first = locate(observed, effects, whiten, replace(settings, simulate_explanations=False))
    leaks = [(effects.locations.index(leak.location), leak.mass_flow) for leak in first.leaks]
    groups = [
        (effects.locations.index(member), size)
        for leak in first.leaks
        for member, size in zip(leak.ambiguity_group, leak.group_mass_flows, strict=True)
    ]
    predicted = effects.change(dict(leaks)) if leaks else np.zeros_like(observed)
    magnitude = np.maximum(np.abs(observed), np.abs(predicted))
    floor = settings.model_error_floor
    return (
        whitener(reference, n_cycles, magnitude, leaks, floor),
        whitener(reference, n_cycles, magnitude, groups, floor),
    )


def _locate_weighted(
    reference: ReferenceModel,
    effects: LeakEffectModel,
    observed: FloatArray,
    n_cycles: int,
    settings: LocalisationSettings,
) -> tuple[Localisation, Whitener]:
    """The leaks behind a run, and the weighting they were found with.

    Weighted with the model error of every location the first fit could not tell
    apart (:func:`run_whitener`), a leak is not ruled out where the twin is unsure of
    its own effect. That weighting also holds the contenders' model error when a
    *second* leak is judged, which no hypothesis with that second leak carries; it can
    hide a small true second leak. So when it finds one leak, the run is located again
    with the chosen leaks' model error alone, and two leaks found so are kept unless
    both lie in the one leak's ambiguity group (one leak split between locations the
    run cannot tell apart: a lane pusher's B-line leak reported as 28.8 SLPM there and
    32.3 SLPM at the supply).
    """
    chosen, grouped = _weightings(reference, effects, observed, n_cycles, settings)

    def imitation(larger: Sequence[tuple[int, float]], smaller: tuple[int, float]) -> float | None:
        return imitated_size(reference, effects, n_cycles, larger, smaller)

    if not settings.group_model_error or grouped is chosen:
        return locate(observed, effects, chosen, settings, imitation), chosen
    result = locate(observed, effects, grouped, settings, imitation)
    if len(result.leaks) != 1:
        return result, grouped
    apart = locate(observed, effects, chosen, settings, imitation)
    group = set(result.leaks[0].ambiguity_group)
    if len(apart.leaks) >= 2 and not all(leak.location in group for leak in apart.leaks):
        return apart, chosen
    return result, grouped


def imitated_size(
    reference: ReferenceModel,
    effects: LeakEffectModel,
    n_cycles: int,
    larger: tuple[int, float] | Sequence[tuple[int, float]],
    smaller: tuple[int, float],
) -> float | None:
    r"""How large a second leak the model error of the first imitates [kg/s].

    A real machine's effect of the larger leak ``(location index, size)`` differs from
    its signature; on plausible plant ``k`` by :math:`d^{(k)}`
    (:attr:`SignatureSet.plant_deviations`). Of several larger leaks (a sequence of
    them) the deviations add, plant by plant. Fitting the smaller leak's signature
    :math:`e` (at its fitted size :math:`f`, linearised) to that deviation alone gives
    the size :math:`f_k = f\, \langle W d^{(k)}, W e \rangle / \lVert W e \rVert^2`
    under the noise weighting :math:`W` of the run (:func:`whitener` without model
    error). The RMS of :math:`f_k` over the plants is what a phantom second leak at that
    location may reach on a machine with only the larger leak.

    Returns
    -------
    float or None
        RMS of :math:`f_k` [kg/s]; None without plausible-plant deviations.
    """
    sig = effects.signatures
    leaks: list[tuple[int, float]] = (
        [larger]  # type: ignore[list-item]
        if isinstance(larger[0], int | np.integer)
        else list(larger)  # type: ignore[arg-type]
    )
    parts = [sig.deviations(int(loc), float(size)) for loc, size in leaks]
    if any(part is None for part in parts) or not parts or smaller[1] <= 0.0:
        return None
    deviations = np.sum([part for part in parts if part is not None], axis=0)
    weigh = whitener(reference, n_cycles)
    direction = weigh(effects.effect(smaller[0], smaller[1]))[0]
    norm = float(direction @ direction)
    if norm <= 0.0:
        return None
    sizes = smaller[1] * (weigh(deviations) @ direction) / norm
    return float(np.sqrt(np.mean(sizes**2)))


def _imitated_leak(
    reference: ReferenceModel,
    effects: LeakEffectModel,
    n_cycles: int,
    settings: LocalisationSettings,
    localisation: Localisation,
) -> tuple[SizedLocation, str] | None:
    """The smallest of several leaks and why it is not reported, when it is no larger
    than the other leaks' model error imitates (:attr:`LocalisationSettings.imitation_z`);
    else None."""
    found = localisation.leaks
    if len(found) < 2 or settings.imitation_z <= 0.0 or localisation.checked_by_simulation:
        return None
    index = effects.locations.index
    small = min(found, key=lambda leak: leak.mass_flow)
    larger = [leak for leak in found if leak is not small]
    imitated = imitated_size(
        reference,
        effects,
        n_cycles,
        [(index(leak.location), leak.mass_flow) for leak in larger],
        (index(small.location), small.mass_flow),
    )
    if imitated is None or small.mass_flow > settings.imitation_z * imitated:
        return None
    names = ", ".join(str(leak.location) for leak in larger)
    other = "leak" if len(larger) == 1 else "leaks"
    fewer = "one leak is" if len(found) == 2 else f"{len(found) - 1} leaks are"
    kind = "pair" if len(found) == 2 else "larger explanation"
    return small, (
        f"a {'second' if len(found) == 2 else 'further'} leak at {small.location} of "
        f"{kg_s_to_slpm(small.mass_flow):.1f} SLPM would lower the residual, but the model "
        f"error of the {other} at {names} alone imitates one of "
        f"{kg_s_to_slpm(imitated):.1f} SLPM there (RMS over plausible plants): {fewer} "
        f"reported and the {kind} is listed as an alternative"
    )


def _unconfident_leak(
    settings: LocalisationSettings, localisation: Localisation
) -> tuple[SizedLocation, str] | None:
    """The least likely of several leaks and why it is not reported, when it is less
    likely than :attr:`LocalisationSettings.min_leak_confidence` to lie in its
    ambiguity group (the residual chose it, but the explanations without it hold the
    weight); else None."""
    found = localisation.leaks
    if len(found) < 2:
        return None
    weakest = min(found, key=lambda leak: leak.confidence)
    if weakest.confidence >= settings.min_leak_confidence:
        return None
    fewer = "one leak is" if len(found) == 2 else f"{len(found) - 1} leaks are"
    kind = "pair" if len(found) == 2 else "larger explanation"
    return weakest, (
        f"a {'second' if len(found) == 2 else 'further'} leak at {weakest.location} of "
        f"{kg_s_to_slpm(weakest.mass_flow):.1f} SLPM would lower the residual, but its "
        f"confidence ({weakest.confidence:.2f}) is below "
        f"{settings.min_leak_confidence:.2f}: {fewer} reported and the {kind} is listed "
        "as an alternative"
    )


def _drop_doubtful_leaks(
    reference: ReferenceModel,
    effects: LeakEffectModel,
    observed: FloatArray,
    n_cycles: int,
    whiten: Whitener,
    settings: LocalisationSettings,
    localisation: Localisation,
    notes: list[str],
) -> Localisation:
    """One leak fewer while the smallest is what the others' model error imitates, or
    one is less likely than not; each larger explanation becomes the first alternative
    and ``notes`` say why. ``localisation`` itself when no leak is doubtful."""
    for _ in range(len(localisation.leaks)):
        doubt = _imitated_leak(
            reference, effects, n_cycles, settings, localisation
        ) or _unconfident_leak(settings, localisation)
        if doubt is None:
            return localisation
        fewer = _fewer_leaks_instead(
            observed, effects, whiten, settings, localisation, notes, *doubt
        )
        if fewer is localisation:
            return localisation
        localisation = fewer
    return localisation


def _fewer_leaks_instead(
    observed: FloatArray,
    effects: LeakEffectModel,
    whiten: Whitener,
    settings: LocalisationSettings,
    localisation: Localisation,
    notes: list[str],
    doubtful: SizedLocation,
    why: str,
) -> Localisation:
    """The localisation with one leak fewer, the leaks of ``localisation`` as its first
    alternative; ``localisation`` itself when no fewer leaks explain the run. Its
    remainder says that the doubtful leak may be present."""
    n = len(localisation.leaks)
    fewer = locate(observed, effects, whiten, replace(settings, max_leaks=n - 1))
    if not 1 <= len(fewer.leaks) <= n - 1:
        return localisation
    larger = Explanation(
        tuple(leak.location for leak in localisation.leaks),
        tuple(leak.mass_flow for leak in localisation.leaks),
        localisation.rss,
    )
    notes.append(why)
    others = tuple(a for a in fewer.alternatives if set(a.locations) != set(larger.locations))
    remainder = fewer.remainder
    if remainder is not None:
        kept = tuple(r for r in remainder.reasons if not r.startswith("the search stopped"))
        reason = (
            f"a leak at {doubtful.location} of {kg_s_to_slpm(doubtful.mass_flow):.1f} SLPM "
            "lowers the residual but is not reported (see the notes)"
        )
        remainder = replace(remainder, more_leaks_possible=True, reasons=(reason, *kept))
    return replace(
        fewer,
        alternatives=(larger, *others)[: max(settings.max_alternatives, 1)],
        remainder=remainder,
    )


def _locate_and_cost(
    reference: ReferenceModel,
    observed: FloatArray,
    n_cycles: int,
    settings: CostSettings,
    localisation_settings: LocalisationSettings,
    notes: list[str],
    threads: int = 1,
) -> tuple[
    Localisation | None,
    list[LeakFinding],
    float,
    LeakTotals | None,
    tuple[int, ...],
    LeakEffectModel | None,
]:
    """Location, size and cost of the leaks behind a detected deviation; their
    totals with intervals, the order to repair them, and the effect model they were
    located with (None without signatures)."""
    effects = reference.leak_effects(threads=threads)
    if effects is None:
        notes.append(
            "leak detected but the reference holds no leak signatures: location and size "
            "cannot be estimated (rebuild the reference with signatures; recordings "
            "without a machine description need --machine DESCRIPTION)"
        )
        return None, [], 0.0, None, (), None
    sig = effects.signatures
    localisation, whiten = _locate_weighted(
        reference, effects, observed, n_cycles, localisation_settings
    )
    localisation = _drop_doubtful_leaks(
        reference, effects, observed, n_cycles, whiten, localisation_settings, localisation, notes
    )
    if not localisation.leaks:
        notes.append("leak detected but no combination of leak signatures explains it")
    if localisation.checked_by_simulation:
        notes.append(
            "the leak signatures alone did not explain this run (leaks that interact, "
            "typically two large ones): locations and sizes were checked by simulating "
            "the best explanations with the digital twin"
        )
    found = localisation.leaks
    leaks, total, totals, order = cost_localisation(reference, sig, localisation, settings)
    if found and sig.mean_flow is None:
        notes.append(
            "the reference holds no mean leak flows per cycle: costs assume the leaks blow "
            "continuously at their nominal flow (an upper bound for leaks on actuator "
            "lines; rebuild the reference with signatures)"
        )
    if localisation.explained < 0.5:
        notes.append(
            f"the leak model explains only {100 * localisation.explained:.0f} % of the "
            "deviation: another fault (or a leak outside the candidate locations) may be "
            "present"
        )
    return localisation, leaks, total, totals, order, effects


def diagnose(
    reference: ReferenceModel,
    run: StepTable,
    settings: CostSettings | None = None,
    localisation: LocalisationSettings | None = None,
    threads: int | None = None,
    faults: bool = True,
) -> Diagnosis:
    """Detect, locate, size and cost leaks in ``run`` against ``reference``; name other
    faults that explain it better.

    Parameters
    ----------
    reference : ReferenceModel
        Leak-free reference of the same machine and sensor set.
    run : StepTable
        Complete cycles of the run to judge (10 make a run in the acceptance tests).
    settings : CostSettings, optional
        Economic inputs of eq. 1.1.
    localisation : LocalisationSettings, optional
        Overrides the reference's localisation settings (e.g. ``max_leaks``, or
        ``simulate_explanations=False`` to skip the check by simulation of the best
        explanations when the signatures do not explain the run).
    threads : int, optional
        Threads that run the check by simulation's independent simulations at once
        (the result does not depend on it). Default: the cores this process may use
        (:func:`pneufdd.parallel.available_cores`); 1 where several diagnoses already
        share the cores (a campaign's or a batch's workers).
    faults : bool
        Test faults other than leaks with the twin when the leaks do not explain a
        detected run well (:mod:`pneufdd.diagnosis.fault_choice`); False: leaks only.

    Returns
    -------
    Diagnosis
    """
    n_threads = resolve_threads(threads)
    settings = settings or CostSettings()
    table = check_compatible(reference, run)
    X = table.features()
    det = reference.detector
    scores = det.score_samples(X)
    m = scores.size
    run_score = det.run_score(scores)
    run_threshold = det.run_threshold(m)
    detected = run_score > run_threshold
    band = reference.band_detector()
    band_fraction = np.zeros(0)
    band_alarms = 0
    if (
        band is not None
        and table.traces is not None
        and table.traces[0].size == band.n_features_in_
    ):
        band_fraction = band.score_samples(table.traces.reshape(m, -1))
        band_alarms = int(np.sum(band_fraction > band.alarm_fraction))
    observed = np.asarray(np.mean(X, axis=0) - det.mean_, dtype=np.float64)
    notes: list[str] = []
    found: Localisation | None = None
    leaks: list[LeakFinding] = []
    findings: list[Finding] = []
    tested = False
    total = 0.0
    totals: LeakTotals | None = None
    order: tuple[int, ...] = ()
    if detected:
        chosen = localisation or reference.localisation
        found, leaks, total, totals, order, located = _locate_and_cost(
            reference, observed, m, settings, chosen, notes, n_threads
        )
        remainder = None if found is None else found.remainder
        if remainder is not None and remainder.more_leaks_possible:
            notes.append("more leaks may be present: " + "; ".join(remainder.reasons))
        findings = leak_findings(leaks, reference.channels)
        noise = np.asarray(det.scale_) * math.sqrt(1.0 / m + 1.0 / reference.n_cycles)
        if (
            faults
            and located is not None
            and needs_fault_check(
                found, located, observed, noise, reference.feature_names, reference.channels
            )
        ):

            def weigh(magnitude: FloatArray, sized: Sequence[tuple[int, float]]) -> Whitener:
                return whitener(reference, m, magnitude, sized, FAULT_MODEL_ERROR, located.cycles)

            verdict = judge_faults(
                located,
                observed,
                weigh,
                found,
                leaks,
                chosen,
                notes,
                reference.channels,
                n_threads,
                reference.fault_screens,
            )
            findings, tested = verdict.findings, verdict.checked
            if verdict.leaks_replaced:
                leaks, total, totals, order, remainder = [], 0.0, None, (), None
            if findings and findings[0].fault_type != "leak":
                notes[:] = [n for n in notes if not n.startswith(_LEAK_ONLY_NOTES)]
                if not leaks:  # the leaks' remainder reads the fault as hidden leaks
                    remainder = None
            elif tested and not findings:
                notes[:] = [n for n in notes if not n.startswith(_LEAK_ONLY_NOTES[0])]
                notes.append(
                    "deviation detected, but no combination of leak signatures and no fault "
                    "of the catalogue (docs/faults.md) explains it: a fault outside the "
                    "catalogue, a change of the machine or a reference that does not cover "
                    "this operation"
                )
    else:
        remainder = undetected_remainder(reference, observed, m)
    return Diagnosis(
        detected=bool(detected),
        cycles_analyzed=int(m),
        cycle_scores=scores,
        cycle_threshold=float(det.threshold_),
        run_score=run_score,
        run_threshold=float(run_threshold),
        p_value=det.run_p_value(X),
        reference_false_alarm_rate=float(det.reference_false_alarm_rate_),
        band_fraction=band_fraction,
        band_alarms=band_alarms,
        leaks=leaks,
        total_annual_cost=total,
        localisation=found,
        observed_change=observed,
        settings=settings,
        notes=notes,
        cycles_skipped=tuple(run.skipped_cycles),
        gaps_repaired=int(run.repaired_gaps),
        supply=supply_check(reference.feature_names, reference.features, X),
        sensor_set=sensor_set_report(reference.channels),
        totals=totals,
        repair_order=order,
        remainder=remainder,
        findings=findings,
        faults_tested=tested,
    )
