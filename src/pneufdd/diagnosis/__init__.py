"""Diagnose: reference model, leak detection, location and sizing, costing.

The engine works on :class:`StepTable` (per cycle and step: timing and summaries of
each analog channel), so it is independent of how a recording was segmented. Most
users need only :class:`pneufdd.LeakDiagnoser`.
"""

from __future__ import annotations

from pneufdd.diagnosis.cost import CostSettings, annual_cost, equivalent_orifice
from pneufdd.diagnosis.detection.band import BandDetector
from pneufdd.diagnosis.detection.statistic import CycleDistanceDetector
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.findings import Diagnosis, LeakFinding
from pneufdd.diagnosis.localisation.model_choice import Explanation
from pneufdd.diagnosis.localisation.search import (
    Localisation,
    LocalisationSettings,
    locate,
)
from pneufdd.diagnosis.reference.file import load_reference, save_reference
from pneufdd.diagnosis.reference.model import (
    MIN_REFERENCE_CYCLES,
    DetectionSettings,
    ReferenceModel,
)
from pneufdd.features.step_table import StepTable

__all__ = [
    "MIN_REFERENCE_CYCLES",
    "BandDetector",
    "CostSettings",
    "CycleDistanceDetector",
    "DetectionSettings",
    "Diagnosis",
    "Explanation",
    "LeakEffectModel",
    "LeakFinding",
    "Localisation",
    "LocalisationSettings",
    "ReferenceModel",
    "SignatureSet",
    "StepTable",
    "annual_cost",
    "diagnose",
    "equivalent_orifice",
    "load_reference",
    "locate",
    "save_reference",
]
