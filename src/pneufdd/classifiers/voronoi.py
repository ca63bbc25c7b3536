"""Stepwise Voronoi nearest-neighbour search (section 5.3.5, Fig. 5.19).

Every training vector :math:`c_i` owns a Voronoi cell, the points nearer to it than to
any other training vector:

.. math:: V_i = \\{x : \\|x - c_i\\| \\le \\|x - c_j\\| \\ \\forall j\\}
          = \\{x : (c_j - c_i)^T x \\le (\\|c_j\\|^2 - \\|c_i\\|^2)/2 \\ \\forall j\\}.

The preprocessing step (1) bounds each cell by its box: the smallest and largest value
of every coordinate over the cell, each a linear programme (the cell is a polyhedron;
only its Delaunay neighbours' half-spaces are needed, all points when the
triangulation is degenerate). A cell that is unbounded in a direction gets an
infinite box side. The search step (2) is *stepwise*: the candidate set starts with
all boxes, and each coordinate of the query removes the boxes whose interval on that
axis does not contain it (Fig. 5.19: 3 candidates instead of 25); the nearest
neighbour is then found by a full search among the candidates only.

The query lies in its nearest neighbour's cell, hence in that cell's box, so the
candidates always contain the brute-force answer: the search is **exact**, it only
computes fewer distances (the cost counted in ``n_distance_computations_``).
Ties between equally near training vectors go to the lowest index, as in a full
search that keeps the first minimum.

References
----------
.. [1] Ramasubramanian, V., Paliwal, K. K. (1997). Voronoi projection-based fast
   nearest-neighbor search algorithms: box-search and mapping table-based search
   techniques. Digital Signal Processing 7(4), 260-277.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import linprog
from scipy.spatial import Delaunay, QhullError
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray, IntArray

__all__ = ["VoronoiNeighbourClassifier", "VoronoiSearch", "voronoi_boxes"]


_MAX_DELAUNAY_DIM = 6
"""Above this dimension the Delaunay triangulation costs more than it saves."""


def _neighbours(points: FloatArray) -> list[IntArray]:
    """Delaunay neighbours of each point (all other points when degenerate)."""
    n, dim = points.shape
    everyone = [np.delete(np.arange(n, dtype=np.int64), i) for i in range(n)]
    unique = np.unique(points, axis=0).shape[0] == n
    if dim < 2 or dim > _MAX_DELAUNAY_DIM or n <= dim + 1 or not unique:
        return everyone
    try:
        tri = Delaunay(points)
    except QhullError:
        return everyone
    if tri.coplanar.size:  # a point left out of the triangulation: be safe
        return everyone
    indptr, indices = tri.vertex_neighbor_vertices
    return [np.asarray(indices[indptr[i] : indptr[i + 1]], dtype=np.int64) for i in range(n)]


def voronoi_boxes(points: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Bounding box of every point's Voronoi cell (step 1 of section 5.3.5).

    Parameters
    ----------
    points : array_like, shape (n_points, n_features)
        Training vectors [feature units].

    Returns
    -------
    lower, upper : ndarray, shape (n_points, n_features)
        Smallest and largest coordinate over each cell; +/-inf where the cell is
        unbounded [feature units].

    Examples
    --------
    >>> lo, hi = voronoi_boxes([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0], [1.0, 1.0]])
    >>> np.round(lo[4], 6) + 0.0, np.round(hi[4], 6) + 0.0
    (array([0., 0.]), array([2., 2.]))
    """
    c = np.asarray(points, dtype=np.float64)
    n, dim = c.shape
    lower = np.full((n, dim), -np.inf)
    upper = np.full((n, dim), np.inf)
    if n == 1:
        return lower, upper
    norms = np.einsum("ij,ij->i", c, c)
    for i, nb in enumerate(_neighbours(c)):
        same = np.all(c[nb] == c[i], axis=1)
        nb = nb[~same]
        if nb.size == 0:
            continue
        a_ub = c[nb] - c[i]
        b_ub = 0.5 * (norms[nb] - norms[i])
        scale = np.maximum(np.max(np.abs(a_ub), axis=1), 1e-300)
        a_ub, b_ub = a_ub / scale[:, None], b_ub / scale
        for k in range(dim):
            for sign, store in ((1.0, lower), (-1.0, upper)):
                cost = np.zeros(dim)
                cost[k] = sign
                res = linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=(None, None), method="highs")
                if res.status == 0:
                    store[i, k] = float(res.x[k])
    span = np.maximum(np.ptp(c, axis=0), 1.0)
    pad = 1e-9 * span  # the LP's tolerance must never cut the query's own cell
    return lower - pad, upper + pad


