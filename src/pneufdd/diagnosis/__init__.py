"""Diagnose: reference model, leak detection, fingerprint location and sizing, costing.

The engine works on :class:`StepTable` (per cycle and step: timing and summaries of
each analog channel), so it is independent of how a recording was segmented.
"""

from __future__ import annotations

from pneufdd.diagnosis.band import BandDetector
from pneufdd.diagnosis.cost import CostedLeak, CostSettings, annual_cost, equivalent_orifice_mm
from pneufdd.diagnosis.engine import Diagnosis, diagnose
from pneufdd.diagnosis.fingerprint import LeakEstimate, Localisation, locate
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
    "LeakEstimate",
    "Localisation",
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
