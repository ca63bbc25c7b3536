"""Shared helpers of the classifiers: parameter checks and the pooled covariance."""

from __future__ import annotations

import numpy as np

from pneufdd.array_types import FloatArray, IntArray

METRICS = ("euclidean", "mahalanobis")


def check_metric(metric: object) -> None:
    """Raise ValueError unless ``metric`` is one of :data:`METRICS`."""
    if metric not in METRICS:
        raise ValueError(f"metric: received {metric!r}; allowed: {list(METRICS)}")


def pooled_covariance(data: FloatArray, codes: IntArray, shrinkage: float) -> FloatArray:
    """Pooled within-class covariance, shrunk towards its diagonal [feature units^2].

    Examples
    --------
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [10.0, 1.0], [12.0, 1.0]])
    >>> pooled_covariance(x, np.array([0, 0, 1, 1]), 0.0).tolist()
    [[2.0, 0.0], [0.0, 0.0]]
    """
    if not 0.0 <= shrinkage <= 1.0:
        raise ValueError(f"shrinkage: received {shrinkage!r}; allowed: [0, 1]")
    centred = data.copy()
    for k in np.unique(codes):
        centred[codes == k] -= data[codes == k].mean(axis=0)
    dof = max(data.shape[0] - np.unique(codes).size, 1)
    cov = centred.T @ centred / dof
    return np.asarray((1.0 - shrinkage) * cov + shrinkage * np.diag(np.diag(cov)))


def pooled_whitener(data: FloatArray, codes: IntArray, shrinkage: float) -> FloatArray:
    """``W`` with ``W W^T = Sigma^-1`` for the pooled covariance (``x @ W`` whitens).

    Directions without spread get a floor of 1e-12 of the largest variance, so that the
    inverse exists (they then dominate the distance, as the Mahalanobis metric says).
    """
    cov = pooled_covariance(data, codes, shrinkage)
    values, vectors = np.linalg.eigh(cov)
    floor = max(float(values.max()) if values.size else 0.0, 1e-300) * 1e-12
    values = np.maximum(values, floor)
    return np.asarray(vectors / np.sqrt(values)[None, :])
