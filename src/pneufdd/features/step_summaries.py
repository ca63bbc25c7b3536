"""Step summaries: a :class:`~pneufdd.recording.Recording` -> a :class:`StepTable`.

Segmentation into cycles and steps comes from :mod:`pneufdd.signals` (steps start at
their valve firing, section 5.3.1.1); this module only slices each analog channel
per step (mean, min, max over ``[start, end)``) and gathers step-aligned traces at a
lower rate for the band method (block means, each step from its own start, NaN past
the step's end).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pneufdd.array_types import FloatArray, IntArray
from pneufdd.errors import InputError, NoCompleteCycleError, describe, naming
from pneufdd.features.step_table import StepTable
from pneufdd.recording.model import Recording
from pneufdd.signals.quality import usable_cycles
from pneufdd.signals.segmentation import Cycle, StepSpec, plc_sequence, segment
from pneufdd.signals.synchronisation import sample_bounds
from pneufdd.sim import MachineDescription

__all__ = [
    "build_step_table",
    "machine_sequence",
    "segment_cycles",
    "sequence_from_records",
    "sequence_to_records",
    "trace_offsets",
]


def machine_sequence(machine: MachineDescription | None) -> tuple[StepSpec, ...] | None:
    """The PLC sequence of a machine description; None without one (then it is learned).

    The description's sequence awaits exactly the switches the PLC waits for, which a
    slow, leaky actuator still reaches inside its step. Step 1 of
    :func:`pneufdd.signals.segmentation.plc_sequence`.
    """
    return None if machine is None else plc_sequence(machine=machine)


def sequence_to_records(sequence: Sequence[StepSpec]) -> list[dict[str, Any]]:
    """JSON-compatible form of a PLC sequence (stored in the reference)."""
    return [
        {
            "valves": sorted(spec.valves),
            "switches": [[name, int(state)] for name, state in sorted(spec.switches)],
            **({} if spec.end_gap_s is None else {"end_gap_s": float(spec.end_gap_s)}),
        }
        for spec in sequence
    ]


def _end_gap(value: Any) -> float | None:
    """A stored ``end_gap_s``: a finite number >= 0, else unknown."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) and value >= 0 else None


def sequence_from_records(records: Sequence[Mapping[str, Any]]) -> tuple[StepSpec, ...]:
    """Inverse of :func:`sequence_to_records`."""
    return tuple(
        StepSpec(
            frozenset(str(v) for v in rec["valves"]),
            frozenset((str(name), int(state)) for name, state in rec.get("switches", [])),
            _end_gap(rec.get("end_gap_s")),
        )
        for rec in records
    )


def segment_cycles(
    recording: Recording, sequence: Sequence[StepSpec] | None = None, where: str = "recording"
) -> tuple[list[Cycle], tuple[StepSpec, ...], list[str]]:
    """Complete cycles of ``recording``, the sequence used, and why others were skipped.

    The sequence is :func:`pneufdd.signals.segmentation.plc_sequence` with
    ``carried=False``: ``sequence`` when given (an empty one counts as none), else
    learned from ``recording`` itself, never from a description the recording carries
    (the diagnosis resolves the description before, see
    :func:`pneufdd.diagnosis.machine.resolve_machine`).

    Raises
    ------
    NoCompleteCycleError
        If the recording holds no complete cycle.
    """
    try:
        specs = plc_sequence(recording, sequence or None, carried=False)
        seg = segment(recording, specs)
    except InputError as exc:
        raise naming(exc, where) from exc
    cycles = list(seg.complete)
    reasons = [f"cycle {c.index}: {c.reason}" for c in seg.rejected]
    if not cycles:
        raise NoCompleteCycleError(
            describe(
                f"complete machine cycles in {where}",
                0,
                "at least one (rejected: " + "; ".join(reasons[:3]) + ")",
            )
        )
    return cycles, tuple(seg.sequence), reasons


def trace_offsets(cycles: Sequence[Cycle], rate_hz: float) -> IntArray:
    """Template offsets: each step gets its median length over ``cycles`` [samples]."""
    start, end = sample_bounds(cycles, rate_hz)
    lengths = np.maximum(np.round(np.median(end - start, axis=0)).astype(np.int64), 1)
    return np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)


