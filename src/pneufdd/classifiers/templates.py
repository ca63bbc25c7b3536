"""Minimum-distance template classifier (eqs. 5.19-5.22).

Each class is represented by its template, the mean :math:`\\mu_i` of its training
vectors (for signals: the averaged sampled curves :math:`\\bar S_{i,j}` of eq. 5.21).
An unknown vector goes to the class of the nearest template. With equal priors and a
covariance :math:`\\Sigma` shared by all classes the Bayes discriminant (5.18)
reduces to

.. math:: g_i(x) = -\\tfrac12 (x - \\mu_i)^T \\Sigma^{-1} (x - \\mu_i)      \\qquad (5.19)

(``metric="mahalanobis"``, :math:`\\Sigma` the pooled within-class covariance), and
with :math:`\\Sigma = \\sigma^2 I` to the Euclidean distance

.. math:: d_\\epsilon = \\|x - \\mu_i\\|                                  \\qquad (5.20)

(``metric="euclidean"``), the distance D of eq. 5.22 when ``x`` holds the samples of
the four signals of a cycle.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray
from pneufdd.classifiers._common import check_metric, pooled_whitener

__all__ = ["MinimumDistanceClassifier"]


class MinimumDistanceClassifier(ClassifierMixin, BaseEstimator):  # type: ignore[misc]
    """Nearest class template, Euclidean (eq. 5.20/5.22) or Mahalanobis (eq. 5.19).

    Parameters
    ----------
    metric : {"euclidean", "mahalanobis"}
        Distance to the templates.
    shrinkage : float
        Mahalanobis only: the pooled covariance is shrunk towards its diagonal,
        ``(1 - s) Sigma + s diag(Sigma)``, so that it stays invertible with few
        training vectors [-].

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    templates_ : ndarray, shape (n_classes, n_features)
        Class means :math:`\\mu_i` [feature units].
    whitener_ : ndarray, shape (n_features, n_features)
        Matrix ``W`` with ``W W^T = Sigma^-1`` (identity for Euclidean).

    Examples
    --------
    >>> clf = MinimumDistanceClassifier().fit([[0.0], [0.2], [1.0], [1.2]], ["a", "a", "b", "b"])
    >>> clf.templates_.ravel().tolist(), clf.predict([[0.7]]).tolist()
    ([0.1, 1.1], ['b'])
    """

    def __init__(self, metric: str = "euclidean", shrinkage: float = 0.1):
        self.metric = metric
        self.shrinkage = shrinkage

    def fit(self, X: npt.ArrayLike, y: npt.ArrayLike) -> MinimumDistanceClassifier:
        """Learn one template (mean vector) per class."""
        check_metric(self.metric)
        data, labels = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(labels)
        self.classes_, codes = np.unique(labels, return_inverse=True)
        self.templates_ = np.vstack(
            [data[codes == k].mean(axis=0) for k in range(self.classes_.size)]
        )
        if self.metric == "mahalanobis":
            self.whitener_ = pooled_whitener(data, codes, self.shrinkage)
        else:
            self.whitener_ = np.eye(data.shape[1])
        return self

    def decision_function(self, X: npt.ArrayLike) -> FloatArray:
        """Discriminant :math:`g_i(x) = -d_i^2 / 2` of every class (eq. 5.19)."""
        check_is_fitted(self, "templates_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        z = data @ self.whitener_
        t = self.templates_ @ self.whitener_
        d2 = np.sum(z**2, axis=1)[:, None] - 2.0 * z @ t.T + np.sum(t**2, axis=1)[None, :]
        g = -0.5 * np.maximum(d2, 0.0)
        out = g[:, 1] - g[:, 0] if self.classes_.size == 2 else g
        return np.asarray(out, dtype=np.float64)

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[Any]:
        """Class of the nearest template."""
        g = self.decision_function(X)
        if g.ndim == 1:
            return np.asarray(self.classes_[(g > 0).astype(np.int64)])
        return np.asarray(self.classes_[np.argmax(g, axis=1)])
