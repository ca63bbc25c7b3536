"""The classifiers against peer libraries and the dissertation's own numbers."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.discriminant_analysis import QuadraticDiscriminantAnalysis
from sklearn.naive_bayes import GaussianNB
from sklearn.neighbors import KNeighborsClassifier, NearestCentroid, NearestNeighbors
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from pneufdd.classifiers import (
    GaussianBayesClassifier,
    MinimumDistanceClassifier,
    NearestNeighbourClassifier,
    SignTableClassifier,
    VectorizedMap,
    VoronoiNeighbourClassifier,
    VoronoiSearch,
    WaveletTransformer,
    voronoi_boxes,
)
from pneufdd.classifiers._common import pooled_covariance
from pneufdd.features.wavelet import decompose, summarise


def _blobs(rng, n_per=40, p=3, k=4, spread=1.0):
    centres = rng.normal(scale=4.0, size=(k, p))
    mix = rng.normal(size=(p, p))
    X = np.vstack([c + spread * rng.normal(size=(n_per, p)) @ mix for c in centres])
    y = np.repeat(np.arange(k), n_per)
    return X, y


@pytest.mark.parametrize(("n", "dim"), [(150, 2), (120, 3), (60, 5)])
def test_voronoi_is_exactly_brute_force_on_10000_queries(n, dim):
    rng = np.random.default_rng(96_000_001 + dim)
    train = rng.normal(size=(n, dim))
    queries = rng.normal(scale=1.3, size=(10_000, dim))  # also outside the data's hull
    search = VoronoiSearch().fit(train)
    dist, idx = search.query(queries)
    ref_dist, ref_idx = (
        NearestNeighbors(n_neighbors=1, algorithm="brute").fit(train).kneighbors(queries)
    )
    assert np.array_equal(idx, ref_idx[:, 0])
    np.testing.assert_allclose(dist, ref_dist[:, 0], rtol=1e-9)
    # fewer distances than a full search (n per query)
    assert search.n_distance_computations_ < 0.5 * n * 10_000


def test_voronoi_boxes_of_a_grid_are_the_cells():
    # a 5 x 5 grid of unit spacing: an inner point's cell is the unit square around it
    g = np.array([[i, j] for i in range(5) for j in range(5)], dtype=float)
    lo, hi = voronoi_boxes(g)
    inner = 2 * 5 + 2
    np.testing.assert_allclose(lo[inner], [1.5, 1.5], atol=1e-7)
    np.testing.assert_allclose(hi[inner], [2.5, 2.5], atol=1e-7)
    assert np.isinf(lo[0]).all()  # a corner's cell is unbounded


def test_voronoi_classifier_equals_1nn():
    rng = np.random.default_rng(3)
    X, y = _blobs(rng, p=2)
    q = rng.normal(scale=5.0, size=(500, 2))
    ours = VoronoiNeighbourClassifier().fit(X, y).predict(q)
    ref = KNeighborsClassifier(n_neighbors=1, algorithm="brute").fit(X, y).predict(q)
    assert np.array_equal(ours, ref)


def test_minimum_distance_equals_nearest_centroid():
    rng = np.random.default_rng(4)
    X, y = _blobs(rng)
    q = rng.normal(scale=5.0, size=(2000, 3))
    ours = MinimumDistanceClassifier().fit(X, y)
    ref = NearestCentroid().fit(X, y)
    np.testing.assert_allclose(ours.templates_, ref.centroids_)
    assert np.array_equal(ours.predict(q), ref.predict(q))


def test_mahalanobis_minimum_distance_is_lda_with_equal_priors():
    # eq. 5.19 is the Bayes rule (5.18) with one covariance and equal priors
    rng = np.random.default_rng(5)
    X, y = _blobs(rng, n_per=60)
    q = rng.normal(scale=5.0, size=(2000, 3))
    ours = MinimumDistanceClassifier(metric="mahalanobis", shrinkage=0.0).fit(X, y).predict(q)
    bayes = GaussianBayesClassifier(covariance="pooled", priors=[0.25] * 4, var_smoothing=0.0)
    assert np.array_equal(ours, bayes.fit(X, y).predict(q))


def test_knn_euclidean_and_mahalanobis_match_scikit_learn():
    rng = np.random.default_rng(6)
    X, y = _blobs(rng)
    q = rng.normal(scale=5.0, size=(1000, 3))
    for k in (1, 5):
        ours = NearestNeighbourClassifier(n_neighbors=k).fit(X, y).predict_proba(q)
        ref = KNeighborsClassifier(n_neighbors=k, algorithm="brute").fit(X, y).predict_proba(q)
        np.testing.assert_allclose(ours, ref)
    vi = np.linalg.inv(pooled_covariance(X, y, 0.0))
    ours = NearestNeighbourClassifier(n_neighbors=3, metric="mahalanobis", shrinkage=0.0)
    ref = KNeighborsClassifier(
        n_neighbors=3, algorithm="brute", metric="mahalanobis", metric_params={"VI": vi}
    )
    np.testing.assert_allclose(ours.fit(X, y).predict_proba(q), ref.fit(X, y).predict_proba(q))


def test_gaussian_bayes_full_equals_qda():
    rng = np.random.default_rng(7)
    X, y = _blobs(rng, n_per=50)
    q = rng.normal(scale=5.0, size=(1000, 3))
    # scikit-learn 1.9's QDA estimates the class covariances with ddof 0
    ours = GaussianBayesClassifier(covariance="full", var_smoothing=0.0, ddof=0).fit(X, y)
    ref = QuadraticDiscriminantAnalysis(store_covariance=True).fit(X, y)
    np.testing.assert_allclose(ours.covariances_, ref.covariance_, rtol=1e-10)
    np.testing.assert_allclose(ours.predict_proba(q), ref.predict_proba(q), atol=1e-9)
    assert np.array_equal(ours.predict(q), ref.predict(q))


def test_gaussian_bayes_diagonal_equals_gaussian_nb():
    rng = np.random.default_rng(8)
    X, y = _blobs(rng, n_per=50)
    q = rng.normal(scale=5.0, size=(1000, 3))
    ours = GaussianBayesClassifier(covariance="diagonal", ddof=0).fit(X, y)
    ref = GaussianNB().fit(X, y)
    np.testing.assert_allclose(ours.predict_log_proba(q), ref.predict_log_proba(q), atol=1e-8)


def test_sign_table_recovers_a_planted_table():
    # three leak classes moving features like the extend/retract/supply rows
    rng = np.random.default_rng(9)
    table = {"none": [0, 0, 0, 0], "A": [1, -1, 0, 1], "B": [-1, 0, 1, 1], "S": [0, -1, -1, 0]}
    X = np.vstack([10.0 * np.array(s) + rng.normal(size=(30, 4)) for s in table.values()])
    y = np.repeat(list(table), 30)
    clf = SignTableClassifier().fit(X, y)
    char = {1: "+", 0: "0", -1: "-"}
    expected = {k: "".join(char[v] for v in s) for k, s in table.items()}
    assert clf.table_strings() == expected
    q = np.vstack([10.0 * np.array(s) + rng.normal(size=(200, 4)) for s in table.values()])
    pred = clf.predict(q).reshape(4, 200)
    # a leak cycle is mistaken only when noise flips two of its unchanged features
    assert np.all(np.mean(pred[1:] == np.array(["A", "B", "S"])[:, None], axis=1) >= 0.97)
    # a leak-free cycle is called leak-free when no feature leaves +/- 2 sigma:
    # probability 0.9545^4 = 0.830
    assert np.mean(pred[0] == "none") == pytest.approx(0.9545**4, abs=0.06)


def test_vectorized_map_sum_of_vectors_and_stepwise_features():
    # leak-free air 1.0 / 2.0 SL; an extend leak adds on axis 0, a retract leak on axis 1,
    # both add up (eq. 5.23); axis 2 is noise only, so two features suffice
    rng = np.random.default_rng(10)
    base = np.array([1.0, 2.0, 5.0])
    shifts = {"none": [0, 0, 0], "A@2": [0.3, 0, 0], "B@5": [0, 0.8, 0], "A@2+B@5": [0.3, 0.8, 0]}
    X = np.vstack([base + s + 0.01 * rng.normal(size=(40, 3)) for s in shifts.values()])
    y = np.repeat(list(shifts), 40)
    vmap = VectorizedMap().fit(X, y)
    np.testing.assert_allclose(vmap.vector("A@2"), [0.3, 0.0, 0.0], atol=0.01)
    total = vmap.combined_vector(["A@2", "B@5"])
    both = vmap.vector("A@2+B@5")
    assert np.linalg.norm(both - total) / np.linalg.norm(total) < 0.02
    assert set(vmap.order_[:2].tolist()) == {0, 1}
    q = base + np.array([0.3, 0.0, 0.0]) + 0.01 * rng.normal(size=(10, 3))
    label, reach, used = vmap.locate(q)
    assert label.tolist() == ["A@2"] * 10
    assert reach.tolist() == [1] * 10
    assert used.tolist() == [2] * 10


def test_wavelet_transformer_agrees_with_the_feature_registry():
    rng = np.random.default_rng(11)
    rows = rng.normal(size=(3, 200)).cumsum(axis=1)
    wt = WaveletTransformer().fit(rows)
    out = wt.transform(rows)
    names = wt.get_feature_names_out().tolist()
    for r, row in enumerate(rows):
        bands = decompose(row, "db4")
        for band, coeffs in bands.items():
            for how, value in summarise(coeffs).items():
                assert out[r, names.index(f"{band}_{how}")] == pytest.approx(value, rel=1e-12)


def test_classifiers_in_a_pipeline():
    rng = np.random.default_rng(12)
    X, y = _blobs(rng, n_per=30, spread=0.3)
    X = X * np.array([1e5, 1.0, 1e-3])  # Pa, SL, kg/s
    pipe = make_pipeline(StandardScaler(), GaussianBayesClassifier()).fit(X, y)
    assert pipe.score(X, y) > 0.95
