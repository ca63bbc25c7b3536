"""Leaks or another fault: which explanation of a deviating run is reported (issue 34).

:func:`pneufdd.diagnosis.engine.diagnose` explains a deviating run by leaks first. When
that explanation leaves a large share of the deviation unexplained, or finds no leak,
or the step durations move beyond what the leaks it found explain, the faults of the
catalogue are fitted with the twin
(:func:`~pneufdd.diagnosis.localisation.faults.fit_faults`) and every explanation is
ranked by the information criterion of the leak search
(:func:`~pneufdd.diagnosis.localisation.model_choice.choose_leak_count`): the whitened
residual plus ``2 ln(dof) s^2`` per fitted size, ``s^2 = max(1, rss_min / (dof - 1))``.

- A fault is an explanation at all only when it passes that criterion against no
  explanation (it lowers the residual by more than the penalty of its one size).
- The best explanation is reported. Explanations whose Akaike-type weight
  ``exp(-(IC - IC_min) / 2 s^2)`` is at least ``group_ratio`` of the best, or whose
  residual is within ``1 + relative_tolerance`` of it (the leak search's rules), join
  its ambiguity group, across types; the confidence is the group's share of the
  weight of every explanation tried.
- When a fault other than a leak is reported, the leaks are not (no invented leaks):
  the leak explanation appears in the fault's ambiguity group when it fits about as
  well, and a note says what the leaks would have been.
"""

from __future__ import annotations

import math
from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import dataclass

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.piecewise import Whitener
from pneufdd.diagnosis.findings import Finding, GroupMember, LeakFinding
from pneufdd.diagnosis.localisation.faults import (
    FaultFit,
    cycle_time_change,
    fault_hypotheses,
    fit_faults,
    largest_step_change,
)
from pneufdd.diagnosis.localisation.search import Localisation, LocalisationSettings
from pneufdd.physics.units import kg_s_to_slpm

__all__ = [
    "DURATION_BAND",
    "FAULT_MODEL_ERROR",
    "UNEXPLAINED_SHARE",
    "FaultVerdict",
    "LeakWeighing",
    "judge_faults",
    "leak_findings",
    "needs_fault_check",
]

UNEXPLAINED_SHARE = 0.3
"""The faults are tested when the leak explanation leaves more than this share of the
whitened deviation unexplained (``1 - explained``) [-]."""

DURATION_BAND = 4.0
"""...or when a step's duration moves beyond what the leaks explain by more than this
many times its noise and model-error band [-]."""

DURATION_FLOOR_S = 0.005
"""Smallest duration band: the PLC's 100 Hz signals quantise a step [s]."""

DURATION_RELATIVE = 0.25
"""Model-error part of the duration band: this share of the larger of the duration's
observed and predicted change (:data:`FAULT_MODEL_ERROR`) [-]."""


@dataclass(frozen=True)
class FaultVerdict:
    """The findings of a run and whether a fault replaced the leaks.

    Attributes
    ----------
    findings : list of Finding
        What is wrong, best first.
    leaks_replaced : bool
        True when a fault other than a leak explains the run better than the leaks,
        which are then not reported.
    checked : bool
        True when the fault hypotheses were fitted.
    fits : tuple of FaultFit
        The fitted fault hypotheses, best first (empty when not checked).
    """

    findings: list[Finding]
    leaks_replaced: bool
    checked: bool
    fits: tuple[FaultFit, ...] = ()


def _leak_member(location: str, mass_flow: float) -> GroupMember:
    return GroupMember("leak", "leak", location, float(kg_s_to_slpm(mass_flow)), "SLPM")


def leak_findings(leaks: Sequence[LeakFinding], channels: Sequence[str] = ()) -> list[Finding]:
    """One :class:`Finding` per leak, its ambiguity group of leak locations.

    A leak on a line without a flow meter of its own (``Q_<LINE>`` not in
    ``channels``) has a spool leak to the exhaust of that line (``valve-leak-out``)
    in its group at the same size: both lose the same air from the same chamber to
    the atmosphere, sized by the same convention (flow from the nominal supply
    pressure); only a meter between the valve and the cylinder tells them apart
    (``docs/faults.md``).
    """
    out = []
    for leak in leaks:
        flows = leak.group_mass_flows or (leak.mass_flow,) * len(leak.ambiguity_group)
        group = tuple(
            _leak_member(str(loc), flow)
            for loc, flow in zip(leak.ambiguity_group, flows, strict=False)
        )
        line = str(leak.location)
        if not leak.location.is_supply and f"Q_{line}" not in channels:
            group += (GroupMember("internal-leak", "valve-leak-out", line, leak.flow_slpm, "SLPM"),)
        out.append(
            Finding(
                "leak",
                "leak",
                str(leak.location),
                leak.flow_slpm,
                "SLPM",
                group,
                leak.confidence,
                annual_cost=leak.annual_cost,
            )
        )
    return out


