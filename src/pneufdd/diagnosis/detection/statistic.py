"""A per-cycle distance that stays quiet under house-air fluctuation (section 4.4.1).

Each cycle is summarised by its per-step feature vector (step durations and the
mean/min/max of each analog channel over each step, see
:class:`~pneufdd.features.step_table.StepTable`). The vector is standardised with the
leak-free reference (eq. 5.1-5.2: :math:`z = (x - \\bar S) / \\bar\\sigma`).

The house-air supply of section 4.4.1 fluctuates slowly; it moves all pressures and
flows of a cycle together, in one or two fixed directions of feature space. Those
directions are learned as the leading principal components ``V`` of the standardised
reference cycles and projected out; a leak adds flow in a step-specific pattern that
mostly lies outside them. The statistic is the mean squared residual

.. math::

    T = \\frac{1}{p - k} \\left\\| (I - V V^T) z \\right\\|^2 ,

a squared prediction error as in PCA process monitoring. Its leak-free distribution
is measured by cross-validation on the reference (each reference cycle scored by a
model fitted without it, so the estimate is honest) and approximated by a scaled
chi-square :math:`g \\chi^2_h` matched in mean and variance (Box, 1954). The
per-cycle threshold is its ``1 - alpha`` quantile.

The cycles of one recording share its conditions (the house-pressure drift level and
compressor phase of section 4.4.1, the machine's warmth), so a cycle scored by a model
that learned its neighbours from the same recording looks closer to the reference than
a cycle of a new run does. When the reference cycles are labelled with their recording
(``groups``) and there are at least :data:`MIN_GROUPS_FOR_GROUPED_CV` recordings, each
recording is scored by a model fitted on the others (leave-one-group-out, the
cross-validation for grouped data of Roberts et al., 2017), which measures the
distribution a new run meets; with fewer, cycles are assigned to folds in turn.

A run of ``m`` cycles is judged on the *median* of its cycle statistics (the upper
median, order statistic :math:`k = \\lfloor m/2 \\rfloor + 1`, when ``m`` is even),
which averages out noise as the dissertation recommends ("take the average of some
coming cycles", section 5.3.2) yet is not moved by a few odd cycles: a leak raises the
statistic of every cycle, while a leak-free machine has occasional cycles unlike the
others (two parallel motions that finish in the other order, a PLC timer one scan
short). For ``m`` independent cycles the ``k``-th order statistic of a distribution
``F`` exceeds ``x`` with probability :math:`1 - I_{F(x)}(k, m - k + 1)` (regularised
incomplete beta function; David & Nagaraja, 2003, eq. 2.1.5), so the run threshold is
:math:`F^{-1}(B^{-1}_{k, m-k+1}(1 - \\alpha))` with :math:`F = g \\chi^2_h`. The
former rule, the run *mean* against :math:`(g/m) \\chi^2_{m h}`, is kept as
``run_statistic="mean"`` (references saved before the median existed use it).

The cycles of one run are not independent either: they share the run's conditions,
the same that made the cross-validation leave whole recordings out. With the held-out
statistics grouped by recording, their intra-class correlation :math:`\\rho` is
estimated by one-way analysis of variance (the unbalanced-design estimator,
Searle et al., 1992, section 3.6, truncated at 0), and a run of ``m`` cycles counts as
:math:`m_{eff} = m / (1 + (m - 1) \\rho)` independent ones (Kish's design effect,
1965, section 5.4): the run mean's law becomes :math:`(g/m_{eff}) \\chi^2_{m_{eff} h}`,
and the median's order-statistic law :math:`B(k, m - k + 1)` becomes
:math:`B(1 + (k - 1) s, 1 + (m - k) s)` with :math:`s = (m_{eff} - 1) / (m - 1)`: the
same law at :math:`\\rho = 0`, one cycle's (uniform) at :math:`\\rho = 1`, and in
between a variance of :math:`\\mu (1 - \\mu) / (m_{eff} + 2)` instead of
:math:`\\mu (1 - \\mu) / (m + 2)` (the design effect). The correction only raises
the run threshold; with fewer than
:data:`MIN_GROUPS_FOR_GROUPED_CV` recordings, or ``run_correlation=False``,
:math:`\\rho = 0` and the rule is the independent one above.

References
----------
.. [1] Box, G. E. P. (1954). Some theorems on quadratic forms applied in the study
   of analysis of variance problems. Ann. Math. Statist. 25(2), 290-302.
.. [2] Jackson, J. E., Mudholkar, G. S. (1979). Control procedures for residuals
   associated with principal component analysis. Technometrics 21(3), 341-349.
.. [3] David, H. A., Nagaraja, H. N. (2003). Order Statistics, 3rd ed. Wiley.
.. [4] Roberts, D. R. et al. (2017). Cross-validation strategies for data with
   temporal, spatial, hierarchical, or phylogenetic structure. Ecography 40(8),
   913-929.
.. [5] Searle, S. R., Casella, G., McCulloch, C. E. (1992). Variance Components.
   Wiley.
.. [6] Kish, L. (1965). Survey Sampling. Wiley.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import stats
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray

__all__ = [
    "MIN_GROUPS_FOR_GROUPED_CV",
    "RUN_STATISTICS",
    "CycleDistanceDetector",
    "cross_validation_folds",
    "median_order",
    "recording_correlation",
    "scaled_chi2_fit",
]

RUN_STATISTICS = ("median", "mean")
"""How a run's cycle statistics are combined: their (upper) median, or their mean."""

