"""The band method of section 5.3.2: mean +/- eps sigma per sample, n % rule.

For repeated cycles every sample ``j`` of every signal ``i`` has a reference mean and
spread (eq. 5.21),

.. math::

    \\bar S_{i,j} = E\\{S_{i,j}\\}, \\qquad
    \\bar\\sigma^2_{i,j} = E\\{(S_{i,j} - \\bar S_{i,j})^2\\},

and a new cycle is out of band at a sample when
:math:`|S_{i,j} - \\bar S_{i,j}| > \\varepsilon \\bar\\sigma_{i,j}` (eq. 5.3,
:math:`\\varepsilon` = 2 or 3). An alarm is raised when more than ``n`` % of the
cycle's samples are out of band. For Gaussian samples the expected out-of-band
fraction of a leak-free cycle is :math:`2(1 - \\Phi(\\varepsilon))`: 4.55 % for
eps = 2, 0.27 % for eps = 3, so ``n`` must sit above that.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray

__all__ = ["BandDetector"]


class BandDetector(BaseEstimator):  # type: ignore[misc]
    """Per-sample threshold band of eq. 5.3 / 5.21 with the n % alarm rule.

    Parameters
    ----------
    eps : float
        Width of the band in reference standard deviations; the dissertation uses
        2 and 3 [-].
    alarm_fraction : float
        Alarm when more than this fraction of a cycle's samples is out of band; the
        dissertation's ``n`` % as a fraction [-].
    min_std : float
        Floor of the per-sample standard deviation, so that a sample that never
        varies over the reference (a saturated flow meter, a closed line) does not
        alarm on rounding noise [unit of X].

    Attributes
    ----------
    mean_ : ndarray, shape (n_features,)
        Reference mean of each sample, :math:`\\bar S_{i,j}`.
    std_ : ndarray, shape (n_features,)
        Reference standard deviation of each sample, :math:`\\bar\\sigma_{i,j}`
        (floored at ``min_std``).
    n_features_in_ : int
        Number of samples per cycle seen in ``fit``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> det = BandDetector(eps=3.0, alarm_fraction=0.02).fit(rng.normal(size=(200, 500)))
    >>> det.predict(rng.normal(size=(3, 500))).tolist()
    [0, 0, 0]
    >>> det.predict(rng.normal(size=(1, 500)) + 2.0).tolist()
    [1]
    """

    def __init__(self, eps: float = 3.0, alarm_fraction: float = 0.05, min_std: float = 0.0):
        self.eps = eps
        self.alarm_fraction = alarm_fraction
        self.min_std = min_std

    def _check_params(self) -> None:
        if not np.isfinite(self.eps) or self.eps <= 0:
            raise ValueError(f"eps: received {self.eps!r}; allowed: > 0 (2 or 3 in eq. 5.3)")
        if not 0.0 <= self.alarm_fraction < 1.0:
            raise ValueError(f"alarm_fraction: received {self.alarm_fraction!r}; allowed: [0, 1)")
        if not np.isfinite(self.min_std) or self.min_std < 0:
            raise ValueError(f"min_std: received {self.min_std!r}; allowed: >= 0")

    def fit(self, X: npt.ArrayLike, y: object = None) -> BandDetector:
        """Learn the per-sample band from leak-free cycles.

        Parameters
        ----------
        X : array_like, shape (n_cycles, n_samples)
            Step-aligned samples of leak-free cycles, one row per cycle. NaN marks a
            sample a cycle does not have (a step shorter than the longest); it is
            left out of that sample's statistics.
        y : None
            Ignored.

        Returns
        -------
        BandDetector
            The fitted detector.
        """
        self._check_params()
        data = validate_data(self, X, ensure_all_finite="allow-nan", dtype=np.float64)
        if data.shape[0] < 2:
            raise ValueError(
                f"BandDetector needs at least 2 samples (cycles); got {data.shape[0]} sample"
            )
        if np.all(np.isnan(data)):
            raise ValueError("Input X contains only NaN.")
        with np.errstate(invalid="ignore"):
            counts = np.sum(np.isfinite(data), axis=0)
            total = np.nansum(data, axis=0)
            mean = np.where(counts > 0, total / np.maximum(counts, 1), np.nan)
            dev = np.where(np.isfinite(data), data - mean, 0.0)
            var = np.sum(dev**2, axis=0) / np.maximum(counts - 1, 1)
        self.mean_ = mean
        self.std_ = np.maximum(np.sqrt(var), self.min_std)
        return self

    @classmethod
    def from_statistics(
        cls,
        mean: npt.ArrayLike,
        std: npt.ArrayLike,
        eps: float = 3.0,
        alarm_fraction: float = 0.05,
        min_std: float = 0.0,
    ) -> BandDetector:
        """Rebuild a fitted detector from stored per-sample statistics (eq. 5.21)."""
        det = cls(eps=eps, alarm_fraction=alarm_fraction, min_std=min_std)
        det._check_params()
        det.mean_ = np.asarray(mean, dtype=np.float64).ravel()
        det.std_ = np.maximum(np.asarray(std, dtype=np.float64).ravel(), min_std)
        if det.mean_.shape != det.std_.shape:
            raise ValueError(f"mean and std shapes differ: {det.mean_.shape} vs {det.std_.shape}")
        det.n_features_in_ = det.mean_.size
        return det

    def out_of_band(self, X: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """Which samples of each cycle leave the band ``mean +/- eps std``.

        Samples that are NaN in ``X`` or in the reference count as in band.
        """
        check_is_fitted(self, ["mean_", "std_"])
        data = validate_data(self, X, ensure_all_finite="allow-nan", dtype=np.float64, reset=False)
        with np.errstate(invalid="ignore"):
            outside = np.abs(data - self.mean_) > self.eps * self.std_
        return np.asarray(outside & np.isfinite(data) & np.isfinite(self.mean_), dtype=np.bool_)

    def score_samples(self, X: npt.ArrayLike) -> FloatArray:
        """Fraction of each cycle's valid samples that is out of band [-]."""
        check_is_fitted(self, ["mean_", "std_"])
        data = validate_data(self, X, ensure_all_finite="allow-nan", dtype=np.float64, reset=False)
        outside = self.out_of_band(data)
        valid = np.isfinite(data) & np.isfinite(self.mean_)
        n_valid = np.maximum(np.sum(valid, axis=1), 1)
        return np.asarray(np.sum(outside, axis=1) / n_valid, dtype=np.float64)

    def decision_function(self, X: npt.ArrayLike) -> FloatArray:
        """Out-of-band fraction minus the alarm fraction; positive means alarm [-]."""
        return self.score_samples(X) - self.alarm_fraction

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[np.int64]:
        """1 for a cycle with more than ``alarm_fraction`` of its samples out of band, else 0."""
        return (self.decision_function(X) > 0).astype(np.int64)

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        tags.requires_fit = True
        return tags