def needs_fault_check(
    localisation: Localisation | None,
    effects: LeakEffectModel,
    observed: FloatArray,
    noise: FloatArray,
    feature_names: Sequence[str],
    channels: Sequence[str] | None = None,
) -> bool:
    """True when the faults are worth fitting (what bounds their cost).

    When no leak explains the run, when a leak lies on a line whose air no flow meter
    sees (neither ``Q_<LINE>`` nor ``Q_In`` in ``channels``: there a leak is read from
    the strokes' timing and pressures only, which an opened meter-out throttle or a
    spool leak move alike), when the leaks leave more than
    :data:`UNEXPLAINED_SHARE` of it unexplained, or when a step's duration differs
    from what the leaks predict (the twin's change when they were checked by
    simulation, else their signature model) by more than
    :data:`DURATION_BAND` times ``max(noise, DURATION_FLOOR_S, DURATION_RELATIVE *
    max(|observed|, |predicted|))`` (``noise``: the run mean's standard deviation per
    feature): with the default 4 x 0.25, a step the leaks do not move at all, or move
    the other way.
    """
    if localisation is None or not localisation.leaks:
        return True
    if channels is not None and "Q_In" not in channels:
        unseen = [
            leak
            for leak in localisation.leaks
            if leak.location.is_supply or f"Q_{leak.location}" not in channels
        ]
        if unseen:
            return True
    if 1.0 - localisation.explained > UNEXPLAINED_SHARE:
        return True
    # what the leaks predict: the twin's change where they were checked by simulation
    # (interacting large leaks, which the signature model misreads), else the model's
    predicted, _ = _leak_change(effects, localisation)
    if predicted is None:  # no leak located (handled above)
        return True
    durations = np.array([name.startswith("duration@") for name in feature_names])
    residual = np.abs(observed - predicted)[durations]
    larger = np.maximum(np.abs(observed), np.abs(predicted))[durations]
    band = np.maximum.reduce(
        [
            noise[durations],
            np.full(int(durations.sum()), DURATION_FLOOR_S),
            DURATION_RELATIVE * larger,
        ]
    )
    return bool(np.any(residual > DURATION_BAND * band))


def _weights(ic: FloatArray, s2: float) -> FloatArray:
    return np.asarray(np.exp(-(ic - float(np.min(ic))) / (2.0 * s2)), dtype=np.float64)


LeakWeighing = Callable[[FloatArray, Sequence[tuple[int, float]]], Whitener]
"""The run's weighting for an effect magnitude [feature unit] and the leaks
``(location index, size [kg/s])`` whose plant model error it carries
(:func:`pneufdd.diagnosis.engine.whitener` with :data:`FAULT_MODEL_ERROR`)."""

FAULT_MODEL_ERROR = 0.25
"""Model-error floor of every explanation compared with faults: this share of the
larger of the observed and the explained change per feature [-].

The twin's effect of a fault on a real plant is known no better than the plant's
parameters: at plant scale 1 a throttle's Cv is drawn within +-50 %, friction and
volumes within tens of per cent (``docs/plant-variation.md``), so a fault's effect on
the plant differs from the twin's by tens of per cent; the leaks carry their sampled
model error (plausible plants) on top. An assumption (``docs/assumptions.md``)."""


def _leak_change(
    effects: LeakEffectModel, localisation: Localisation | None
) -> tuple[FloatArray | None, list[tuple[int, float]]]:
    """The leak explanation's change and its leaks ``(index, size [kg/s])``.

    The simulated change when the leaks were checked by simulation (the twin's cache
    holds it), else the signature model's; None without leaks."""
    if localisation is None or not localisation.leaks:
        return None, []
    index = effects.locations.index
    leaks = {index(leak.location): leak.mass_flow for leak in localisation.leaks}
    change = effects.simulate(leaks) if localisation.checked_by_simulation else None
    if change is None:
        change = effects.change(leaks)
    return change, list(leaks.items())


