"""Sign-table (logistic table) classifier learned from data (Tables 4.4-4.5).

Table 4.5 lists, for every leak location, the direction (+, -, 0) in which each
feature of Table 4.4 moves when a leak grows there. This classifier learns such a
table from labelled runs: for each class, the sign of the difference between the
class mean and the leak-free mean of each feature, kept only where the difference
exceeds ``threshold`` leak-free standard deviations (else 0). A query is turned into
its own sign vector against the leak-free mean (same threshold) and assigned the
class whose row agrees in most features (ties: the class listed first); a query
with no significant change is leak-free. The learned table is ``table_`` and prints
like Table 4.5 with :meth:`SignTableClassifier.table_strings`.

Without a leak-free class in the training labels the reference is the mean and
spread of all training vectors (then the table shows how each class differs from
the average, and no query is called leak-free).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray

__all__ = ["SignTableClassifier"]


class SignTableClassifier(ClassifierMixin, BaseEstimator):  # type: ignore[misc]
    """Learned logistic table of Table 4.5 and nearest-row matching.

    Parameters
    ----------
    normal_class : str or int
        Label of the leak-free runs (the reference of the signs).
    threshold : float
        A change counts (+ or -) when it exceeds this many leak-free standard
        deviations [-].

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    table_ : ndarray of int, shape (n_classes, n_features)
        Learned signs (+1, 0, -1) of each class; the leak-free row is all 0.
    reference_mean_, reference_std_ : ndarray, shape (n_features,)
        Leak-free mean and standard deviation [feature units].

    Examples
    --------
    >>> X = [[0.0, 0.0], [0.1, -0.1], [5.0, 0.0], [5.1, 0.1], [0.0, -5.0], [0.1, -5.1]]
    >>> y = ["none", "none", "A", "A", "B", "B"]
    >>> clf = SignTableClassifier().fit(X, y)
    >>> clf.table_strings()
    {'A': '+0', 'B': '0-', 'none': '00'}
    >>> clf.predict([[4.0, 0.0], [0.0, 0.05]]).tolist()
    ['A', 'none']
    """

    def __init__(self, normal_class: str | int = "none", threshold: float = 2.0):
        self.normal_class = normal_class
        self.threshold = threshold

    def fit(self, X: npt.ArrayLike, y: npt.ArrayLike) -> SignTableClassifier:
        """Learn the sign of each feature's change for every class."""
        if not np.isfinite(self.threshold) or self.threshold < 0:
            raise ValueError(f"threshold: received {self.threshold!r}; allowed: >= 0")
        data, labels = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(labels)
        self.classes_, codes = np.unique(labels, return_inverse=True)
        normal = np.flatnonzero(self.classes_ == self.normal_class)
        self.normal_index_ = int(normal[0]) if normal.size else -1
        ref = data[codes == self.normal_index_] if normal.size else data
        self.reference_mean_ = ref.mean(axis=0)
        spread = ref.std(axis=0, ddof=1) if ref.shape[0] > 1 else np.zeros(data.shape[1])
        floor = 1e-9 * np.maximum(np.abs(self.reference_mean_), 1e-300)
        self.reference_std_ = np.maximum(spread, floor)
        means = np.vstack([data[codes == k].mean(axis=0) for k in range(self.classes_.size)])
        self.table_ = self._signs(means)
        if normal.size:
            self.table_[self.normal_index_] = 0
        return self

    def _signs(self, values: FloatArray) -> npt.NDArray[np.int64]:
        change = (values - self.reference_mean_) / self.reference_std_
        return np.where(np.abs(change) > self.threshold, np.sign(change), 0).astype(np.int64)

    def decision_function(self, X: npt.ArrayLike) -> FloatArray:
        """Number of features whose sign agrees with each class's row [-]."""
        check_is_fitted(self, "table_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        signs = self._signs(data)
        agree = np.sum(signs[:, None, :] == self.table_[None, :, :], axis=2).astype(np.float64)
        out = agree[:, 1] - agree[:, 0] if self.classes_.size == 2 else agree
        return np.asarray(out, dtype=np.float64)

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[Any]:
        """Class whose sign row agrees most; leak-free when nothing changed."""
        check_is_fitted(self, "table_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        signs = self._signs(data)
        agree = np.sum(signs[:, None, :] == self.table_[None, :, :], axis=2)
        leak = agree.copy()
        if self.normal_index_ >= 0:
            leak[:, self.normal_index_] = -1
        best = np.argmax(leak, axis=1)
        if self.normal_index_ >= 0:
            best = np.where(np.any(signs != 0, axis=1), best, self.normal_index_)
        return np.asarray(self.classes_[best])

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        # a table of signs is a coarse, qualitative rule: on scikit-learn's generic
        # blobs without a leak-free class it is not meant to reach 83 % accuracy
        tags.classifier_tags.poor_score = True
        return tags

    def table_strings(self) -> dict[Any, str]:
        """The learned table as Table 4.5 prints it: one ``+-0`` string per class."""
        check_is_fitted(self, "table_")
        char = {1: "+", 0: "0", -1: "-"}
        return {
            c.item() if hasattr(c, "item") else c: "".join(char[int(s)] for s in row)
            for c, row in zip(self.classes_, self.table_, strict=True)
        }
