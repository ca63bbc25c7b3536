"""The gap rule of ``diagnose`` for calibration and drafting (docs/data-quality.md).

A plant's recordings have gaps: NaN, infinite or out-of-range samples (a DAQ's
over-range marker), dropouts. ``diagnose`` interpolates short ones (up to 0.05 s) and
skips every cycle a longer one touches (:mod:`pneufdd.signals.quality`); calibration
and drafting apply the same rule, so one infinite sample can no longer turn a
calibration into nonsense (issue 39: "supply air 986.50 %").
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from pneufdd.array_types import BoolArray
from pneufdd.recording.model import Recording
from pneufdd.signals.quality import GapReport, check_channels, repair_gaps, usable_cycles
from pneufdd.signals.segmentation import Cycle

__all__ = ["SUPPLY_CHANNELS", "gap_checked", "gaps_repaired"]

SUPPLY_CHANNELS = ("Q_In", "P_In")
"""The supply meter's channels the evidence uses when recorded."""


def gap_checked(
    recording: Recording,
    cycles: Sequence[Cycle],
    line_channels: Sequence[str],
    where: str,
) -> tuple[Recording, BoolArray, GapReport]:
    """``recording`` after the gap rule of ``diagnose`` (docs/data-quality.md).

    The channels the evidence uses (``Q_In``, ``P_In``, ``line_channels``) are judged
    (:func:`pneufdd.signals.quality.check_channels`), their short gaps interpolated and
    their long gaps left NaN (:func:`pneufdd.signals.quality.usable_cycles`).

    Returns
    -------
    recording : Recording
        With the repaired channels.
    usable : ndarray of bool
        Per cycle of ``cycles``: no long gap touches it.
    report : GapReport

    Raises
    ------
    NoCompleteCycleError
        If fewer than half of ``cycles`` are usable (naming ``where`` and the channel).
    ChannelError, UnitError
        If a channel is implausible.
    """
    channels = [c for c in SUPPLY_CHANNELS if c in recording.channels] + list(line_channels)
    check_channels(recording, channels, where)
    repaired, report = usable_cycles(recording, cycles, channels, where)
    fixed = [
        dataclasses.replace(recording.info(c), values=repaired[c])
        if c in repaired
        else recording.info(c)
        for c in recording.channels
    ]
    clean = Recording(fixed, start_time=recording.start_time, metadata=recording.metadata)
    return clean, report.usable, report


def gaps_repaired(recording: Recording) -> Recording:
    """``recording`` with every analog channel's short gaps interpolated, long ones NaN.

    For whole-recording statistics (the draft's percentiles and fits, which skip NaN):
    an infinite or out-of-range sample never reaches them.

    Examples
    --------
    >>> import numpy as np
    >>> rec = Recording.from_arrays({"P_In": [6e5, np.inf, 6.2e5]}, 100.0, units={"P_In": "Pa"})
    >>> gaps_repaired(rec).channel("P_In")[1].tolist()
    [600000.0, 610000.0, 620000.0]
    """
    channels = []
    for name in recording.channels:
        ch = recording.info(name)
        if name in recording.analog_channels:
            values = repair_gaps(ch.values, ch.rate_hz, ch.unit, copy=False)[0]
            if values is not ch.values:
                ch = dataclasses.replace(ch, values=values)
        channels.append(ch)
    return Recording(channels, start_time=recording.start_time, metadata=recording.metadata)