MIN_GROUPS_FOR_GROUPED_CV = 3
"""Fewest recordings for leave-one-recording-out cross-validation: with two, each
model would learn from half the reference and overstate the spread [-]."""


def scaled_chi2_fit(values: npt.ArrayLike) -> tuple[float, float]:
    """Fit ``g * chi2(h)`` to positive values by matching mean and variance (Box, 1954).

    Parameters
    ----------
    values : array_like
        Samples of a non-negative statistic.

    Returns
    -------
    g : float
        Scale [unit of values].
    h : float
        Degrees of freedom [-].

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> g, h = scaled_chi2_fit(3.0 * rng.chisquare(5.0, size=200_000))
    >>> round(g, 1), round(h, 1)
    (3.0, 5.0)
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    mean = float(np.mean(v)) if v.size else 0.0
    var = float(np.var(v, ddof=1)) if v.size > 1 else 0.0
    if mean <= 0.0:
        return 1e-12, 1.0
    if var <= 1e-12 * mean**2:
        h = 1e6
        return mean / h, h
    return var / (2.0 * mean), 2.0 * mean**2 / var


def median_order(n_cycles: int) -> int:
    """Order statistic (1-based) of the upper median of ``n_cycles`` values [-].

    Examples
    --------
    >>> [median_order(m) for m in (1, 2, 3, 10, 11)]
    [1, 2, 2, 6, 6]
    """
    return int(n_cycles) // 2 + 1


def recording_correlation(values: npt.ArrayLike, groups: npt.ArrayLike) -> float:
    """Intra-class correlation of ``values`` within their groups (recordings) [-].

    One-way analysis of variance with unequal group sizes (Searle et al., 1992,
    section 3.6): between- and within-group mean squares ``MSB``, ``MSW`` and the
    effective group size :math:`n_0 = (N - \\sum n_i^2 / N) / (k - 1)` give
    :math:`\\sigma_b^2 = (MSB - MSW) / n_0`, and :math:`\\rho = \\sigma_b^2 /
    (\\sigma_b^2 + MSW)`, truncated at 0 (a negative estimate is sampling noise).

    Examples
    --------
    >>> recording_correlation([1.0, 1.1, 0.9, 3.0, 3.1, 2.9], [0, 0, 0, 1, 1, 1]) > 0.9
    True
    >>> recording_correlation([1.0, 3.0, 2.0, 1.0, 3.0, 2.0], [0, 0, 0, 1, 1, 1])
    0.0
    """
    x = np.asarray(values, dtype=np.float64).ravel()
    labels, index = np.unique(np.asarray(groups).ravel(), return_inverse=True)
    if index.size != x.size:
        raise ValueError(
            f"groups: received {index.size} labels for {x.size} values; allowed: one per value"
        )
    k, n = labels.size, x.size
    if k < 2 or n <= k:
        return 0.0
    sizes = np.bincount(index, minlength=k).astype(np.float64)
    means = np.bincount(index, weights=x, minlength=k) / sizes
    msb = float(np.sum(sizes * (means - x.mean()) ** 2) / (k - 1))
    msw = float(np.sum((x - means[index]) ** 2) / (n - k))
    n0 = (n - float(np.sum(sizes**2)) / n) / (k - 1)
    between = max((msb - msw) / n0, 0.0)
    total = between + msw
    return float(between / total) if total > 0 else 0.0


def cross_validation_folds(
    n_samples: int, n_folds: int, groups: npt.ArrayLike | None = None
) -> npt.NDArray[np.int64]:
    """Fold number of each sample for the cross-validated leak-free statistic.

    Parameters
    ----------
    n_samples : int
        Number of reference cycles [-].
    n_folds : int
        Folds when the cycles are not grouped (leave-one-out when ``n_samples`` is not
        larger) [-].
    groups : array_like of int, shape (n_samples,), optional
        Recording of each cycle. With at least :data:`MIN_GROUPS_FOR_GROUPED_CV`
        distinct recordings each recording is one fold.

    Returns
    -------
    ndarray of int, shape (n_samples,)

    Examples
    --------
    >>> cross_validation_folds(6, 3).tolist()
    [0, 1, 2, 0, 1, 2]
    >>> cross_validation_folds(6, 3, [7, 7, 8, 8, 9, 9]).tolist()
    [0, 0, 1, 1, 2, 2]
    >>> cross_validation_folds(4, 2, [0, 0, 1, 1]).tolist()   # two recordings: in turn
    [0, 1, 0, 1]
    """
    by_recording = _recording_folds(n_samples, groups)
    if by_recording is not None:
        return by_recording
    return np.arange(n_samples, dtype=np.int64) % min(int(n_folds), n_samples)


def _recording_folds(n_samples: int, groups: npt.ArrayLike | None) -> npt.NDArray[np.int64] | None:
    """One fold per recording, or None when there are too few recordings to group."""
    if groups is None:
        return None
    g = np.asarray(groups)
    if g.shape != (n_samples,) or g.dtype.kind not in "iu":
        raise ValueError(
            f"groups: received shape {g.shape} of dtype {g.dtype}; allowed: one "
            f"integer recording number per sample ({n_samples})"
        )
    labels, folds = np.unique(g, return_inverse=True)
    if labels.size < MIN_GROUPS_FOR_GROUPED_CV:
        return None
    return np.asarray(folds, dtype=np.int64)


def _fit_space(
    data: FloatArray, floor: FloatArray, n_nuisance: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    mean = np.mean(data, axis=0)
    std = np.std(data, axis=0, ddof=1) if data.shape[0] > 1 else np.zeros(data.shape[1])
    scale = np.maximum(std, floor)
    scale = np.where(scale > 0, scale, 1.0)
    z = (data - mean) / scale
    k = max(0, min(n_nuisance, data.shape[0] - 2, data.shape[1] - 1))
    if k == 0:
        return mean, scale, np.zeros((0, data.shape[1]))
    _, _, vt = np.linalg.svd(z, full_matrices=False)
    return mean, scale, vt[:k]


def _residual_stat(z: FloatArray, components: FloatArray) -> FloatArray:
    resid = z - (z @ components.T) @ components
    dof = max(z.shape[1] - components.shape[0], 1)
    return np.asarray(np.sum(resid**2, axis=1) / dof, dtype=np.float64)


class CycleDistanceDetector(BaseEstimator):  # type: ignore[misc]
    """Standardised per-step-feature distance with the supply fluctuation projected out.

    Parameters
    ----------
    n_nuisance : int
        Number of leading principal directions of the leak-free reference treated as
        supply fluctuation and projected out (section 4.4.1) [-].
    false_alarm_rate : float
        Target probability that a leak-free cycle, or a leak-free run, is flagged [-].
    scale_floor : float or array_like
        Floor of each feature's standard deviation: the sensor resolution, so that a
        feature that never varies in the reference does not dominate [feature unit].
    n_folds : int
        Cross-validation folds used to measure the leak-free distribution of the
        statistic (leave-one-out when there are no more cycles than folds) [-].
    run_statistic : {"median", "mean"}
        How a run's cycle statistics are combined (module docstring).
    run_correlation : bool
        Let the run threshold account for the correlation of one recording's cycles
        (module docstring); needs ``groups`` in :meth:`fit`.

    Attributes
    ----------
    mean_ : ndarray, shape (n_features,)
        Reference mean of each feature, eq. 5.1.
    scale_ : ndarray, shape (n_features,)
        Reference standard deviation of each feature, floored.
    components_ : ndarray, shape (k, n_features)
        Orthonormal supply-fluctuation directions in standardised space.
    reference_scores_ : ndarray, shape (n_cycles,)
        Cross-validated statistic of each reference cycle.
    grouped_cv_ : bool
        True when the cross-validation left out one recording at a time.
    recording_correlation_ : float
        Intra-class correlation of the held-out statistics within a recording, used by
        the run threshold (0 without grouped cross-validation or ``run_correlation``).
    chi2_scale_, chi2_dof_ : float
        Box fit ``g``, ``h`` of the leak-free distribution.
    threshold_ : float
        Per-cycle alarm threshold, the ``1 - false_alarm_rate`` quantile.
    reference_false_alarm_rate_ : float
        Fraction of the cross-validated reference cycles above ``threshold_``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> supply = rng.normal(size=(60, 1))                     # common fluctuation
    >>> X = supply * np.linspace(1, 2, 40) + 0.1 * rng.normal(size=(60, 40))
    >>> det = CycleDistanceDetector(n_nuisance=1).fit(X)
    >>> fluct = 3.0 * np.linspace(1, 2, 40) + 0.1 * rng.normal(size=(1, 40))
    >>> int(det.predict(fluct)[0])                            # big fluctuation: quiet
    0
    >>> leak = 0.3 * (np.arange(40) % 2) + 0.1 * rng.normal(size=(1, 40))
    >>> int(det.predict(leak)[0])                             # step pattern: alarm
    1
    """

    def __init__(
        self,
        n_nuisance: int = 2,
        false_alarm_rate: float = 0.005,
        scale_floor: float | npt.ArrayLike = 0.0,
        n_folds: int = 20,
        run_statistic: str = "median",
        run_correlation: bool = True,
    ):
        self.n_nuisance = n_nuisance
        self.false_alarm_rate = false_alarm_rate
        self.scale_floor = scale_floor
        self.n_folds = n_folds
        self.run_statistic = run_statistic
        self.run_correlation = run_correlation

    def _floor(self, n_features: int) -> FloatArray:
        floor = np.asarray(self.scale_floor, dtype=np.float64)
        if floor.ndim == 0:
            floor = np.full(n_features, float(floor))
        if floor.shape != (n_features,) or np.any(~np.isfinite(floor)) or np.any(floor < 0):
            raise ValueError(
                f"scale_floor: received shape {floor.shape}; allowed: a non-negative scalar "
                f"or one value per feature ({n_features})"
            )
        return floor

    def fit(
        self, X: npt.ArrayLike, y: object = None, groups: npt.ArrayLike | None = None
    ) -> CycleDistanceDetector:
        """Learn reference statistics, fluctuation directions and the threshold.

        Parameters
        ----------
        X : array_like, shape (n_cycles, n_features)
            Per-cycle feature vectors of leak-free cycles.
        y : None
            Ignored.
        groups : array_like of int, shape (n_cycles,), optional
            Recording of each cycle (:func:`cross_validation_folds`).

        Returns
        -------
        CycleDistanceDetector
            The fitted detector.
        """
        if not isinstance(self.n_nuisance, int | np.integer) or self.n_nuisance < 0:
            raise ValueError(f"n_nuisance: received {self.n_nuisance!r}; allowed: int >= 0")
        if not 0.0 < self.false_alarm_rate < 1.0:
            raise ValueError(
                f"false_alarm_rate: received {self.false_alarm_rate!r}; allowed: (0, 1)"
            )
        if not isinstance(self.n_folds, int | np.integer) or self.n_folds < 2:
            raise ValueError(f"n_folds: received {self.n_folds!r}; allowed: int >= 2")
        if self.run_statistic not in RUN_STATISTICS:
            raise ValueError(
                f"run_statistic: received {self.run_statistic!r}; allowed: {list(RUN_STATISTICS)}"
            )
        data = validate_data(self, X, dtype=np.float64)
        n = data.shape[0]
        if n < 3:
            raise ValueError(
                f"CycleDistanceDetector needs at least 3 samples (cycles); got {n} sample(s)"
            )
        floor = self._floor(data.shape[1])
        self.mean_, self.scale_, self.components_ = _fit_space(data, floor, int(self.n_nuisance))
        by_recording = _recording_folds(n, groups)
        self.grouped_cv_ = by_recording is not None
        fold_of = (
            cross_validation_folds(n, int(self.n_folds)) if by_recording is None else by_recording
        )
        scores = np.empty(n)
        for f in np.unique(fold_of):
            test = fold_of == f
            mean, scale, comps = _fit_space(data[~test], floor, int(self.n_nuisance))
            scores[test] = _residual_stat((data[test] - mean) / scale, comps)
        self.reference_scores_ = scores
        self.recording_correlation_ = (
            recording_correlation(scores, fold_of)
            if by_recording is not None and self.run_correlation
            else 0.0
        )
        self.chi2_scale_, self.chi2_dof_ = scaled_chi2_fit(scores)
        self.threshold_ = self.run_threshold(1)
        self.reference_false_alarm_rate_ = float(np.mean(scores > self.threshold_))
        return self

    def standardize(self, X: npt.ArrayLike) -> FloatArray:
        """Standardised features ``(x - mean_) / scale_`` (eq. 5.2 over eq. 5.3's sigma)."""
        check_is_fitted(self, ["mean_", "scale_", "components_"])
        data = validate_data(self, X, dtype=np.float64, reset=False)
        return np.asarray((data - self.mean_) / self.scale_, dtype=np.float64)

    def project(self, Z: npt.ArrayLike) -> FloatArray:
        """Remove the supply-fluctuation directions from standardised vectors (rows)."""
        check_is_fitted(self, ["components_"])
        z = np.atleast_2d(np.asarray(Z, dtype=np.float64))
        return np.asarray(z - (z @ self.components_.T) @ self.components_, dtype=np.float64)

    def score_samples(self, X: npt.ArrayLike) -> FloatArray:
        """Statistic T of each cycle (larger = further from the leak-free reference) [-]."""
        return _residual_stat(self.standardize(X), self.components_)

    def decision_function(self, X: npt.ArrayLike) -> FloatArray:
        """``T - threshold_``; positive means alarm [-]."""
        return self.score_samples(X) - self.threshold_

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[np.int64]:
        """1 for a cycle whose statistic exceeds the per-cycle threshold, else 0."""
        return (self.decision_function(X) > 0).astype(np.int64)

    def run_score(self, scores: npt.ArrayLike) -> float:
        """The run's statistic from its cycle statistics: their median or mean [-].

        Parameters
        ----------
        scores : array_like, shape (n_cycles,)
            Cycle statistics of the run (:meth:`score_samples`).
        """
        s = np.sort(np.asarray(scores, dtype=np.float64).ravel())
        if s.size == 0:
            raise ValueError("run_score: received no cycle statistics; allowed: at least one")
        if self.run_statistic == "mean":
            return float(np.mean(s))
        return float(s[median_order(s.size) - 1])

    def effective_cycles(self, n_cycles: int) -> float:
        """Independent cycles a run of ``n_cycles`` is worth: ``m / (1 + (m-1) rho)`` [-]."""
        check_is_fitted(self, ["recording_correlation_"])
        m = max(int(n_cycles), 1)
        return m / (1.0 + (m - 1) * self.recording_correlation_)

    def _median_law(self, n_cycles: int) -> tuple[float, float]:
        """Beta parameters of the median's quantile level F(median) (module docstring)."""
        m = max(int(n_cycles), 1)
        k = median_order(m)
        if m == 1:
            return 1.0, 1.0
        shrink = (self.effective_cycles(m) - 1.0) / (m - 1)
        return 1.0 + (k - 1) * shrink, 1.0 + (m - k) * shrink

    def run_threshold(self, n_cycles: int) -> float:
        """Threshold of the run statistic of a run of ``n_cycles`` cycles [-]."""
        check_is_fitted(self, ["chi2_scale_", "chi2_dof_"])
        g, h, alpha = self.chi2_scale_, self.chi2_dof_, self.false_alarm_rate
        if self.run_statistic == "mean":
            m_eff = self.effective_cycles(n_cycles)
            return float(g / m_eff * stats.chi2.ppf(1.0 - alpha, m_eff * h))
        a, b = self._median_law(n_cycles)
        return float(g * stats.chi2.ppf(stats.beta.ppf(1.0 - alpha, a, b), h))

    def run_p_value(self, X: npt.ArrayLike) -> float:
        """Probability of a leak-free run scoring at least this run's statistic [-]."""
        scores = self.score_samples(X)
        g, h = self.chi2_scale_, self.chi2_dof_
        value = self.run_score(scores)
        if self.run_statistic == "mean":
            m_eff = self.effective_cycles(scores.size)
            return float(stats.chi2.sf(value * m_eff / g, m_eff * h))
        a, b = self._median_law(scores.size)
        return float(stats.beta.sf(stats.chi2.cdf(value / g, h), a, b))

    def predict_run(self, X: npt.ArrayLike) -> bool:
        """True when the run statistic of the run's cycles exceeds the run threshold."""
        scores = self.score_samples(X)
        return bool(self.run_score(scores) > self.run_threshold(scores.size))

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.requires_fit = True
        return tags