def judge_faults(
    effects: LeakEffectModel,
    observed: FloatArray,
    weigh: LeakWeighing,
    localisation: Localisation | None,
    leaks: Sequence[LeakFinding],
    settings: LocalisationSettings,
    notes: list[str],
    channels: Sequence[str] = (),
    threads: int = 1,
    cache: MutableMapping[tuple[str, str, float], FloatArray | None] | None = None,
) -> FaultVerdict:
    """Fit the fault hypotheses and choose between them and the leaks.

    Parameters
    ----------
    effects : LeakEffectModel
        The reference's twin interface (its description gives the hypotheses).
    observed : ndarray
        Mean feature change of the run [feature unit].
    weigh : callable
        The run's weighting (:data:`LeakWeighing`), the same rule for every
        explanation.
    localisation : Localisation or None
        The leak explanation (None: not located).
    leaks : sequence of LeakFinding
        The leaks it reports.
    settings : LocalisationSettings
        ``group_ratio`` and ``relative_tolerance`` of the ambiguity group.
    notes : list of str
        Appended to: what replaced the leaks, or why the faults were not tested.
    channels : sequence of str
        The reference's analog channels (:func:`leak_findings`).
    threads : int
        Simulations that run at once.
    cache : mapping, optional
        The reference's screening simulations (:attr:`ReferenceModel.fault_screens`).

    Returns
    -------
    FaultVerdict
    """
    if effects.machine is None or effects.fault_simulator is None:
        notes.append(
            "faults other than leaks were not tested: the reference has no digital twin "
            "(no machine description)"
        )
        return FaultVerdict(leak_findings(leaks, channels), False, False)
    hypotheses = fault_hypotheses(effects.machine)
    fits = fit_faults(
        observed,
        effects.simulate_fault,
        lambda magnitude: weigh(magnitude, ()),
        hypotheses,
        threads=threads,
        cache=cache,
    )
    sized = [f for f in fits if f.simulated]
    leak_change, leak_sizes = _leak_change(effects, localisation)
    # one weighting for the decision: noise, the leaks' plant model error and a floor
    # relative to the largest change any contender explains (each was sized with its own)
    changes = [f.change for f in sized] + ([] if leak_change is None else [leak_change])
    magnitude = np.max(np.abs(np.vstack([observed, *changes])), axis=0)
    whiten = weigh(magnitude, leak_sizes)

    def rss_of(change: FloatArray) -> float:
        r = np.asarray(whiten(observed - change)[0], dtype=np.float64)
        return float(r @ r)

    dof = int(observed.size)
    rss_null = rss_of(np.zeros_like(observed))
    fault_rss = [rss_of(f.change) for f in sized]
    leak_rss = math.inf if leak_change is None else rss_of(leak_change)
    k_leak = len(leaks)
    rss_min = min([leak_rss, rss_null, *fault_rss])
    s2 = max(1.0, rss_min / max(dof - 1, 1))
    penalty = 2.0 * math.log(max(dof, 2)) * s2
    # a fault must pass the criterion against no explanation, as a first leak must
    passing = [(f, r) for f, r in zip(sized, fault_rss, strict=True) if rss_null - r > penalty]
    if not passing:
        return FaultVerdict(leak_findings(leaks, channels), False, True, tuple(fits))
    candidates = [f for f, _ in passing]
    ic = np.array(
        [*(r + penalty for _, r in passing), leak_rss + penalty * k_leak if leaks else math.inf]
    )
    rss = np.array([*(r for _, r in passing), leak_rss])
    weights = _weights(ic, s2) if np.isfinite(ic).any() else np.zeros(ic.size)
    best = int(np.argmin(ic))
    close = (weights >= settings.group_ratio * weights[best]) | (
        rss <= (1.0 + settings.relative_tolerance) * rss[best]
    )
    share = float(np.sum(weights[close]) / np.sum(weights)) if np.sum(weights) > 0 else 0.0
    members = [
        (i, GroupMember(f.hypothesis.family, f.hypothesis.kind, f.hypothesis.location, f.size,
                        f.hypothesis.unit))
        for i, f in enumerate(candidates)
        if close[i]
    ]  # fmt: skip
    members.sort(key=lambda m: -weights[m[0]])
    fault_members = tuple(m for _, m in members)
    # an internal leak the leak explanation fits about as well (close): the signals cannot
    # tell a spool or piston leak from a leak of the same line, both lose the same air,
    # and external leaks are the common case; the leaks stay, costed, and the internal
    # leak joins their group (a nominal description's leak signatures sized badly on a
    # varied plant let a simulated spool leak win by a little and dropped a real leak)
    internal_close = (
        best < len(candidates)
        and bool(close[-1])
        and candidates[best].hypothesis.family == "internal-leak"
    )
    if best == len(candidates) or (leaks and internal_close):
        # the leaks stay; close faults join the largest's group
        found = leak_findings(leaks, channels)
        if found and fault_members:
            first = found[0]
            found[0] = Finding(
                first.fault_type,
                first.kind,
                first.location,
                first.size,
                first.unit,
                first.ambiguity_group + fault_members,
                min(first.confidence, share),
                first.annual_cost,
            )
        return FaultVerdict(found, False, True, tuple(fits))
    chosen = candidates[best]
    group = fault_members
    if leaks and close[-1]:
        group = group + tuple(_leak_member(str(leak.location), leak.mass_flow) for leak in leaks)
    h = chosen.hypothesis
    finding = Finding(
        h.family,
        h.kind,
        h.location,
        chosen.size,
        h.unit,
        group,
        share,
        cycle_time_change=cycle_time_change(effects.signatures.feature_names, chosen.change),
        step_change=largest_step_change(effects.signatures.feature_names, chosen.change),
    )
    if leaks:
        notes.append(
            f"{finding.describe()} explains the run better than the leak explanation "
            f"({', '.join(f'{leak.location} {leak.flow_slpm:.1f} SLPM' for leak in leaks)}; "
            f"weighted residual {rss[best]:.3g} against {leak_rss:.3g}): no leak is reported"
        )
    return FaultVerdict([finding], bool(leaks), True, tuple(fits))
