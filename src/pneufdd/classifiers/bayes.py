"""Gaussian Bayes classifier (eqs. 5.13-5.18).

Each class :math:`\\omega_i` is a multivariate normal density (5.15) with mean
:math:`\\mu_i` and covariance :math:`\\Sigma_i` (5.16); a vector goes to the class of
the largest discriminant

.. math:: g_i(x) = \\ln P(\\omega_i) - \\tfrac{l}{2} \\ln 2\\pi - \\tfrac12 \\ln|\\Sigma_i|
          - \\tfrac12 (x - \\mu_i)^T \\Sigma_i^{-1} (x - \\mu_i)          \\qquad (5.18)

(eq. 5.18 prints :math:`\\tfrac12 \\ln 2\\pi`; the normal density of dimension ``l``
has :math:`\\tfrac{l}{2}`, the same for every class, so the decision is unchanged).
``covariance`` chooses :math:`\\Sigma_i`: ``"full"`` (eq. 5.16 per class; the model of
scikit-learn's QuadraticDiscriminantAnalysis), ``"diagonal"`` (independent
features; GaussianNB's model) or ``"pooled"`` (one covariance for all classes, the
assumption that leads to eq. 5.19). Variances get ``var_smoothing`` times the largest
feature variance added, as GaussianNB does, so that a feature constant within a
class does not make :math:`\\Sigma_i` singular.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.special import logsumexp
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray

__all__ = ["GaussianBayesClassifier"]

COVARIANCES = ("full", "diagonal", "pooled")


class GaussianBayesClassifier(ClassifierMixin, BaseEstimator):  # type: ignore[misc]
    """Bayes decision with Gaussian class densities (eqs. 5.15-5.18).

    Parameters
    ----------
    covariance : {"full", "diagonal", "pooled"}
        Covariance model of the classes.
    priors : array_like, optional
        :math:`P(\\omega_i)` in the order of ``classes_``; the training shares when None.
    var_smoothing : float
        Added to the variances: this fraction of the largest feature variance [-].
    ddof : int
        Delta degrees of freedom of the covariance estimates (1: unbiased, as
        QuadraticDiscriminantAnalysis; 0: maximum likelihood, as GaussianNB) [-].

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    means_ : ndarray, shape (n_classes, n_features)
        :math:`\\mu_i` [feature units].
    covariances_ : ndarray, shape (n_classes, n_features, n_features)
        :math:`\\Sigma_i` [feature units^2].
    priors_ : ndarray, shape (n_classes,)
        :math:`P(\\omega_i)` [-].

    Examples
    --------
    >>> X = [[0.0], [0.5], [1.0], [4.0], [5.0], [6.0]]
    >>> clf = GaussianBayesClassifier().fit(X, [0, 0, 0, 1, 1, 1])
    >>> clf.predict([[2.0], [3.5]]).tolist()
    [0, 1]
    """

    def __init__(
        self,
        covariance: str = "full",
        priors: npt.ArrayLike | None = None,
        var_smoothing: float = 1e-9,
        ddof: int = 1,
    ):
        self.covariance = covariance
        self.priors = priors
        self.var_smoothing = var_smoothing
        self.ddof = ddof

    def fit(self, X: npt.ArrayLike, y: npt.ArrayLike) -> GaussianBayesClassifier:
        """Estimate each class's mean, covariance and prior."""
        if self.covariance not in COVARIANCES:
            raise ValueError(f"covariance: received {self.covariance!r}; allowed: {COVARIANCES}")
        if not np.isfinite(self.var_smoothing) or self.var_smoothing < 0:
            raise ValueError(f"var_smoothing: received {self.var_smoothing!r}; allowed: >= 0")
        data, labels = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(labels)
        self.classes_, codes = np.unique(labels, return_inverse=True)
        n_classes, n_features = self.classes_.size, data.shape[1]
        epsilon = self.var_smoothing * float(np.max(np.var(data, axis=0)))
        means = np.zeros((n_classes, n_features))
        covs = np.zeros((n_classes, n_features, n_features))
        pooled = np.zeros((n_features, n_features))
        for k in range(n_classes):
            rows = data[codes == k]
            means[k] = rows.mean(axis=0)
            centred = rows - means[k]
            pooled += centred.T @ centred
            dof = max(rows.shape[0] - self.ddof, 1)
            covs[k] = centred.T @ centred / dof
        if self.covariance == "pooled":
            covs[:] = pooled / max(data.shape[0] - self.ddof * n_classes, 1)
        if self.covariance == "diagonal":
            covs = np.stack([np.diag(np.diag(c)) for c in covs])
        covs += epsilon * np.eye(n_features)[None]
        # a class whose covariance is still singular (too few vectors): floor its spectrum
        for k in range(n_classes):
            values, vectors = np.linalg.eigh(covs[k])
            floor = max(float(values.max()), 1e-300) * 1e-10
            if values.min() < floor:
                covs[k] = (vectors * np.maximum(values, floor)) @ vectors.T
        if self.priors is None:
            priors = np.bincount(codes, minlength=n_classes) / data.shape[0]
        else:
            priors = np.asarray(self.priors, dtype=np.float64)
            if priors.shape != (n_classes,) or np.any(priors < 0) or priors.sum() <= 0:
                raise ValueError(
                    f"priors: received {self.priors!r}; allowed: {n_classes} non-negative values"
                )
            priors = priors / priors.sum()
        self.means_, self.covariances_, self.priors_ = means, covs, priors
        return self

    def _discriminants(self, X: npt.ArrayLike) -> FloatArray:
        """:math:`g_i(x)` of eq. 5.18 for every class."""
        check_is_fitted(self, "means_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        n_features = data.shape[1]
        out = np.empty((data.shape[0], self.classes_.size))
        with np.errstate(divide="ignore"):
            log_priors = np.log(self.priors_)
        for k in range(self.classes_.size):
            chol = np.linalg.cholesky(self.covariances_[k])
            z = np.linalg.solve(chol, (data - self.means_[k]).T)
            logdet = 2.0 * np.sum(np.log(np.diag(chol)))
            out[:, k] = (
                log_priors[k]
                - 0.5 * n_features * np.log(2.0 * np.pi)
                - 0.5 * logdet
                - 0.5 * np.sum(z**2, axis=0)
            )
        return out

    def predict_log_proba(self, X: npt.ArrayLike) -> FloatArray:
        """:math:`\\ln P(\\omega_i | x)` (eq. 5.12 with the Gaussian densities)."""
        g = self._discriminants(X)
        return np.asarray(g - logsumexp(g, axis=1, keepdims=True))

    def predict_proba(self, X: npt.ArrayLike) -> FloatArray:
        """:math:`P(\\omega_i | x)` [-]."""
        return np.asarray(np.exp(self.predict_log_proba(X)))

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[Any]:
        """Class of the largest discriminant (eq. 5.14)."""
        g = self._discriminants(X)
        return np.asarray(self.classes_[np.argmax(g, axis=1)])
