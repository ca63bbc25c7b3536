"""Many short recordings of one machine: start-up cycles, duplicated cycles (issue 33).

A plant's data often comes as triggered captures, one cycle or a few per file. The
reference build and the pooled diagnosis treat their cycles as one population:

* **Start-up cycles** (:attr:`DetectionSettings.startup_cycles`): the first cycle of a
  recording may follow a stop, so by default it is neither learned nor judged. A
  capture that *starts at a cycle start of a running machine* has no such cycle.
  Detected when the recording's first step is step 1 of a complete cycle and a
  solenoid is already energised at its first sample without firing there (held over
  from the previous cycle, as in a triggered capture with a pre-trigger): such a
  recording has 0 start-up cycles. A capture starting exactly at its trigger shows
  nothing of the previous cycle and cannot be told from a machine started from rest:
  pass ``--startup-cycles 0``.
* **Duplicated cycles**: cycles with identical samples (a file copied, cycles pasted
  to reach a minimum count) are not independent; a reference built from them claims
  a spread and a false-alarm rate it does not have. Refused.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.features.step_table import StepTable
from pneufdd.recording.model import Recording
from pneufdd.signals.events import VALVE_PREFIX
from pneufdd.signals.segmentation import Cycle

__all__ = ["check_duplicates", "continues_running", "startup_of"]


def continues_running(recording: Recording, first: Cycle | None) -> bool:
    """Whether ``recording`` starts at a cycle start of a running machine (see module rule).

    ``first`` is the recording's first segmented cycle (complete or not).
    """
    if first is None or not first.complete or first.index != 1 or not first.steps:
        return False
    for name in recording.digital_channels:
        if not name.startswith(VALVE_PREFIX):
            continue
        info = recording.info(name)
        # on at the first sample, and the first step fired later: held over
        if (
            info.values.size
            and info.values[0] == 1
            and first.steps[0].start_s > info.t0 + 0.5 / info.rate_hz
        ):
            return True
    return False


def startup_of(
    recording: Recording, first: Cycle | None, default: int, given: int | None
) -> tuple[int, bool]:
    """Start-up cycles of one recording and whether it was detected as a running start.

    ``given`` (the ``--startup-cycles`` option) wins; else 0 for a recording that
    :func:`continues_running`, else ``default``.
    """
    if given is not None:
        return given, False
    if default and continues_running(recording, first):
        return 0, True
    return default, False


def _cycle_digests(table: StepTable) -> list[str]:
    """One digest per cycle of its analog summaries and traces (identical samples, same digest)."""
    out = []
    for i in range(table.n_cycles):
        h = hashlib.sha256(np.ascontiguousarray(table.summaries[i]).tobytes())
        if table.traces is not None:
            h.update(np.ascontiguousarray(table.traces[i]).tobytes())
        out.append(h.hexdigest())
    return out


def check_duplicates(
    tables: Sequence[StepTable], labels: Sequence[str], recordings: Sequence[Recording]
) -> None:
    """Refuse duplicated recordings or cycles (identical samples).

    Raises
    ------
    InputError
        Naming the files (and cycles) that repeat each other.
    """
    seen: dict[str, str] = {}
    for rec, where in zip(recordings, labels, strict=True):
        h = hashlib.sha256()
        for name in rec.channels:
            h.update(name.encode())
            h.update(np.ascontiguousarray(rec.info(name).values).tobytes())
        key = h.hexdigest()
        if key in seen:
            raise InputError(
                describe(
                    "reference recordings",
                    f"{where} has the same samples as {seen[key]}",
                    "independent recordings (each cycle once; a copied file adds no "
                    "information and fakes the reference's spread)",
                )
            )
        seen[key] = where
    cycles: dict[str, str] = {}
    for table, where in zip(tables, labels, strict=True):
        if not table.channels:
            return  # durations alone repeat legitimately (10 ms digital samples)
        for i, key in enumerate(_cycle_digests(table)):
            name = f"cycle {int(table.cycle_index[i])} of {where}"
            if key in cycles:
                raise InputError(
                    describe(
                        "reference cycles",
                        f"{name} has the same samples as {cycles[key]}",
                        "independent cycles (each cycle once: repeated cycles fake the "
                        "reference's spread and its false-alarm rate)",
                    )
                )
            cycles[key] = name
