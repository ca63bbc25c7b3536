"""Campaigns on triggered captures (issue 33): references and runs as many short files.

A plant's DAQ often writes one short file per trigger (``docs/captures.md``). With a
:class:`CaptureDesign` in :attr:`~pneufdd.evaluation.campaign.CampaignDesign.capture`
(``pneufdd campaign --capture triggered``), a campaign judges exactly that:

* each plant's **reference** is built from ``captures_per_reference`` captures of
  ``cycles_per_file`` cycles each (:func:`pneufdd.sim.captures.simulate_captures`,
  ``pre_trigger_s`` before each trigger, as exported: machine name only), taken from
  ``reference_recordings`` separate simulations of the plant (their own seeds and
  house-air states), every capture a file of its own;
* each **run** is ``captures_per_run`` captures of one simulation with the run's leaks,
  pooled and judged together (:func:`pneufdd.diagnosis.recordings.pooled_table`, as
  ``pneufdd diagnose --pool`` does); start-up cycles are detected per capture.

Without a capture design, references and runs are continuous recordings, as before.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pneufdd.diagnosis.recordings import pooled_table, run_table
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError, describe
from pneufdd.features.step_table import StepTable
from pneufdd.limits import MAX_CAMPAIGN_COUNT, check_count
from pneufdd.recording.model import Recording
from pneufdd.sim import MachineDescription, as_exported, simulate
from pneufdd.sim.captures import simulate_captures

__all__ = [
    "CAPTURE_KINDS",
    "CaptureDesign",
    "reference_recordings",
    "run_recordings",
    "run_step_table",
]

CAPTURE_KINDS = ("continuous", "triggered")
"""How a campaign's plants are recorded: one continuous file, or triggered captures."""


@dataclass(frozen=True)
class CaptureDesign:
    """How a campaign records its plants as triggered captures.

    Attributes
    ----------
    captures_per_reference : int
        Captures a plant's reference is built from (at least 10 cycles in all) [-].
    captures_per_run : int
        Captures pooled into one judged run [-].
    cycles_per_file : int
        Cycles from each capture's trigger [-].
    pre_trigger_s : float
        Span recorded before each trigger [s].
    """

    captures_per_reference: int = 20
    captures_per_run: int = 10
    cycles_per_file: int = 1
    pre_trigger_s: float = 0.3

    def __post_init__(self) -> None:
        for name, low in (
            ("captures_per_reference", 1),
            ("captures_per_run", 1),
            ("cycles_per_file", 1),
        ):
            check_count(
                f"campaign {name} (--{name.replace('_', '-')})",
                getattr(self, name),
                MAX_CAMPAIGN_COUNT,
                low,
            )
        if self.captures_per_reference * self.cycles_per_file < 10:
            raise InputError(
                describe(
                    "campaign captures per reference x cycles per file",
                    self.captures_per_reference * self.cycles_per_file,
                    ">= 10 (a reference needs 10 cycles)",
                )
            )
        pre = self.pre_trigger_s
        if isinstance(pre, bool) or not isinstance(pre, int | float) or not 0 <= pre <= 10:
            raise InputError(describe("campaign pre-trigger (--pre-trigger-s)", pre, "0 to 10 s"))

    @property
    def run_cycles(self) -> int:
        """Cycles judged per run [-]."""
        return self.captures_per_run * self.cycles_per_file


def _split(total: int, parts: int) -> list[int]:
    """``total`` as ``parts`` counts differing by at most one, larger first."""
    base, extra = divmod(total, parts)
    return [base + (1 if k < extra else 0) for k in range(parts)]


def reference_recordings(
    capture: CaptureDesign | None,
    plant: MachineDescription,
    seeds: Sequence[int],
    cycles_per_recording: int,
) -> list[Recording]:
    """A plant's leak-free reference recordings, as exported.

    Continuous (``capture`` None): one run of ``cycles_per_recording`` + 2 cycles per
    seed. Triggered: the captures split over one simulation per seed, each a
    recording of its own.
    """
    if capture is None:
        return [
            as_exported(simulate(plant, cycles=cycles_per_recording + 2, seed=seed))
            for seed in seeds
        ]
    out: list[Recording] = []
    for seed, files in zip(seeds, _split(capture.captures_per_reference, len(seeds)), strict=True):
        if files:
            out.extend(_captures(capture, plant, files, None, seed))
    return out


def _captures(
    capture: CaptureDesign, plant: MachineDescription, files: int, leaks: Any, seed: int
) -> list[Recording]:
    caps = simulate_captures(
        plant,
        files=files,
        cycles_per_file=capture.cycles_per_file,
        pre_trigger_s=capture.pre_trigger_s,
        leaks=leaks,
        seed=seed,
    )
    return [as_exported(cap) for cap in caps]


def run_recordings(
    capture: CaptureDesign | None,
    plant: MachineDescription,
    run_cycles: int,
    leaks: Any,
    seed: int,
) -> tuple[list[Recording], list[dict[str, Any]]]:
    """A run's recordings as exported, and its leaks as simulated (the ground truth).

    Raises
    ------
    MachineStalledError
        When the plant stalls with these leaks.
    """
    if capture is None:
        recording = simulate(plant, cycles=run_cycles + 2, leaks=leaks, seed=seed)
        return [as_exported(recording)], list(recording.metadata["leaks"])
    caps = simulate_captures(
        plant,
        files=capture.captures_per_run,
        cycles_per_file=capture.cycles_per_file,
        pre_trigger_s=capture.pre_trigger_s,
        leaks=leaks,
        seed=seed,
    )
    truth = list(caps[0].metadata["leaks"]) if caps else []
    return [as_exported(cap) for cap in caps], truth


def run_step_table(
    model: ReferenceModel,
    recordings: Sequence[Recording],
    run_cycles: int,
    where: str,
    pooled: bool,
) -> StepTable:
    """The run's first ``run_cycles`` cycles as the reference summarises them: the
    running cycles of one continuous recording, or the captures' cycles ``pooled``.

    Raises
    ------
    NoCompleteCycleError
        When the run (or every capture) holds no complete cycle.
    """
    if pooled:
        names = [f"{where} capture {k + 1}" for k in range(len(recordings))]
        table = pooled_table(model, recordings, names)
    else:
        (recording,) = recordings
        table = run_table(model, recording, where)
    return table.take(np.arange(min(run_cycles, table.n_cycles)))
