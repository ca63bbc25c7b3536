"""Which faults a sensor set can tell apart: the isolability table (issue 34, item 3).

A diagnosis reports an ambiguity group when several explanations fit a run about as
well (:mod:`pneufdd.diagnosis.fault_choice`). Which explanations end up together is a
property of the machine and its sensors, not of one run: it follows from the fault
signatures, the feature changes each fault causes, and from the band within which the
twin's signature is known on a real plant. This module computes it ahead of any run.

**Signatures.** Every fault hypothesis the description carries
(:func:`~pneufdd.diagnosis.localisation.faults.fault_hypotheses`: throttles, friction,
valve delays, piston and spool leaks, late switches, the regulator) at its screening
size, and a leak of :data:`LEAK_SIGNATURE_SLPM` at each leak location, simulated with
the reference's twin and seed against its leak-free run, both without sensor noise
(:class:`~pneufdd.diagnosis.effects.twin.TwinLeakEffect`,
:func:`~pneufdd.sim.variation.noise_free`), as the diagnosis simulates the faults.

**Told apart or not.** Let :math:`e_i` be the signature of hypothesis :math:`i` and
:math:`W` the diagnosis's weighting of a run of ``run_cycles`` cycles
(:func:`pneufdd.diagnosis.engine.whitener`: the reference's noise, the noise of a
2-cycle simulated change, a model-error floor of
:data:`~pneufdd.diagnosis.fault_choice.FAULT_MODEL_ERROR` of the larger of the two
changes per feature, the house-air directions projected out). A run with fault
:math:`i` explained by hypothesis :math:`j` at its best size leaves, beyond the noise,

.. math::

    d_{ij} = \\min_{a} \\lVert W (e_i - a\\, e_j) \\rVert^2, \\qquad
    a \\in [0.1, 3]

and :math:`j` joins :math:`i`'s ambiguity group when its Akaike-type weight
:math:`\\exp(-d_{ij} / 2)` is at least the group ratio of the reference's
localisation settings (0.05: :math:`d_{ij} \\le 2 \\ln 20 = 5.99`): the diagnosis's
own group rule (:func:`~pneufdd.diagnosis.fault_choice.judge_faults`) applied to the
expected residuals. Hypothesis :math:`i` is *detectable as an explanation* when
:math:`\\lVert W e_i \\rVert^2` exceeds the penalty of one fitted size,
:math:`2 \\ln(\\mathrm{dof})` (a fault must beat "no explanation" by it).

The relation is not symmetric (a large effect may explain a small one's features but
not the reverse); the table lists, for each hypothesis, the others that cannot be
told from it when it is the truth. Signatures are scaled linearly (a fault's effect is
not linear in its size: sizing by simulation may fit a little better or worse), and
the floor is the fault's, not the leaks' sampled plant spread: an approximation of
what :func:`~pneufdd.diagnosis.fault_choice.judge_faults` does on a run
(``docs/faults.md``, "Isolability").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.signatures import feature_columns
from pneufdd.diagnosis.effects.twin import SIGNATURE_SEED, TwinLeakEffect
from pneufdd.diagnosis.fault_choice import FAULT_MODEL_ERROR
from pneufdd.diagnosis.findings import GroupMember
from pneufdd.diagnosis.localisation.faults import fault_hypotheses
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.diagnosis.reference.sensor_sets import sensor_set_kind
from pneufdd.errors import InputError, describe
from pneufdd.features.step_summaries import sequence_from_records
from pneufdd.location import Location
from pneufdd.parallel import thread_map
from pneufdd.physics.units import slpm_to_kg_s
from pneufdd.sim import MachineDescription, vary_machine
from pneufdd.sim.variation import noise_free

__all__ = [
    "LADDER",
    "LEAK_SIGNATURE_SLPM",
    "PLANT_SEED",
    "RUN_CYCLES",
    "SCALES",
    "FaultSignatures",
    "IsolabilityTable",
    "component",
    "fault_signatures",
    "isolability",
]

LEAK_SIGNATURE_SLPM = 40.0
"""Size of the leak whose signature stands for each leak location [SLPM]: the piston
leak's screening size, between the spool leaks' (20) and the acceptance's leaks
(30-150)."""

PLANT_SEED = 3_470_000
"""Seed of the first plausible plant of the plant-uncertainty band."""

RUN_CYCLES = 12
"""Cycles of the run the weighting assumes (the acceptance's runs) [-]."""

LADDER = (1.0 / 3.0, 1.0, 1.8)
"""Sizes simulated per hypothesis, times its signature size (1.8: a throttle's -50 %
becomes -90 %, within its 95 % range) [-]."""

SCALES = tuple(sorted({1.0, *(float(s) for s in np.geomspace(0.1, 3.0, 15))}))
"""Multiples of a signature tried to explain another (the sizing's 0.1-3 range, and 1) [-]."""


@dataclass(frozen=True)
class FaultSignatures:
    """Feature changes of every hypothesis at its signature size.

    Attributes
    ----------
    members : tuple of GroupMember
        The hypotheses: type, kind, location, signature size and unit.
    feature_names : tuple of str
        Features of ``changes``' columns.
    changes : ndarray, shape (n_members, n_features)
        Simulated change of each [feature unit].
    stalled : tuple of GroupMember
        Hypotheses the machine cannot run with at their signature size (left out).
    deviations : ndarray, shape (n_members, n_plants, n_features)
        Each plausible plant's change less the twin's, for the same fault (zero where
        the plant stops) [feature unit]; ``n_plants`` 0 trusts the twin.
    ladder : ndarray, shape (n_members, len(LADDER), n_features)
        The change at each size of :data:`LADDER` times the signature size (NaN where
        the machine stops) [feature unit]; empty: ``changes`` scaled linearly.
    """

    members: tuple[GroupMember, ...]
    feature_names: tuple[str, ...]
    changes: FloatArray
    stalled: tuple[GroupMember, ...] = ()
    deviations: FloatArray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    ladder: FloatArray = field(default_factory=lambda: np.zeros((0, 0, 0)))

    def path(self, scale: float) -> FloatArray:
        """Every member's change at ``scale`` times its signature size, piecewise linear
        through 0 and the ladder (linear beyond its ends) [feature unit]."""
        if not self.ladder.size:
            return scale * self.changes
        xs = (0.0, *LADDER)
        ys = np.concatenate([np.zeros_like(self.ladder[:, :1]), self.ladder], axis=1)
        k = min(max(int(np.searchsorted(xs, scale)) - 1, 0), len(xs) - 2)
        t = (scale - xs[k]) / (xs[k + 1] - xs[k])
        return np.asarray((1.0 - t) * ys[:, k] + t * ys[:, k + 1])

    def select(self, names: Sequence[str]) -> FaultSignatures:
        """The same signatures over the features ``names`` (a sensor set's)."""
        cols = feature_columns(self.feature_names, names, "features of the sensor set")
        dev = self.deviations[:, :, cols] if self.deviations.size else self.deviations
        ladder = self.ladder[:, :, cols] if self.ladder.size else self.ladder
        return FaultSignatures(
            self.members, tuple(names), self.changes[:, cols], self.stalled, dev, ladder
        )


def fault_signatures(
    reference: ReferenceModel,
    cycles: int = 2,
    threads: int = 1,
    leak_slpm: float = LEAK_SIGNATURE_SLPM,
    plants: int = 0,
    plant_scale: float = 1.0,
    seed: int = PLANT_SEED,
) -> FaultSignatures:
    """Simulate every fault hypothesis and a leak per location on the reference's twin.

    With ``plants`` > 0 the same faults are simulated on that many plausible plants
    drawn around the description (:func:`~pneufdd.sim.vary_machine` at
    ``plant_scale``, seeds ``seed + k``), each against its own leak-free baseline: the
    spread of a fault's effect on a real machine, treated like the leaks'
    (:attr:`SignatureSet.plant_deviations`).

    Parameters
    ----------
    reference : ReferenceModel
        A reference with a machine description and its PLC sequence.
    cycles : int
        Inner cycles averaged per simulation (the diagnosis's 2).
    threads : int
        Simulations at once.
    leak_slpm : float
        Size of each location's leak [SLPM].
    plants : int
        Plausible plants whose deviations form the plant-uncertainty band [-].
    plant_scale : float
        Their spread relative to the documented tolerances (1: a plausible machine).
    seed : int
        Seed of the first plant.

    Raises
    ------
    InputError
        When the reference has no description or no PLC sequence (no twin).
    """
    machine = reference.description
    if machine is None or not reference.sequence:
        raise InputError(
            describe(
                "reference for an isolability table",
                "one without a machine description or PLC sequence",
                "a reference built with the machine's description (--machine)",
            )
        )
    if plants < 0 or not 0.0 <= plant_scale <= 3.0:
        raise InputError(
            describe(
                "plausible plants and their scale", (plants, plant_scale), "plants >= 0, scale 0-3"
            )
        )
    sequence = sequence_from_records(reference.sequence)
    faults = fault_hypotheses(machine)
    members = [
        GroupMember(h.family, h.kind, h.location, h.sign * h.screening, h.unit) for h in faults
    ]
    members += [
        GroupMember("leak", "leak", loc, leak_slpm, "SLPM") for loc in machine.leak_locations
    ]
    mass = float(slpm_to_kg_s(leak_slpm))
    n_features = len(reference.feature_names)

    def simulate_all(
        description: MachineDescription, scales: Sequence[float]
    ) -> list[FloatArray | None]:
        twin = TwinLeakEffect(
            noise_free(description), reference.feature_names, sequence, reference.channels, cycles,
            SIGNATURE_SEED,
        )  # fmt: skip

        def one(job: tuple[int, float]) -> FloatArray | None:
            i, scale = job
            try:
                if i < len(faults):
                    h = faults[i]
                    return twin.fault_change(h.fault(scale * h.screening))
                return twin({Location.parse(members[i].location): scale * mass})
            except InputError:  # the description cannot carry it
                return None

        return thread_map(one, [(i, scale) for scale in scales for i in range(n)], threads)

    n = len(members)
    on_twin = simulate_all(machine, LADDER)
    got = on_twin[n * LADDER.index(1.0) : n * (LADDER.index(1.0) + 1)]
    kept = [i for i, g in enumerate(got) if g is not None]
    changes = np.array([got[i] for i in kept], dtype=np.float64).reshape(len(kept), n_features)
    nan = np.full(n_features, np.nan)
    ladder = np.array(
        [[on_twin[k * n + i] if on_twin[k * n + i] is not None else nan for k in range(len(LADDER))]
         for i in kept],
        dtype=np.float64,
    ).reshape(len(kept), len(LADDER), n_features)  # fmt: skip
    deviations = np.zeros((len(kept), plants, n_features))
    for k in range(plants):
        on_plant = simulate_all(vary_machine(machine, plant_scale, seed + k), (1.0,))
        for row, i in enumerate(kept):
            change = on_plant[i]
            if change is not None and np.all(np.isfinite(change)):
                deviations[row, k] = change - changes[row]
    return FaultSignatures(
        tuple(members[i] for i in kept),
        reference.feature_names,
        changes,
        tuple(m for m, g in zip(members, got, strict=True) if g is None),
        deviations,
        ladder,
    )


@dataclass(frozen=True)
class IsolabilityTable:
    """Which hypotheses a sensor set cannot tell apart.

    Attributes
    ----------
    machine : str
        The machine.
    sensor_set : str
        Kind of the set (``full``, ``supply-only``, ``line-flows``, ``digital-only``...).
    channels : tuple of str
        Its analog channels.
    members : tuple of GroupMember
        The hypotheses at their signature sizes.
    distance : ndarray, shape (n, n)
        :math:`d_{ij}`: the excess weighted residual of explaining ``i``'s signature
        by ``j`` at its best scale [-].
    strength : ndarray, shape (n,)
        :math:`\\lVert W e_i \\rVert^2` [-].
    threshold : float
        Largest ``d`` with which ``j`` joins ``i``'s group [-].
    penalty : float
        Smallest ``strength`` with which ``i`` is an explanation at all [-].
    stalled : tuple of GroupMember
        Hypotheses left out: the machine stops with them.
    truth_scale : float
        Size of the true faults, times their signature size [-].
    """

    machine: str
    sensor_set: str
    channels: tuple[str, ...]
    members: tuple[GroupMember, ...]
    distance: FloatArray
    strength: FloatArray
    threshold: float
    penalty: float
    stalled: tuple[GroupMember, ...] = field(default=())
    truth_scale: float = 1.0

    @property
    def detectable(self) -> FloatArray:
        """True where the hypothesis beats "no explanation" (bool array)."""
        return np.asarray(self.strength > self.penalty)

    def group(self, i: int) -> tuple[int, ...]:
        """Indices of the hypotheses that cannot be told from ``i`` (``i`` excluded)."""
        close = np.flatnonzero(self.distance[i] <= self.threshold)
        return tuple(int(j) for j in close if j != i)

    def type_confusions(self) -> dict[tuple[str, str], int]:
        """``(true type, confused type) -> count`` of detectable hypotheses whose group
        holds a member of another type."""
        out: dict[tuple[str, str], int] = {}
        for i, m in enumerate(self.members):
            if not self.detectable[i]:
                continue
            for t in sorted({self.members[j].fault_type for j in self.group(i)} - {m.fault_type}):
                out[(m.fault_type, t)] = out.get((m.fault_type, t), 0) + 1
        return out

    def summary(self) -> dict[str, Any]:
        """Counts: hypotheses, detectable, isolable (group of one), type isolable (no
        other type in the group), component isolable (no other component)."""
        rows = [(i, m) for i, m in enumerate(self.members) if self.detectable[i]]
        alone = sum(not self.group(i) for i, _ in rows)
        by_type = sum(
            all(self.members[j].fault_type == m.fault_type for j in self.group(i)) for i, m in rows
        )
        by_component = sum(
            all(component(self.members[j].location) == component(m.location) for j in self.group(i))
            for i, m in rows
        )
        return {
            "hypotheses": len(self.members),
            "detectable": len(rows),
            "isolable": alone,
            "type_isolable": by_type,
            "component_isolable": by_component,
            "stalled": len(self.stalled),
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible: summary, type confusions and one row per hypothesis."""
        return {
            "machine": self.machine,
            "sensor_set": self.sensor_set,
            "channels": list(self.channels),
            "threshold": self.threshold,
            "penalty": self.penalty,
            "truth_scale": self.truth_scale,
            "summary": self.summary(),
            "type_confusions": [
                {"type": a, "confused_with": b, "count": n}
                for (a, b), n in sorted(self.type_confusions().items())
            ],
            "rows": self.rows(),
            "stalled": [m.to_dict() for m in self.stalled],
        }

    def rows(self) -> list[dict[str, Any]]:
        """One record per hypothesis: what it is and what it cannot be told from."""
        return [
            {
                **m.to_dict(),
                "detectable": bool(self.detectable[i]),
                "strength": float(self.strength[i]),
                "cannot_tell_from": [self.members[j].describe() for j in self.group(i)],
            }
            for i, m in enumerate(self.members)
        ]

    def to_pandas(self) -> Any:
        """One row per hypothesis (:meth:`rows`) as a DataFrame."""
        import pandas as pd

        frame = pd.DataFrame(self.rows())
        frame["cannot_tell_from"] = frame["cannot_tell_from"].map("; ".join)
        return frame


def component(location: str) -> str:
    """The actuator (or the switch's actuator, or ``supply``) a location belongs to.

    Examples
    --------
    >>> [component(x) for x in ("S_DNC_B", "DNC_A", "DNC", "supply")]
    ['DNC', 'DNC', 'DNC', 'supply']
    """
    name = location[2:] if location.startswith("S_") else location
    return name[:-2] if name.endswith(("_A", "_B")) else name


def _weights(
    reference: ReferenceModel, run_cycles: int, predicted_cycles: int
) -> tuple[FloatArray, FloatArray]:
    """Noise variance per feature and the house-air directions (k, n_features)."""
    det = reference.detector
    sigma = np.asarray(det.scale_, dtype=np.float64)
    variance = sigma**2 * (1.0 / run_cycles + 1.0 / reference.n_cycles + 1.0 / predicted_cycles)
    nuisance = np.asarray(det.components_, dtype=np.float64) * sigma
    return variance, nuisance


def _excess(
    target: FloatArray,
    candidates: FloatArray,
    variance: FloatArray,
    nuisance: FloatArray,
    deviations: FloatArray | None = None,
) -> FloatArray:
    r"""``(target - c)^T C^{-1} (target - c)`` per row ``c`` of ``candidates``.

    :math:`C = \operatorname{diag}(\sigma^2 + (\rho m)^2) + D D^T / K + \lambda N N^T`,
    :math:`\lambda \to \infty`: the noise, the floor relative to ``m = max(|target|,
    |c|)`` per row, the ``K`` plant ``deviations`` of the target (``(K, features)``)
    and the house-air directions ``nuisance`` projected out, as
    :func:`pneufdd.diagnosis.engine.whitener` weighs a run (Woodbury's identity)."""
    magnitude = np.maximum(np.abs(target)[None, :], np.abs(candidates))
    weight = 1.0 / np.sqrt(variance[None, :] + (FAULT_MODEL_ERROR * magnitude) ** 2)
    r = (target[None, :] - candidates) * weight
    plants = np.zeros((0, target.size)) if deviations is None else deviations
    low_rank = np.vstack([plants / np.sqrt(max(plants.shape[0], 1)), nuisance])
    if low_rank.shape[0] == 0:
        return np.asarray(np.sum(r * r, axis=1))
    basis = weight[:, None, :] * low_rank[None, :, :]  # (rows, k, features)
    gram = np.einsum("rkf,rlf->rkl", basis, basis)
    # the plants' directions have unit prior variance, the house air's an infinite one
    gram = gram + np.diag([1.0] * plants.shape[0] + [1e-12] * nuisance.shape[0])[None]
    proj = np.einsum("rkf,rf->rk", basis, r)
    coef = np.linalg.solve(gram, proj[..., None])[..., 0]
    explained = np.einsum("rk,rk->r", coef, proj)
    return np.asarray(np.sum(r * r, axis=1) - explained)


def isolability(
    reference: ReferenceModel,
    signatures: FaultSignatures | None = None,
    run_cycles: int = RUN_CYCLES,
    predicted_cycles: int = 2,
    threads: int = 1,
    truth_scale: float = 1.0,
) -> IsolabilityTable:
    """The isolability table of a reference's machine and sensor set.

    Parameters
    ----------
    reference : ReferenceModel
        The reference (its noise, house-air directions, sensor set and twin).
    signatures : FaultSignatures, optional
        Signatures over a superset of its features (computed once for several sensor
        sets of one machine); simulated with :func:`fault_signatures` when omitted.
    run_cycles : int
        Cycles of the judged run [-].
    predicted_cycles : int
        Cycles a simulated change averages (the diagnosis's 2) [-].
    threads : int
        Simulations at once when the signatures are simulated here.
    truth_scale : float
        Size of the true faults, times their signature size (one of :data:`LADDER`
        where simulated, e.g. 1/3 for faults a third as large; the plants' deviations
        scaled linearly) [-].

    Returns
    -------
    IsolabilityTable
    """
    if run_cycles < 1 or predicted_cycles < 1:
        raise InputError(
            describe(
                "cycles of the run and of a simulated change",
                (run_cycles, predicted_cycles),
                ">= 1 each",
            )
        )
    sig = (
        fault_signatures(reference, predicted_cycles, threads) if signatures is None else signatures
    )
    sig = sig.select(reference.feature_names)
    variance, nuisance = _weights(reference, run_cycles, predicted_cycles)
    e = sig.path(truth_scale)
    n = e.shape[0]
    distance = np.full((n, n), np.inf)
    strength = np.zeros(n)
    dev = truth_scale * (sig.deviations if sig.deviations.size else np.zeros((n, 0, e.shape[1])))
    paths = [sig.path(a) for a in SCALES]
    zero = np.zeros((1, e.shape[1]))
    for i in range(n):
        if not np.all(np.isfinite(e[i])):  # the machine stops at this size
            continue
        tried = np.array([_excess(e[i], path, variance, nuisance, dev[i]) for path in paths])
        distance[i] = np.min(np.where(np.isfinite(tried), tried, np.inf), axis=0)
        strength[i] = float(_excess(e[i], zero, variance, nuisance, dev[i])[0])
    dof = max(len(reference.feature_names), 2)
    return IsolabilityTable(
        reference.machine,
        sensor_set_kind(reference.channels),
        tuple(reference.channels),
        tuple(replace(m, size=truth_scale * m.size) for m in sig.members),
        distance,
        strength,
        2.0 * math.log(1.0 / reference.localisation.group_ratio),
        2.0 * math.log(dof),
        sig.stalled,
        truth_scale,
    )
