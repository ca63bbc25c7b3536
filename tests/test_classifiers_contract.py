"""Every classifier of the dissertation passes scikit-learn's estimator checks."""

from __future__ import annotations

from sklearn.utils.estimator_checks import parametrize_with_checks

from pneufdd.classifiers import (
    GaussianBayesClassifier,
    MinimumDistanceClassifier,
    NearestNeighbourClassifier,
    SignTableClassifier,
    VectorizedMap,
    VoronoiNeighbourClassifier,
    WaveletTransformer,
)


@parametrize_with_checks(
    [
        MinimumDistanceClassifier(),
        MinimumDistanceClassifier(metric="mahalanobis"),
        NearestNeighbourClassifier(),
        NearestNeighbourClassifier(n_neighbors=3, metric="mahalanobis"),
        GaussianBayesClassifier(),
        GaussianBayesClassifier(covariance="diagonal"),
        GaussianBayesClassifier(covariance="pooled"),
        SignTableClassifier(),
        VectorizedMap(),
        VoronoiNeighbourClassifier(),
        WaveletTransformer(),
    ]
)
def test_sklearn_contract(estimator, check):
    check(estimator)
