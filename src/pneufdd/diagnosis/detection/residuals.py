"""Physics residuals: the run replayed through the machine's twin (section 4.1).

Model-based detection compares what the machine does with what its model says it
should do, and calls a fault when the residual is not zero (eq. 4.1, Fig. 4.1). Here
the model is the twin (:mod:`pneufdd.sim`) of the machine *as described*: the PLC
sequence the recording's valve commands follow is run through it leak-free, and per
PLC step the mean supply flow ``Q_In`` and mean supply pressure ``P_In`` of the run
are compared with the twin's:

.. math:: r^Q_j = \\bar Q_j - \\hat Q_j, \\qquad r^P_j = \\bar P_j - \\hat P_j .

A real plant is never its twin: the residuals of leak-free runs are not zero but
carry the model error. The :class:`ResidualDetector` therefore calibrates on
leak-free runs of the plant: their mean residual is the twin's bias (a "calibrated
twin") and their spread the noise. A cycle is flagged when a step's standardised
flow residual exceeds the threshold (Bonferroni over the steps, so that the cycle's
false-alarm rate is at most ``false_alarm_rate``).

The electro-pneumatic analogy of section 4.3 gives the consistency check: a leak is
a resistance in parallel with the load, so it draws more current and drops the
voltage across it (eqs. 4.19-4.20),

.. math:: i_{ls} > i \\ \\&\\ V_{m,ls} < V_m \\Leftrightarrow Q_{ls} > Q \\ \\&\\ P_{ls} < P
          \\qquad (4.21)

A flow rise *with* a pressure rise is the house air pushing harder, not a leak.
:meth:`ResidualDetector.verdict` says which it is for each cycle; with
``require_consistency`` only cycles consistent with eq. 4.21 are flagged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import stats
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.features.step_summaries import build_step_table, machine_sequence, segment_cycles
from pneufdd.recording.model import Recording
from pneufdd.sim import MachineDescription, load_machine, simulate

__all__ = [
    "RESIDUAL_CHANNELS",
    "ResidualDetector",
    "SupplyCheck",
    "TwinReplay",
    "Verdict",
    "supply_check",
]

RESIDUAL_CHANNELS = ("Q_In", "P_In")
"""Supply flow and supply pressure: the current and voltage of eq. 4.21."""


@dataclass(frozen=True)
class TwinReplay:
    """The twin's leak-free step means, and the residuals of a run against them.

    Attributes
    ----------
    machine : str
        Machine name.
    flow : ndarray, shape (n_steps,)
        Twin's mean supply mass flow per PLC step [kg/s].
    pressure : ndarray, shape (n_steps,)
        Twin's mean supply pressure per step [Pa].
    """

    machine: str
    flow: FloatArray
    pressure: FloatArray

    @classmethod
    def of(cls, machine: str | MachineDescription, cycles: int = 4, seed: int = 0) -> TwinReplay:
        """Run the twin (the description as written) leak-free for ``cycles`` cycles.

        The PLC sequence of the description issues the same valve commands as the
        machine's PLC, so its steps line up with the recording's (the segmentation
        aligns both on the valve firings). Sensor noise averages out over the cycles.
        """
        desc = load_machine(machine) if isinstance(machine, str) else machine
        rec = simulate(desc, cycles=cycles + 2, seed=seed)
        means = _step_means(rec, desc, "the twin's replay")
        return cls(desc.name, means[..., 0].mean(axis=0), means[..., 1].mean(axis=0))

    def residuals(self, recording: Recording, machine: MachineDescription) -> FloatArray:
        """Per cycle: flow residuals of every step, then pressure residuals.

        Parameters
        ----------
        recording : Recording
            A run of the machine with ``Q_In``, ``P_In`` and its PLC channels.
        machine : MachineDescription
            The description (for its PLC sequence).

        Returns
        -------
        ndarray, shape (n_cycles, 2 * n_steps)
            ``[r^Q_1 .. r^Q_n, r^P_1 .. r^P_n]`` [kg/s, Pa].
        """
        means = _step_means(recording, machine, "the run")
        if means.shape[1] != self.flow.size:
            raise InputError(
                describe("steps per cycle of the run", means.shape[1], [self.flow.size])
            )
        return np.hstack([means[..., 0] - self.flow, means[..., 1] - self.pressure])


def _step_means(recording: Recording, machine: MachineDescription, where: str) -> FloatArray:
    cycles, _, _ = segment_cycles(recording, machine_sequence(machine), where)
    table = build_step_table(recording, cycles, machine.name, RESIDUAL_CHANNELS)
    return np.asarray(table.summaries[:, :, :, 0])


Verdict = str
"""``"no leak"``, ``"leak (eq. 4.21 holds)"`` or ``"not a leak (pressure rose too)"``."""


class ResidualDetector(BaseEstimator):  # type: ignore[misc]
    """Thresholds on twin residuals from leak-free runs, with the eq. 4.21 verdict.

    Parameters
    ----------
    false_alarm_rate : float
        Target share of leak-free cycles flagged [-].
    flow_columns : int, optional
        Number of leading columns of ``X`` that are flow residuals; the rest are
        pressure residuals of the same steps. Default: the first half (rounded up),
        as :meth:`TwinReplay.residuals` orders them.
    require_consistency : bool
        Flag only cycles whose pressure fell where the flow rose (eq. 4.21).

    Attributes
    ----------
    bias_ : ndarray, shape (n_features,)
        Mean leak-free residual: the twin's error on this plant [kg/s, Pa].
    scale_ : ndarray, shape (n_features,)
        Leak-free standard deviation of each residual [kg/s, Pa].
    threshold_ : float
        Threshold on the largest standardised flow residual of a cycle [-].

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> free = np.hstack([rng.normal(0, 1e-4, (200, 3)), rng.normal(0, 500, (200, 3))])
    >>> det = ResidualDetector().fit(free)
    >>> leak = free[:2] + np.array([0, 8e-4, 0, 0, -4e3, 0])
    >>> det.predict(leak).tolist(), det.verdict(leak)[0]
    ([1, 1], 'leak (eq. 4.21 holds)')
    """

    def __init__(
        self,
        false_alarm_rate: float = 0.01,
        flow_columns: int | None = None,
        require_consistency: bool = True,
    ):
        self.false_alarm_rate = false_alarm_rate
        self.flow_columns = flow_columns
        self.require_consistency = require_consistency

    def _split(self, n_features: int) -> int:
        k = (n_features + 1) // 2 if self.flow_columns is None else int(self.flow_columns)
        if not 1 <= k <= n_features:
            raise ValueError(
                f"flow_columns: received {self.flow_columns!r}; allowed: 1..{n_features}"
            )
        return k

    def fit(self, X: npt.ArrayLike, y: object = None) -> ResidualDetector:
        """Calibrate bias and spread of each residual on leak-free cycles."""
        if not 0.0 < self.false_alarm_rate < 1.0:
            raise ValueError(
                f"false_alarm_rate: received {self.false_alarm_rate!r}; allowed: (0, 1)"
            )
        data = validate_data(self, X, dtype=np.float64)
        if data.shape[0] < 2:
            raise ValueError(
                f"ResidualDetector needs at least 2 samples; got n_samples = {data.shape[0]}"
            )
        k = self._split(data.shape[1])
        self.bias_ = data.mean(axis=0)
        spread = data.std(axis=0, ddof=1)
        floor = 1e-9 * np.maximum(np.abs(self.bias_), 1e-300)
        self.scale_ = np.maximum(spread, floor)
        n = data.shape[0]
        # Bonferroni over the flow columns; the t quantile for a spread estimated from n
        # cycles, widened for a new cycle (prediction interval)
        q = stats.t.isf(self.false_alarm_rate / k, df=n - 1) * np.sqrt(1.0 + 1.0 / n)
        self.threshold_ = float(q)
        self.n_flow_columns_ = k
        return self

    def standardised(self, X: npt.ArrayLike) -> FloatArray:
        """``(r - bias) / scale`` of every residual [-]."""
        check_is_fitted(self, "bias_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        return np.asarray((data - self.bias_) / self.scale_)

    def decision_function(self, X: npt.ArrayLike) -> FloatArray:
        """Largest standardised flow residual of each cycle minus the threshold [-]."""
        z = self.standardised(X)
        return np.asarray(np.max(z[:, : self.n_flow_columns_], axis=1) - self.threshold_)

    def _pressure_fell(self, z: FloatArray) -> npt.NDArray[np.bool_]:
        k = self.n_flow_columns_
        flow, pressure = z[:, :k], z[:, k:]
        if pressure.shape[1] == 0:
            return np.ones(z.shape[0], dtype=bool)
        m = min(k, pressure.shape[1])
        raised = flow[:, :m] > self.threshold_
        weight = np.where(raised, 1.0, 0.0)
        seen = weight.sum(axis=1) > 0
        mean_p = np.where(
            seen,
            np.sum(pressure[:, :m] * weight, axis=1) / np.maximum(weight.sum(axis=1), 1.0),
            np.mean(pressure[:, :m], axis=1),
        )
        return np.asarray(mean_p < 0.0)

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[np.int64]:
        """1 for a cycle flagged as leaking, else 0."""
        z = self.standardised(X)
        flagged = np.max(z[:, : self.n_flow_columns_], axis=1) > self.threshold_
        if self.require_consistency:
            flagged &= self._pressure_fell(z)
        return np.asarray(flagged, dtype=np.int64)

    def verdict(self, X: npt.ArrayLike) -> list[Verdict]:
        """Eq. 4.21 for each cycle: a flow rise with a pressure drop is a leak."""
        z = self.standardised(X)
        raised = np.max(z[:, : self.n_flow_columns_], axis=1) > self.threshold_
        fell = self._pressure_fell(z)
        return [
            "no leak"
            if not r
            else "leak (eq. 4.21 holds)"
            if f
            else "not a leak (pressure rose too)"
            for r, f in zip(raised, fell, strict=True)
        ]

    def leak_flow(self, X: npt.ArrayLike) -> FloatArray:
        """Estimated extra supply flow of each cycle: largest calibrated flow residual [kg/s]."""
        check_is_fitted(self, "bias_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        k = self.n_flow_columns_
        return np.asarray(np.max(data[:, :k] - self.bias_[:k], axis=1))

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.requires_fit = True
        return tags


def residual_rows(
    replay: TwinReplay, recordings: Sequence[Recording], machine: MachineDescription
) -> FloatArray:
    """Residual rows of several runs stacked (cycles of all runs)."""
    return np.vstack([replay.residuals(r, machine) for r in recordings])


@dataclass(frozen=True)
class SupplyCheck:
    """Eq. 4.19-4.21 on a run's supply: does its extra flow come with a pressure drop?

    The plant's own leak-free reference plays the calibrated twin: per PLC step, the
    run's mean supply flow and pressure are compared with the reference cycles'
    (:class:`ResidualDetector` fitted on them), and each cycle gets the verdict of
    :meth:`ResidualDetector.verdict`.

    Attributes
    ----------
    verdict : str
        The verdict of most cycles (ties: the first of "leak (eq. 4.21 holds)",
        "not a leak (pressure rose too)", "no leak").
    cycles : dict of str to int
        Number of cycles per verdict [-].
    flow_change : float
        Run mean minus reference mean of the supply flow, averaged over the steps
        [kg/s].
    pressure_change : float
        The same for the supply pressure [Pa].
    """

    verdict: Verdict
    cycles: dict[str, int]
    flow_change: float
    pressure_change: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form (flows in kg/s, pressures in Pa)."""
        return {
            "verdict": self.verdict,
            "cycles": dict(self.cycles),
            "flow_change_kg_s": self.flow_change,
            "pressure_change_pa": self.pressure_change,
        }