def _summaries(values: Sequence[FloatArray], start: IntArray, end: IntArray) -> FloatArray:
    """Mean, minimum and maximum of every step window of channels on one time base.

    ``values``: the channels' samples, all of one length; ``start``, ``end``: window
    sample bounds, shape (cycles, steps). Returns shape (channels, cycles, steps, 3).
    Each channel is summarised by one compiled pass that releases the GIL
    (:func:`pneufdd.signals.windows.window_summaries`: the arithmetic of a running sum
    and ``reduceat``, bit for bit).
    """
    n = values[0].size
    s = np.clip(start, 0, n - 1)
    e = np.clip(np.maximum(end, start + 1), 1, n)
    e = np.maximum(e, s + 1)
    bounds = np.stack([s.ravel(), e.ravel()], axis=1).ravel()
    shape = (len(values), *start.shape, 3)
    if np.all(np.diff(bounds) >= 0) and bounds[-1] <= n:
        from pneufdd.signals.windows import window_summaries

        # minimum and maximum over [s, e) with e clipped to the last sample, as reduceat
        extreme_end = np.minimum(e.ravel(), n - 1)
        first, last = s.ravel().astype(np.int64), e.ravel().astype(np.int64)
        rows = [
            window_summaries(np.ascontiguousarray(row, dtype=np.float64), first, last, extreme_end)
            for row in values
        ]
        return np.stack(rows).reshape(shape)
    # overlapping windows (never for a valid segmentation): slow path
    out = np.empty(shape)
    pairs = list(zip(s.ravel(), e.ravel(), strict=True))
    for c, row in enumerate(values):
        csum = np.concatenate([[0.0], np.cumsum(np.where(np.isnan(row), 0.0, row))])
        out[c, ..., 0] = (csum[e] - csum[s]) / (e - s)
        out[c, ..., 1] = np.array([row[a:b].min() for a, b in pairs]).reshape(start.shape)
        out[c, ..., 2] = np.array([row[a:b].max() for a, b in pairs]).reshape(start.shape)
    return out


def _traces(
    values: FloatArray,
    rate: float,
    t0: float,
    cycles: Sequence[Cycle],
    offsets: IntArray,
    trace_rate: float,
) -> FloatArray:
    dec = max(round(rate / trace_rate), 1)
    n_blocks = values.size // dec
    blocks = values[: n_blocks * dec].reshape(n_blocks, dec).mean(axis=1)
    start, end = sample_bounds(cycles, rate / dec, t0)
    lengths = np.diff(offsets)
    out = np.full((len(cycles), int(offsets[-1])), np.nan)
    for j, width in enumerate(lengths):
        idx = start[:, j : j + 1] + np.arange(width)[None, :]
        valid = (idx < end[:, j : j + 1]) & (idx >= 0) & (idx < n_blocks)
        chunk = np.full(idx.shape, np.nan)
        chunk[valid] = blocks[idx[valid]]
        out[:, offsets[j] : offsets[j + 1]] = chunk
    return out


def build_step_table(
    recording: Recording,
    cycles: Sequence[Cycle],
    machine: str,
    channels: Sequence[str] | None = None,
    offsets: IntArray | None = None,
    trace_rate_hz: float = 100.0,
    where: str = "recording",
) -> StepTable:
    """Summarise ``cycles`` of ``recording`` into a :class:`StepTable`.

    The gap rule of :mod:`pneufdd.signals.quality` applies first: short gaps (NaN,
    infinite or out-of-range samples) are interpolated, cycles touched by a longer gap
    are left out and listed in ``skipped_cycles``.

    Parameters
    ----------
    recording : Recording
        The recording the cycles were found in.
    cycles : sequence of Cycle
        Complete cycles (all with the same number of steps).
    machine : str
        Machine name.
    channels : sequence of str, optional
        Analog channels to summarise (all analog channels by default).
    offsets : ndarray of int, optional
        Template offsets (:func:`trace_offsets`); no traces when omitted.
    trace_rate_hz : float
        Rate of the step-aligned traces [Hz].
    where : str
        The recording's file, named in messages.

    Returns
    -------
    StepTable

    Raises
    ------
    NoCompleteCycleError
        If gaps leave too few cycles usable (the message names file and channel).
    """
    names = tuple(recording.analog_channels if channels is None else channels)
    recording.require(names, "the diagnosis sensor set")
    # read only: a channel without gaps is summarised from the recording's own array
    repaired, gaps = usable_cycles(recording, cycles, names, where, copy=False)
    cycles = [c for c, ok in zip(cycles, gaps.usable, strict=True) if ok]
    start = np.array([[s.start_s for s in c.steps] for c in cycles], dtype=np.float64)
    end = np.array([[s.end_s for s in c.steps] for c in cycles], dtype=np.float64)
    n_cycles, n_steps = start.shape
    summaries = np.zeros((n_cycles, n_steps, len(names), 3))
    traces = None if offsets is None or not names else np.zeros((n_cycles, len(names), offsets[-1]))
    # channels on one time base are summarised together (the gap rule keeps their size)
    column = {name: i for i, name in enumerate(names)}
    for (rate, t0, _), members in recording.time_bases(names).items():
        s_idx, e_idx = sample_bounds(cycles, rate, t0)
        columns = [column[m] for m in members]
        found = _summaries([repaired[m] for m in members], s_idx, e_idx)
        summaries[:, :, columns, :] = np.moveaxis(found, 0, 2)
    if traces is not None and offsets is not None:
        for i, name in enumerate(names):
            info = recording.info(name)
            traces[:, i, :] = _traces(
                repaired[name], info.rate_hz, info.t0, cycles, offsets, trace_rate_hz
            )
    return StepTable(
        machine=machine,
        step_start=start,
        step_end=end,
        channels=names,
        units=tuple(recording.unit(n) for n in names),
        summaries=summaries,
        traces=traces,
        trace_offsets=offsets if traces is not None else None,
        trace_rate_hz=trace_rate_hz,
        cycle_index=np.array([c.index for c in cycles], dtype=np.int64),
        skipped_cycles=gaps.skipped,
        repaired_gaps=gaps.repaired_gaps,
    )
