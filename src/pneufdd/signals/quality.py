"""Data quality at the edge: plausible channels, and the gap rule for real DAQ data.

Two things are judged before any cycle is summarised (docs/data-quality.md):

**Plausible channels** (:func:`check_channels`). A channel named like a pressure
(``P_...``), mass flow (``Q_...``) or position (``X_...``) must carry that quantity's SI
unit; analog channels must be sampled at :data:`MIN_ANALOG_RATE_HZ` or faster and PLC
signals at :data:`MIN_DIGITAL_RATE_HZ` or faster (the rig sampled 1000 Hz analog and
100 Hz digital, section 3.4.2; strokes last 0.4 to 2.2 s, so a 0.1 s step still holds 5
analog samples at the slowest rate allowed); every analog
channel must start within :data:`MAX_START_OFFSET_S` of the PLC signals (one trigger
starts a recording's channels; a larger offset means two clocks) and overlap them for at
least half of their span; a pressure channel's median must be a compressed-air pressure
(:data:`PRESSURE_MEDIAN_RANGE_PA`, absolute). Anything else is refused, naming the file
and the channel: judging such data would give a confident verdict on nonsense.

**Gaps** (:func:`repair_gaps`). A sample that is NaN, infinite or outside its quantity's
physical range (:data:`PHYSICAL_RANGE`: a DAQ's over-range marker, 1e308...) is missing.
A run of missing samples no longer than :data:`MAX_REPAIR_S` (shorter than a valve's
switching transient, so a step's mean, minimum and maximum barely move) is repaired by
linear interpolation between its neighbours. A longer gap is left missing, and every
cycle it touches (as every cycle a channel did not record at all, and every cycle in
which gaps of any length cover more than :data:`MAX_GAP_FRACTION` of a channel's
samples) is skipped and counted. :func:`usable_cycles` applies the rule to a set of
cycles; a recording with fewer than :data:`MIN_USABLE_FRACTION` of its complete cycles
usable is refused, naming the file and the channel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

import pneufdd.limits as limits
from pneufdd.array_types import BoolArray, FloatArray, IntArray
from pneufdd.errors import ChannelError, NoCompleteCycleError, UnitError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.segmentation import Cycle
from pneufdd.signals.synchronisation import sample_bounds

__all__ = [
    "MAX_GAP_FRACTION",
    "MAX_REPAIR_S",
    "MAX_START_OFFSET_S",
    "MIN_ANALOG_RATE_HZ",
    "MIN_DIGITAL_RATE_HZ",
    "MIN_USABLE_FRACTION",
    "PHYSICAL_RANGE",
    "PRESSURE_MEDIAN_RANGE_PA",
    "GapReport",
    "check_carried_description",
    "check_channels",
    "check_sequence_channels",
    "repair_gaps",
    "usable_cycles",
]


MAX_REPAIR_S = 0.05
"""Longest run of missing samples repaired by interpolation [s]."""

MIN_ANALOG_RATE_HZ = 50.0
"""Slowest plausible sample rate of an analog channel [Hz]."""

MIN_DIGITAL_RATE_HZ = 10.0
"""Slowest plausible sample rate of a PLC signal (valve solenoid, switch) [Hz]."""

MAX_RATE_HZ = limits.MAX_RATE_HZ
"""Fastest plausible sample rate of any channel [Hz] (:mod:`pneufdd.limits`)."""

MAX_START_OFFSET_S = 1.0
"""Largest difference between an analog channel's start and the PLC signals' [s]."""

MAX_GAP_FRACTION = 0.1
"""Largest fraction of a cycle's samples of one channel that may be missing."""

MIN_OVERLAP = 0.5
"""Least fraction of the PLC signals' span an analog channel's time base must cover."""

MIN_USABLE_FRACTION = 0.5
"""Least fraction of a recording's complete cycles that must survive the gap rule."""

