"""The dissertation's classifiers as scikit-learn estimators (sections 5.2.3, 5.3.2-5.3.5).

They learn from labelled runs of one machine (leaks introduced on purpose, the
dissertation's procedure) and work on the feature matrices of
:func:`pneufdd.features.feature_matrix` (in a :class:`~sklearn.pipeline.Pipeline`,
usually after a :class:`~sklearn.preprocessing.StandardScaler`):

=================================  =====================================================
estimator                          method
=================================  =====================================================
:class:`MinimumDistanceClassifier`  class templates, eqs. 5.19-5.22
:class:`NearestNeighbourClassifier` k-NN, Euclidean or Mahalanobis (section 5.3.2)
:class:`GaussianBayesClassifier`    Gaussian Bayes, eqs. 5.15-5.18
:class:`SignTableClassifier`        learned logistic table (Tables 4.4-4.5)
:class:`VectorizedMap`              vectorized map, eqs. 5.23-5.24 (section 5.3.4)
:class:`VoronoiNeighbourClassifier` stepwise Voronoi search (section 5.3.5)
:class:`WaveletTransformer`         DWT band features (section 5.3.3)
:class:`BandDetector`               band detector of eq. 5.21 (from ``diagnosis.detection``)
=================================  =====================================================

The physics-residual detector (section 4.1) needs the twin and lives in
:mod:`pneufdd.diagnosis.detection.residuals`. May import: :mod:`pneufdd.features`,
:mod:`pneufdd.diagnosis` (the band detector) and the layers below; it comes after
``diagnosis`` and ``calibration`` in the import order.
"""

from __future__ import annotations

from pneufdd.classifiers.bayes import GaussianBayesClassifier
from pneufdd.classifiers.knn import NearestNeighbourClassifier
from pneufdd.classifiers.sign_table import SignTableClassifier
from pneufdd.classifiers.templates import MinimumDistanceClassifier
from pneufdd.classifiers.vector_map import VectorizedMap
from pneufdd.classifiers.voronoi import VoronoiNeighbourClassifier, VoronoiSearch, voronoi_boxes
from pneufdd.classifiers.wavelet import WaveletTransformer
from pneufdd.diagnosis.detection.band import BandDetector

__all__ = [
    "BandDetector",
    "GaussianBayesClassifier",
    "MinimumDistanceClassifier",
    "NearestNeighbourClassifier",
    "SignTableClassifier",
    "VectorizedMap",
    "VoronoiNeighbourClassifier",
    "VoronoiSearch",
    "WaveletTransformer",
    "voronoi_boxes",
]
