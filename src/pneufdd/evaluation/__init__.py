"""Evaluation: how well the diagnosis does on simulated plants that differ from their twin.

Campaigns (:mod:`.campaign`: plants drawn around a description, references, runs with
known leaks, diagnosed and scored by :mod:`.scoring`), labelled rows for the
classifiers (:mod:`.labelled`) and the comparison of every method (:mod:`.compare`).

May import: everything up to :mod:`pneufdd.classifiers` (diagnosis, calibration,
features, sim, ...); not monitor, report or cli.
"""

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