class VoronoiSearch(BaseEstimator):  # type: ignore[misc]
    """Exact nearest-neighbour search with the stepwise Voronoi box method (section 5.3.5).

    Attributes
    ----------
    points_ : ndarray, shape (n_points, n_features)
        The training vectors.
    lower_, upper_ : ndarray, shape (n_points, n_features)
        Voronoi-cell boxes (:func:`voronoi_boxes`).
    order_ : ndarray of int
        Axes in the order the stepwise search applies them (most selective first:
        smallest mean box width relative to the data's spread).
    n_distance_computations_ : int
        Distances computed by all :meth:`query` calls so far (a full search computes
        ``n_points`` per query).
    n_queries_ : int
        Queries answered so far.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> train, queries = rng.random((50, 2)), rng.random((200, 2))
    >>> search = VoronoiSearch().fit(train)
    >>> _, idx = search.query(queries)
    >>> brute = np.argmin(((queries[:, None] - train[None]) ** 2).sum(-1), axis=1)
    >>> bool(np.all(idx == brute)), search.n_distance_computations_ < 200 * 50 / 5
    (True, True)
    """

    def fit(self, X: npt.ArrayLike, y: object = None) -> VoronoiSearch:
        """Build the Voronoi boxes of the training vectors ``X``."""
        data = validate_data(self, X, dtype=np.float64)
        self.points_ = np.array(data, dtype=np.float64)
        self.lower_, self.upper_ = voronoi_boxes(self.points_)
        spread = np.maximum(np.ptp(self.points_, axis=0), 1e-300)
        width = np.where(np.isfinite(self.upper_ - self.lower_), self.upper_ - self.lower_, 1e300)
        self.order_ = np.argsort(np.mean(width, axis=0) / spread, kind="stable").astype(np.int64)
        self.n_distance_computations_ = 0
        self.n_queries_ = 0
        return self

    def candidates(self, x: npt.ArrayLike) -> IntArray:
        """Training indices whose boxes contain the query ``x`` (step 1, stepwise)."""
        check_is_fitted(self, "points_")
        q = np.asarray(x, dtype=np.float64).ravel()
        alive = np.arange(self.points_.shape[0], dtype=np.int64)
        for k in self.order_:
            keep = (self.lower_[alive, k] <= q[k]) & (q[k] <= self.upper_[alive, k])
            alive = alive[keep]
            if alive.size <= 1:
                break
        return alive

    def query(self, X: npt.ArrayLike) -> tuple[FloatArray, IntArray]:
        """Nearest training vector of each query (step 2: full search among candidates).

        Returns
        -------
        distance : ndarray, shape (n_queries,)
            Euclidean distance to the nearest training vector [feature units].
        index : ndarray of int, shape (n_queries,)
            Its row in the training data.
        """
        check_is_fitted(self, "points_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        dist = np.empty(data.shape[0])
        index = np.empty(data.shape[0], dtype=np.int64)
        n = self.points_.shape[0]
        chunk = max(1, 2_000_000 // max(n * data.shape[1], 1))
        for lo in range(0, data.shape[0], chunk):
            q = data[lo : lo + chunk]
            # step 1 for a block of queries at once: the boxes containing each query
            inside = np.ones((q.shape[0], n), dtype=bool)
            for k in self.order_:
                inside &= (self.lower_[None, :, k] <= q[:, k, None]) & (
                    q[:, k, None] <= self.upper_[None, :, k]
                )
            empty = ~inside.any(axis=1)
            inside[empty] = True  # only reachable through round-off: search all
            # step 2: distances to the candidates only
            rows, cols = np.nonzero(inside)
            d2 = np.sum((self.points_[cols] - q[rows]) ** 2, axis=1)
            # per query: smallest distance, ties to the lowest index (cols ascend per row)
            order = np.lexsort((cols, d2, rows))
            first = np.ones(order.size, dtype=bool)
            first[1:] = rows[order][1:] != rows[order][:-1]
            best = order[first]
            index[lo : lo + q.shape[0]] = cols[best]
            dist[lo : lo + q.shape[0]] = np.sqrt(d2[best])
            self.n_distance_computations_ += int(rows.size)
        self.n_queries_ += int(data.shape[0])
        return dist, index


class VoronoiNeighbourClassifier(ClassifierMixin, BaseEstimator):  # type: ignore[misc]
    """1-nearest-neighbour classifier on the stepwise Voronoi search (section 5.3.5).

    The answer is exactly the brute-force nearest neighbour's class (eq. 5.20 applied
    to single training vectors); only fewer distances are computed.

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    search_ : VoronoiSearch
        The fitted search structure.

    Examples
    --------
    >>> clf = VoronoiNeighbourClassifier().fit([[0.0, 0.0], [1.0, 1.0]], ["none", "DNC_A"])
    >>> clf.predict([[0.9, 0.8]]).tolist()
    ['DNC_A']
    """

    def fit(self, X: npt.ArrayLike, y: npt.ArrayLike) -> VoronoiNeighbourClassifier:
        """Store the labelled training vectors and build their Voronoi boxes."""
        data, labels = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(labels)
        self.classes_, self.y_ = np.unique(labels, return_inverse=True)
        self.search_ = VoronoiSearch().fit(data)
        return self

    def predict(self, X: npt.ArrayLike) -> npt.NDArray[Any]:
        """The class of each query's nearest training vector."""
        check_is_fitted(self, "search_")
        data = validate_data(self, X, dtype=np.float64, reset=False)
        _, index = self.search_.query(data)
        return np.asarray(self.classes_[self.y_[index]])
