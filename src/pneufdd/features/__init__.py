"""Features: a registry of named, documented feature functions and the
feature-matrix builder (sections 3.3, 4.3.1-4.3.2 and 5.3.3 of the dissertation).
"""

from __future__ import annotations

from pneufdd.features import air, motion, table44, wavelet
from pneufdd.features.context import CycleView, Options, RecordingData
from pneufdd.features.matrix import GROUPS, feature_matrix, features_of, labels_of
from pneufdd.features.registry import REGISTRY, Feature, Unavailable, column_name, get
from pneufdd.features.table44 import TABLE_4_5, TABLE_44_NAMES

__all__ = [
    "GROUPS",
    "REGISTRY",
    "TABLE_4_5",
    "TABLE_44_NAMES",
    "CycleView",
    "Feature",
    "Options",
    "RecordingData",
    "Unavailable",
    "air",
    "column_name",
    "feature_matrix",
    "features_of",
    "get",
    "labels_of",
    "motion",
    "table44",
    "wavelet",
]
