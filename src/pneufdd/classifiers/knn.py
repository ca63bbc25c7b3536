"""k-nearest-neighbour rule with Euclidean or Mahalanobis distance (section 5.3.2).

A query takes the majority class of its ``k`` nearest training vectors; the
dissertation's nearest-neighbour rule is ``k = 1`` (eq. 5.20 applied to single
training vectors). The Mahalanobis distance
:math:`\\sqrt{(x - c)^T \\Sigma^{-1} (x - c)}` uses the pooled within-class covariance
(eq. 5.16 pooled over classes, as in eq. 5.19), computed as a Euclidean distance
after whitening ``x -> x W`` with ``W W^T = Sigma^-1``; the neighbour search itself is
scikit-learn's :class:`~sklearn.neighbors.NearestNeighbors`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.neighbors import NearestNeighbors
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray
from pneufdd.classifiers._common import check_metric, pooled_whitener

__all__ = ["NearestNeighbourClassifier"]


class NearestNeighbourClassifier(ClassifierMixin, BaseEstimator):  # type: ignore[misc]
    """k-NN majority vote with Euclidean or Mahalanobis distance (section 5.3.2).

    Parameters
    ----------
    n_neighbors : int
        Neighbours that vote (1: the nearest-neighbour rule) [-].
    metric : {"euclidean", "mahalanobis"}
        Distance.
    shrinkage : float
        Mahalanobis only: shrinkage of the pooled covariance towards its diagonal [-].

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    whitener_ : ndarray, shape (n_features, n_features)
        ``W`` with ``W W^T = Sigma^-1`` (identity for Euclidean).

    Examples
    --------
    >>> X = [[0.0, 0.0], [0.1, 0.0], [1.0, 1.0], [1.1, 1.0]]
    >>> knn = NearestNeighbourClassifier(n_neighbors=1).fit(X, [0, 0, 1, 1])
    >>> knn.predict([[0.9, 0.9]]).tolist()
    [1]
    """

    def __init__(self, n_neighbors: int = 1, metric: str = "euclidean", shrinkage: float = 0.1):
        self.n_neighbors = n_neighbors
        self.metric = metric
        self.shrinkage = shrinkage

    def fit(self, X: npt.ArrayLike, y: npt.ArrayLike) -> NearestNeighbourClassifier:
        """Store the (whitened) training vectors."""
        check_metric(self.metric)
        if isinstance(self.n_neighbors, bool) or not isinstance(self.n_neighbors, int | np.integer):
            raise ValueError(f"n_neighbors: received {self.n_neighbors!r}; allowed: integer >= 1")
        if self.n_neighbors < 1:
            raise ValueError(f"n_neighbors: received {self.n_neighbors!r}; allowed: integer >= 1")
        data, labels = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(labels)
        self.classes_, self.y_ = np.unique(labels, return_inverse=True)
        if self.metric == "mahalanobis":
            self.whitener_ = pooled_whitener(data, self.y_, self.shrinkage)
        else:
            self.whitener_ = np.eye(data.shape[1])
        k = min(int(self.n_neighbors), data.shape[0])
        self.search_ = NearestNeighbors(n_neighbors=k, algorithm="brute").fit(data @ self.whitener_)
        return self

    def predict_proba(self, X: npt.ArrayLike) -> FloatArray:
        """Share of the ``k`` neighbours' votes for each class [-]."""
        check_is_fitted(self, "search_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        _, index = self.search_.kneighbors(data @ self.whitener_)
        votes = np.zeros((data.shape[0], self.classes_.size))
        for col in range(index.shape[1]):
            np.add.at(votes, (np.arange(data.shape[0]), self.y_[index[:, col]]), 1.0)
        return np.asarray(votes / index.shape[1])

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[Any]:
        """Majority class of the ``k`` nearest training vectors (ties: first class)."""
        proba = self.predict_proba(X)
        return np.asarray(self.classes_[np.argmax(proba, axis=1)])