PRESSURE_MEDIAN_RANGE_PA = (10e3, 10e6)
"""Plausible median of an absolute compressed-air pressure channel [Pa]."""

PHYSICAL_RANGE: dict[str, tuple[float, float]] = {
    "Pa": (0.0, 1e8),  # absolute: no negative pressure; 1000 bar is far beyond pneumatics
    "kg/s": (-10.0, 10.0),  # ~470,000 SLPM: beyond any pneumatic machine's supply
    "m": (-100.0, 100.0),
}
"""Physical range of each SI unit [unit]; samples outside it are missing."""

_QUANTITY_OF_PREFIX = {
    "P_": ("Pa", "a pressure"),
    "Q_": ("kg/s", "a mass flow"),
    "X_": ("m", "a position"),
}
_PLC_PREFIXES = ("U_", "S_")


@dataclass(frozen=True)
class GapReport:
    """What the gap rule did to a set of cycles of one recording.

    Attributes
    ----------
    usable : ndarray of bool, shape (n_cycles,)
        Cycles no long gap touches.
    skipped : tuple of (int, str)
        Each skipped cycle's index in the recording and the first channel with a
        long gap in it.
    repaired_gaps : int
        Short gaps repaired by interpolation, over all channels.
    """

    usable: BoolArray
    skipped: tuple[tuple[int, str], ...]
    repaired_gaps: int


def _span(recording: Recording, name: str) -> tuple[float, float]:
    ch = recording.info(name)
    return float(ch.t0), float(ch.t0 + ch.values.size / ch.rate_hz)


def check_channels(recording: Recording, analog: Sequence[str], where: str) -> None:
    """Refuse implausible channels: unit of the wrong kind, rate or time base.

    Parameters
    ----------
    recording : Recording
        The recording to judge.
    analog : sequence of str
        Analog channels about to be used (every PLC signal is always judged).
    where : str
        The file, named in messages.

    Raises
    ------
    UnitError
        If a ``P_``/``Q_``/``X_`` channel's unit is not a pressure/mass flow/length.
    ChannelError
        If a rate is implausible, an analog time base misses the PLC signals, or a
        pressure's median is not a compressed-air pressure.
    """
    plc = [c for c in recording.digital_channels if c.startswith(_PLC_PREFIXES)]
    for name in plc:
        rate = recording.rate(name)
        if not MIN_DIGITAL_RATE_HZ <= rate <= MAX_RATE_HZ:
            raise ChannelError(
                describe(
                    f"{where}: sample rate of PLC signal {name!r} [Hz]",
                    rate,
                    f"{MIN_DIGITAL_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz",
                )
            )
    plc_spans = [_span(recording, c) for c in plc if recording.info(c).values.size]
    for name in analog:
        ch = recording.info(name)
        for prefix, (unit, quantity) in _QUANTITY_OF_PREFIX.items():
            if name.startswith(prefix) and ch.unit != unit:
                raise UnitError(
                    describe(
                        f"{where}: unit of channel {name!r} ({quantity}, by its name)",
                        ch.unit,
                        [unit],
                    )
                )
        if not MIN_ANALOG_RATE_HZ <= ch.rate_hz <= MAX_RATE_HZ:
            raise ChannelError(
                describe(
                    f"{where}: sample rate of analog channel {name!r} [Hz]",
                    ch.rate_hz,
                    f"{MIN_ANALOG_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz (pneumatic steps last "
                    "0.1 s and more)",
                )
            )
        if ch.values.size == 0:
            raise ChannelError(describe(f"{where}: samples of channel {name!r}", 0, "> 0"))
        if plc_spans:
            start = min(s for s, _ in plc_spans)
            end = max(e for _, e in plc_spans)
            a0, a1 = _span(recording, name)
            overlap = max(0.0, min(a1, end) - max(a0, start))
            if abs(a0 - start) > MAX_START_OFFSET_S or (
                end > start and overlap < MIN_OVERLAP * (end - start)
            ):
                raise ChannelError(
                    describe(
                        f"{where}: time base of channel {name!r} [s]",
                        f"{a0:.6g} to {a1:.6g}",
                        f"starting within {MAX_START_OFFSET_S:g} s of the PLC signals' "
                        f"{start:.6g} to {end:.6g} and covering at least "
                        f"{100 * MIN_OVERLAP:.0f} % of them (one clock, one trigger)",
                    )
                )
        if ch.unit == "Pa":
            finite = ch.values[np.isfinite(ch.values)]
            low, high = PRESSURE_MEDIAN_RANGE_PA
            if finite.size and not low <= float(np.median(finite)) <= high:
                raise ChannelError(
                    describe(
                        f"{where}: median of pressure channel {name!r} [Pa absolute]",
                        float(np.median(finite)),
                        f"{low:g} to {high:g} Pa (absolute; was a gauge or bar value "
                        "stored as Pa?)",
                    )
                )


