"""Evaluation: how well the diagnosis does on simulated plants that differ from their twin."""

from __future__ import annotations

from pneufdd.evaluation.campaign import (
    SENSOR_SETS,
    TARGETS,
    CampaignDesign,
    CampaignResult,
    rescore,
    run_campaign,
)
from pneufdd.evaluation.scoring import RunOutcome, Tally

__all__ = [
    "SENSOR_SETS",
    "TARGETS",
    "CampaignDesign",
    "CampaignResult",
    "RunOutcome",
    "Tally",
    "rescore",
    "run_campaign",
]
