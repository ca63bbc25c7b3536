"""Diagnose: reference model, leak detection, location and sizing, costing.

The engine works on :class:`StepTable` (per cycle and step: timing and summaries of
each analog channel), so it is independent of how a recording was segmented. Most
users need only :class:`pneufdd.LeakDiagnoser`.
"""

from __future__ import annotations

from pneufdd.diagnosis.band import BandDetector
from pneufdd.diagnosis.cost import CostedLeak, CostSettings, annual_cost, equivalent_orifice_mm
from pneufdd.diagnosis.effects import LeakEffectModel
from pneufdd.diagnosis.engine import Diagnosis, diagnose
from pneufdd.diagnosis.localisation import (
    LeakEstimate,
    Localisation,
    LocalisationSettings,
    locate,
)
from pneufdd.diagnosis.model_choice import Explanation
from pneufdd.diagnosis.pnref import load_reference, save_reference
from pneufdd.diagnosis.reference import MIN_REFERENCE_CYCLES, DetectionSettings, ReferenceModel
from pneufdd.diagnosis.signatures import SignatureSet
from pneufdd.diagnosis.statistic import CycleDistanceDetector
from pneufdd.diagnosis.steps import StepTable

__all__ = [
    "MIN_REFERENCE_CYCLES",
    "BandDetector",
    "CostSettings",
    "CostedLeak",
    "CycleDistanceDetector",
    "DetectionSettings",
    "Diagnosis",
    "Explanation",
    "LeakEffectModel",
    "LeakEstimate",
    "Localisation",
    "LocalisationSettings",
    "ReferenceModel",
    "SignatureSet",
    "StepTable",
    "annual_cost",
    "diagnose",
    "equivalent_orifice_mm",
    "load_reference",
    "locate",
    "save_reference",
]
