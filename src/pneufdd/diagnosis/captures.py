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
* **Sessions** (:func:`capture_sessions`): captures taken one after the other share
  the conditions of that hour (house air, the machine's warmth), so their cycles are
  no more independent than the cycles of one continuous recording. The reference's
  cross-validation leaves out a whole session and its run threshold accounts for the
  correlation within one (:mod:`pneufdd.diagnosis.detection.statistic`), as for
  recordings; with each capture counted as a recording of its own, a held-out
  capture's neighbours from its session stayed in the model and the reference
  promised a spread that a new session's captures exceed (issue 33: 7 of 70
  leak-free runs of pooled captures flagged on one festo-dsd plant).
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from datetime import datetime, timedelta

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.features.step_table import StepTable
from pneufdd.recording.model import Recording
from pneufdd.signals.events import VALVE_PREFIX
from pneufdd.signals.segmentation import Cycle

__all__ = [
    "MAX_CAPTURE_CYCLES",
    "SESSION_GAP_S",
    "capture_sessions",
    "check_duplicates",
    "continues_running",
    "startup_of",
]

SESSION_GAP_S = 600.0
"""Longest pause between two captures of one session [s]: the house air's drift and
the compressor's cycle (section 4.4.1) change within minutes, the machine's warmth
within tens of minutes; an assumption (``docs/assumptions.md``)."""

MAX_CAPTURE_CYCLES = 3
"""Most running cycles a recording may hold to be grouped with its neighbours as a
capture of one session; longer recordings are sessions of their own [-]."""


def capture_sessions(recordings: Sequence[Recording], cycles: Sequence[int]) -> tuple[int, ...]:
    """The session of each recording, numbered from 0 in order.

    A recording joins the previous one's session when both are captures (at most
    :data:`MAX_CAPTURE_CYCLES` running cycles, ``cycles``) and it starts after the
    previous one ends, within :data:`SESSION_GAP_S`: the files of one triggered
    acquisition, as its DAQ numbers them. A recording starting before the previous
    one ended (another acquisition, or simulations that all start at the epoch)
    or after a longer pause starts a new session.

    Examples
    --------
    >>> from datetime import UTC, datetime, timedelta
    >>> from pneufdd.recording.model import Channel
    >>> def rec(start_s):
    ...     t0 = datetime(2026, 11, 27, 14, 0, tzinfo=UTC) + timedelta(seconds=start_s)
    ...     return Recording([Channel("P_In", np.zeros(100), 10.0, "Pa")], start_time=t0)
    >>> capture_sessions([rec(0), rec(15), rec(30), rec(5), rec(20), rec(4000)], [1] * 6)
    (0, 0, 0, 1, 1, 2)
    >>> capture_sessions([rec(0), rec(15)], [1, 40])  # a long recording: its own session
    (0, 1)
    """
    out: list[int] = []
    previous: tuple[datetime, bool] | None = None
    session = -1
    for recording, n in zip(recordings, cycles, strict=True):
        start = recording.start_time
        capture = int(n) <= MAX_CAPTURE_CYCLES
        joins = False
        if previous is not None:
            end, was_capture = previous
            pause = (start - end).total_seconds()
            joins = capture and was_capture and 0.0 <= pause <= SESSION_GAP_S
        session += 0 if joins else 1
        out.append(session)
        previous = (start + timedelta(seconds=recording.duration), capture)
    return tuple(out)


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