_VERDICT_ORDER = ("leak (eq. 4.21 holds)", "not a leak (pressure rose too)", "no leak")


def supply_check(
    feature_names: Sequence[str], reference: npt.ArrayLike, run: npt.ArrayLike
) -> SupplyCheck | None:
    """The eq. 4.21 verdict of a run against its leak-free reference (no simulation).

    Parameters
    ----------
    feature_names : sequence of str
        Names of the feature columns (:func:`pneufdd.features.step_table.feature_names`).
    reference : array_like, shape (n_reference_cycles, n_features)
        Leak-free cycles.
    run : array_like, shape (n_cycles, n_features)
        The run's cycles.

    Returns
    -------
    SupplyCheck or None
        None when the features hold no ``Q_In`` and ``P_In`` step means (no supply
        sensors) or the reference has fewer than 3 cycles.

    Examples
    --------
    >>> names = ("Q_In.mean@1", "Q_In.mean@2", "P_In.mean@1", "P_In.mean@2")
    >>> rng = np.random.default_rng(0)
    >>> ref = np.hstack([rng.normal(1e-3, 1e-5, (40, 2)), rng.normal(5e5, 200, (40, 2))])
    >>> leak = ref[:5] + [2e-4, 2e-4, -3e3, -3e3]
    >>> supply_check(names, ref, leak).verdict
    'leak (eq. 4.21 holds)'
    >>> supply_check(names, ref, ref[:5] + [2e-4, 2e-4, 3e3, 3e3]).verdict
    'not a leak (pressure rose too)'
    """
    names = list(feature_names)
    flow = [i for i, n in enumerate(names) if n.startswith("Q_In.mean@")]
    pressure = [i for i, n in enumerate(names) if n.startswith("P_In.mean@")]
    ref = np.atleast_2d(np.asarray(reference, dtype=np.float64))
    X = np.atleast_2d(np.asarray(run, dtype=np.float64))
    if not flow or not pressure or len(flow) != len(pressure) or ref.shape[0] < 3:
        return None
    cols = flow + pressure
    detector = ResidualDetector(flow_columns=len(flow)).fit(ref[:, cols])
    verdicts = detector.verdict(X[:, cols])
    counts = {v: verdicts.count(v) for v in _VERDICT_ORDER if v in verdicts}
    most = max(counts.values())
    verdict = next(v for v in _VERDICT_ORDER if counts.get(v, 0) == most)
    change = X[:, cols].mean(axis=0) - ref[:, cols].mean(axis=0)
    k = len(flow)
    return SupplyCheck(verdict, counts, float(np.mean(change[:k])), float(np.mean(change[k:])))