def repair_gaps(
    values: npt.ArrayLike,
    rate_hz: float,
    unit: str,
    max_gap_s: float = MAX_REPAIR_S,
    copy: bool = True,
) -> tuple[FloatArray, BoolArray, int, BoolArray]:
    """Apply the gap rule to one channel.

    Parameters
    ----------
    values : array_like
        The channel's samples [unit].
    rate_hz : float
        Its sample rate [Hz].
    unit : str
        Its SI unit (selects :data:`PHYSICAL_RANGE`).
    max_gap_s : float
        Longest gap repaired [s].
    copy : bool
        False: a channel without gaps comes back as ``values`` itself (float64), not a
        copy, for callers that only read it.

    Returns
    -------
    repaired : ndarray
        Short gaps interpolated, long gaps NaN [unit].
    long_gap : ndarray of bool
        True on the samples of gaps too long to repair.
    n_repaired : int
        Number of short gaps repaired.
    missing : ndarray of bool
        True on every sample that was missing (repaired or not).

    Examples
    --------
    >>> v, long_gap, n, _ = repair_gaps([1.0, float("nan"), 3.0, 1e308, 5.0], 100.0, "Pa")
    >>> v.tolist(), bool(long_gap.any()), n
    ([1.0, 2.0, 3.0, 4.0, 5.0], False, 2)
    """
    x = np.asarray(values, dtype=np.float64)
    low, high = PHYSICAL_RANGE.get(unit, (-np.inf, np.inf))
    # fast path: the extremes are in range (NaN fails both comparisons)
    finite_range = math.isfinite(low) and math.isfinite(high)
    if finite_range and x.size and low <= float(x.min()) and float(x.max()) <= high:
        none = np.zeros(x.size, dtype=bool)
        return (x.copy() if copy else x), none, 0, none
    x = x.copy()
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(x) | (x < low) | (x > high)
    if not bad.any():
        return x, bad, 0, bad
    if bad.all():
        x[:] = np.nan
        return x, bad, 0, bad
    edges = np.diff(np.concatenate([[0], bad.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    longest = max(1, round(max_gap_s * rate_hz))
    idx = np.arange(x.size)
    x[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    long_gap = np.zeros(x.size, dtype=bool)
    short = 0
    for a, b in zip(starts, ends, strict=True):
        if b - a > longest:
            long_gap[a:b] = True
        else:
            short += 1
    x[long_gap] = np.nan
    return x, long_gap, short, bad


def usable_cycles(
    recording: Recording,
    cycles: Sequence[Cycle],
    channels: Sequence[str],
    where: str,
    copy: bool = True,
) -> tuple[dict[str, FloatArray], GapReport]:
    """Repair short gaps in ``channels`` and find the cycles long gaps leave usable.

    ``copy`` False: a channel without gaps is returned as the recording's own array
    (for callers that only read it; :func:`repair_gaps`).

    Returns
    -------
    repaired : dict of str to ndarray
        Each channel's samples after the gap rule [channel unit].
    report : GapReport

    Raises
    ------
    NoCompleteCycleError
        If fewer than :data:`MIN_USABLE_FRACTION` of ``cycles`` (or none) are usable;
        the message names the file and the channel whose gaps skipped most cycles.
    """
    n = len(cycles)
    usable = np.ones(n, dtype=bool)
    blame: dict[int, str] = {}
    per_channel: dict[str, int] = {}
    repaired_total = 0
    repaired: dict[str, FloatArray] = {}
    bounds: dict[tuple[float, float], tuple[IntArray, IntArray]] = {}
    for name in channels:
        ch = recording.info(name)
        values, long_gap, count, missing = repair_gaps(ch.values, ch.rate_hz, ch.unit, copy=copy)
        repaired[name] = values
        repaired_total += count
        if n == 0:
            continue
        key = (ch.rate_hz, ch.t0)
        if key not in bounds:
            bounds[key] = sample_bounds(cycles, ch.rate_hz, ch.t0)
        start, end = bounds[key]
        first, last = start[:, 0], end[:, -1]
        size = values.size
        touched = (first < 0) | (last > size)  # not recorded: a gap too
        if missing.any():
            csum = np.concatenate([[0], np.cumsum(long_gap, dtype=np.int64)])
            msum = np.concatenate([[0], np.cumsum(missing, dtype=np.int64)])
            a, b = np.clip(first, 0, size), np.clip(last, 0, size)
            lost = msum[b] - msum[a]
            touched |= (csum[b] - csum[a] > 0) | (lost > MAX_GAP_FRACTION * np.maximum(b - a, 1))
        for i in np.flatnonzero(touched & usable):
            blame[int(i)] = name
        per_channel[name] = int(np.sum(touched))
        usable &= ~touched
    kept = int(np.sum(usable))
    if n and (kept == 0 or kept < MIN_USABLE_FRACTION * n):
        worst = max(per_channel, key=lambda c: per_channel[c])
        raise NoCompleteCycleError(
            describe(
                f"{where}: usable cycles (gaps of NaN, infinite or out-of-range samples "
                f"longer than {MAX_REPAIR_S:g} s, or no samples, skip a cycle; channel "
                f"{worst!r} has them in {per_channel[worst]} of {n} complete cycles)",
                kept,
                f"at least {MIN_USABLE_FRACTION:.0%} of the complete cycles (docs/data-quality.md)",
            )
        )
    skipped = tuple((cycles[i].index, blame[i]) for i in sorted(blame))
    return repaired, GapReport(usable, skipped, repaired_total)


def check_carried_description(recording: Recording, where: str) -> None:
    """Refuse a malformed machine description carried in a recording's metadata.

    Simulated recordings carry their description (``metadata["machine"]
    ["description"]``); its sequence segments the recording, so a damaged one is
    refused (naming the file and the key) rather than ignored or half used.
    """
    from pneufdd.sim.description import parse_description

    machine = recording.metadata.get("machine")
    if machine is None or isinstance(machine, str):
        return
    if not isinstance(machine, dict):
        raise ChannelError(describe(f"{where}: metadata 'machine'", machine, "a name or a table"))
    raw = machine.get("description")
    if raw is None:
        return
    if not isinstance(raw, dict):
        raise ChannelError(
            describe(f"{where}: metadata machine.description", raw, "a machine description")
        )
    parse_description(raw, f"{where}: metadata machine.description")


def check_sequence_channels(
    recording: Recording, switches: Sequence[str], valves: Sequence[str], where: str
) -> None:
    """Refuse a recording lacking a valve or switch channel its PLC sequence needs."""
    missing = sorted({*switches, *valves} - set(recording.channels))
    if missing:
        raise ChannelError(
            describe(
                f"{where}: PLC channel(s) the machine's sequence needs",
                f"missing {missing}",
                "every valve solenoid and awaited switch of the sequence",
            )
        )
