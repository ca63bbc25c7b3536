"""Vectorized map (section 5.3.4, Fig. 5.18, eqs. 5.23-5.24).

The axes are features of consumed air (eq. 4.17: air per stroke or per step),
each normalised by its leak-free value, so that the leak-free machine sits at
``(1, 1, ...)`` and a leak is a **vector** from there to its cluster's centre. Each
class (a location and level, ``"DNC_A@2"``) is one cluster. Combined leaks add up as
vectors (eq. 5.23, :math:`\\vec L = \\vec L_1 + \\vec L_2`, and eq. 5.24 in N
dimensions): :meth:`VectorizedMap.combined_vector` predicts where a combination
lies from its single-leak clusters.

The features are ranked by separating power (Fisher's ratio: spread of the class
centres over the pooled within-class spread). A query is located **stepwise**: with
the two best features first; the answer is unambiguous when a single cluster lies
within ``radius`` pooled standard deviations of it (or, when none does, the nearest
is ``radius`` nearer than the second); otherwise the next feature is added, until
the answer is unambiguous or the features are used up (then the nearest cluster).
:meth:`VectorizedMap.locate` also returns how many clusters were still in reach
when it stopped (the ambiguity group's size) and how many axes were needed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray

__all__ = ["VectorizedMap"]


class VectorizedMap(ClassifierMixin, BaseEstimator):  # type: ignore[misc]
    """Normalised-air vector map with stepwise feature addition (section 5.3.4).

    Parameters
    ----------
    normal_class : str or int
        Label of the leak-free runs, whose mean is the normalisation (1 on every
        axis). Without such a class the mean of all training vectors is used.
    radius : float
        A cluster is in reach of a query within this many pooled within-class
        standard deviations (Euclidean in the scaled space) [-].
    min_features : int
        Features used in the first step (two in the dissertation) [-].

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    scale_ : ndarray, shape (n_features,)
        Leak-free value of each feature (the normalisation) [feature units].
    centres_ : ndarray, shape (n_classes, n_features)
        Cluster centres in normalised units [-].
    vectors_ : ndarray, shape (n_classes, n_features)
        Leak vectors: centre minus the leak-free point [-].
    spread_ : ndarray, shape (n_features,)
        Pooled within-class standard deviation of each normalised feature [-].
    order_ : ndarray of int
        Features by decreasing Fisher ratio.

    Examples
    --------
    >>> X = [[10.0, 20.0], [10.0, 20.0], [15.0, 20.0], [15.0, 20.0], [10.0, 30.0], [10.0, 30.0]]
    >>> y = ["none", "none", "A@2", "A@2", "B@2", "B@2"]
    >>> vmap = VectorizedMap().fit(X, y)
    >>> np.round(vmap.vector("A@2"), 2).tolist(), np.round(vmap.vector("B@2"), 2).tolist()
    ([0.5, 0.0], [0.0, 0.5])
    >>> np.round(vmap.combined_vector(["A@2", "B@2"]), 2).tolist()
    [0.5, 0.5]
    """

    def __init__(
        self, normal_class: str | int = "none", radius: float = 3.0, min_features: int = 2
    ):
        self.normal_class = normal_class
        self.radius = radius
        self.min_features = min_features

    def fit(self, X: npt.ArrayLike, y: npt.ArrayLike) -> VectorizedMap:
        """Normalise, find the cluster centres and rank the features."""
        if not np.isfinite(self.radius) or self.radius <= 0:
            raise ValueError(f"radius: received {self.radius!r}; allowed: > 0")
        if isinstance(self.min_features, bool) or not isinstance(self.min_features, int):
            raise ValueError(f"min_features: received {self.min_features!r}; allowed: int >= 1")
        if self.min_features < 1:
            raise ValueError(f"min_features: received {self.min_features!r}; allowed: int >= 1")
        data, labels = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(labels)
        self.classes_, codes = np.unique(labels, return_inverse=True)
        normal = np.flatnonzero(self.classes_ == self.normal_class)
        ref = data[codes == normal[0]] if normal.size else data
        scale = ref.mean(axis=0)
        tiny = 1e-12 * max(float(np.max(np.abs(data))), 1e-300)
        self.scale_ = np.where(np.abs(scale) > tiny, scale, 1.0)
        z = data / self.scale_
        k = self.classes_.size
        self.centres_ = np.vstack([z[codes == c].mean(axis=0) for c in range(k)])
        origin = self.centres_[normal[0]] if normal.size else np.ones(data.shape[1])
        self.vectors_ = self.centres_ - origin
        within = np.zeros(data.shape[1])
        for c in range(k):
            within += np.sum((z[codes == c] - self.centres_[c]) ** 2, axis=0)
        spread = np.sqrt(within / max(data.shape[0] - k, 1))
        between = np.var(self.centres_, axis=0)
        floor = 1e-9 * max(float(np.max(spread)), 1e-12)
        self.spread_ = np.maximum(spread, floor)
        fisher = between / self.spread_**2
        self.order_ = np.argsort(-fisher, kind="stable").astype(np.int64)
        self.fisher_ = fisher
        return self

    def vector(self, label: Any) -> FloatArray:
        """Leak vector of class ``label`` (its centre minus the leak-free point) [-]."""
        check_is_fitted(self, "vectors_")
        where = np.flatnonzero(self.classes_ == label)
        if where.size == 0:
            raise ValueError(f"class: received {label!r}; allowed: {self.classes_.tolist()}")
        return np.asarray(self.vectors_[int(where[0])])

    def combined_vector(self, labels: Sequence[Any]) -> FloatArray:
        """Vector sum of single-leak vectors: where a combination should lie (eq. 5.23-5.24)."""
        return np.asarray(np.sum([self.vector(lab) for lab in labels], axis=0))

    def _scaled(self, X: npt.ArrayLike) -> FloatArray:
        check_is_fitted(self, "centres_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        return np.asarray(data / self.scale_ / self.spread_)

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[Any]:
        """Cluster of each query, adding features stepwise until unambiguous."""
        answer, _, _ = self.locate(X)
        return answer

    def locate(
        self, X: npt.ArrayLike
    ) -> tuple[npt.NDArray[Any], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """Stepwise location of each query.

        Returns
        -------
        label : ndarray
            Cluster (class) of each query.
        in_reach : ndarray of int
            Clusters within ``radius`` when the search stopped (at least 1): the
            ambiguity group's size [-].
        features_used : ndarray of int
            Axes needed [-].
        """
        z = self._scaled(X)
        centres = self.centres_ / self.spread_
        n, p = z.shape
        first = min(self.min_features, p)
        answer = np.zeros(n, dtype=np.int64)
        reach = np.zeros(n, dtype=np.int64)
        used = np.zeros(n, dtype=np.int64)
        for i in range(n):
            for m in range(first, p + 1):
                axes = self.order_[:m]
                d = np.sqrt(np.sum((centres[:, axes] - z[i, axes]) ** 2, axis=1))
                ranked = np.argsort(d, kind="stable")
                inside = int(np.sum(d <= self.radius))
                gap = d[ranked[1]] - d[ranked[0]] if d.size > 1 else np.inf
                answer[i], reach[i], used[i] = ranked[0], max(inside, 1), m
                if inside == 1 or (inside == 0 and gap > self.radius):
                    break
        return np.asarray(self.classes_[answer]), reach, used
