"""Recordings as a plant's data acquisition makes them: triggered captures, quantised channels.

A plant rarely logs continuously. A DAQ or PLC trace is usually *triggered*: each file
holds a fixed span from a trigger (the first valve firing of a cycle), often with a
pre-trigger part, so that the file starts with the previous cycle's last solenoid
still energised. Its analog channels are quantised by the converter (a supply
pressure in 0.19 bar steps). The twin writes such recordings so that every shape a
plant's files take is tested end to end (issue 33, item 6):

* :func:`cut_captures` cuts a continuous simulated run into captures: capture ``k``
  starts ``pre_trigger_s`` before the first valve firing of its first cycle (or, with
  ``start_in_step``, halfway through that step of the cycle: a start in mid-sequence
  with the solenoids of the step on) and lasts ``capture_s`` (default: up to the
  next cycle's trigger after its ``cycles_per_file`` cycles, plus the pre-trigger span
  or at least :data:`POST_TRIGGER_S`, so the file ends just inside the next cycle).
  Both ends lie on the slowest channel's sample grid, so every channel spans the same
  time. Captures never overlap: the machine keeps cycling while the DAQ writes a file
  and re-arms, so the cycles between two captures are not recorded.
* :func:`simulate_captures` simulates enough cycles (one before the first capture, so
  its pre-trigger shows the previous cycle's end) and cuts them.
* :func:`quantize` rounds analog channels to a converter's quantum (pressures in
  gauge steps, as a transducer's converter gives them).

Each capture keeps the run's metadata (the leaks are the ground truth) with
``cycle_start_s`` of its own cycles and ``capture`` = ``{"kind", "index",
"start_in_run_s", "pre_trigger_s", "cycles_per_file"}``; its ``start_time`` is the
run's plus the capture's offset.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from datetime import timedelta
from typing import Any

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.physics.constants import P_ATM
from pneufdd.recording.model import Channel, Recording

POST_TRIGGER_S = 0.05
"""Least span a default capture records after the next cycle's trigger [s]: the last
step's awaited switch may close at the very sample the next step fires."""

__all__ = ["crop", "cut_captures", "quantize", "simulate_captures", "start_mid_sequence"]


def crop(recording: Recording, start_s: float, end_s: float) -> Recording:
    """The part of ``recording`` from ``start_s`` up to ``end_s`` [s], time reset to 0.

    Every channel keeps its samples with ``start_s <= t < end_s`` (its own rate); the
    wall-clock start moves by ``start_s``. Metadata is copied unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> rec = Recording.from_arrays({"P_In": np.arange(10.0)}, 10.0, units={"P_In": "Pa"})
    >>> part = crop(rec, 0.3, 0.6)
    >>> part.channel("P_In")[1].tolist()
    [3.0, 4.0, 5.0]
    """
    if not (math.isfinite(start_s) and math.isfinite(end_s)) or not 0.0 <= start_s < end_s:
        raise InputError(describe("capture span [s]", (start_s, end_s), "0 <= start < end"))
    channels = []
    for name in recording.channels:
        info = recording.info(name)
        # sample k is at t0 + k / rate; a tolerance of a millionth of a sample keeps
        # times computed from a cycle start on the grid they came from
        first = max(0, math.ceil((start_s - info.t0) * info.rate_hz - 1e-6))
        last = max(first, math.ceil((end_s - info.t0) * info.rate_hz - 1e-6))
        t0 = info.t0 + first / info.rate_hz - start_s
        channels.append(
            Channel(
                name,
                info.values[first:last].copy(),
                info.rate_hz,
                info.unit,
                info.kind,
                round(t0, 12),
            )
        )
    return Recording(
        channels,
        start_time=recording.start_time + timedelta(seconds=start_s),
        metadata=recording.metadata,
    )


def quantize(recording: Recording, quanta: Mapping[str, float]) -> Recording:
    """``recording`` with each named analog channel rounded to its quantum [SI unit].

    Pressures (unit ``Pa``) are quantised in gauge (over 101325 Pa), as a transducer's
    converter steps; other channels from zero.

    Examples
    --------
    >>> import numpy as np
    >>> rec = Recording.from_arrays({"P_In": [601325.0, 611325.0]}, 1000.0, units={"P_In": "Pa"})
    >>> quantize(rec, {"P_In": 19000.0}).channel("P_In")[1].tolist()
    [595325.0, 614325.0]
    """
    unknown = sorted(set(quanta) - set(recording.analog_channels))
    if unknown:
        raise InputError(
            describe("channel to quantise", unknown[0], list(recording.analog_channels))
        )
    channels = []
    for name in recording.channels:
        info = recording.info(name)
        if name in quanta:
            q = float(quanta[name])
            if not (math.isfinite(q) and q > 0.0):
                raise InputError(describe(f"quantum of {name}", q, "> 0"))
            zero = P_ATM if info.unit == "Pa" else 0.0
            values = np.round((info.values.astype(np.float64) - zero) / q) * q + zero
            info = Channel(name, values, info.rate_hz, info.unit, info.kind, info.t0)
        channels.append(info)
    return Recording(channels, start_time=recording.start_time, metadata=recording.metadata)


def _windows(
    cycle_starts: Sequence[float],
    step_starts: Sequence[float] | None,
    duration: float,
    files: int,
    cycles_per_file: int,
    pre_trigger_s: float,
    capture_s: float | None,
) -> list[tuple[float, float, int]]:
    """``(start, end, first cycle)`` of each capture; fewer than ``files`` if the run is short."""
    starts = [*list(cycle_starts), duration]
    # a capture starting in mid-sequence holds the rest of that cycle, then its cycles
    span = cycles_per_file + (0 if step_starts is None else 1)
    out: list[tuple[float, float, int]] = []
    earliest = 0.0
    c = 1 if len(cycle_starts) > 1 else 0  # one cycle before the first capture
    while len(out) < files and c + span <= len(cycle_starts):
        trigger = starts[c] if step_starts is None else step_starts[c]
        begin = trigger - pre_trigger_s
        if begin < earliest - 1e-9 or begin < 0.0:
            c += 1
            continue
        tail = starts[c + span] + max(pre_trigger_s, POST_TRIGGER_S)
        end = begin + capture_s if capture_s is not None else tail
        if end > duration + 1e-9:
            break
        out.append((begin, min(end, duration), c))
        earliest = end
        c += span
    return out


def cut_captures(
    recording: Recording,
    files: int,
    cycles_per_file: int = 1,
    pre_trigger_s: float = 0.0,
    capture_s: float | None = None,
    start_in_step: int | None = None,
    step_start: Any = None,
) -> list[Recording]:
    """Cut a simulated continuous run into triggered captures (see the module's rules).

    Parameters
    ----------
    recording : Recording
        A simulated run (its metadata's ``cycle_start_s`` gives the triggers).
    files : int
        Number of captures wanted.
    cycles_per_file : int
        Cycles from each capture's trigger.
    pre_trigger_s : float
        Span recorded before the trigger [s].
    capture_s : float, optional
        Fixed length of each capture [s]; by default up to the next trigger after its
        cycles (a longer capture holds the start of the next cycle, cut mid-step).
    start_in_step : int, optional
        1-based step: each capture starts halfway through this step instead of at the
        trigger (a start in mid-sequence with the step's solenoids on); needs
        ``step_start``.
    step_start : array_like, shape (cycles, steps), optional
        Step starts of the run [s] (:attr:`SimulationResult.step_start`).

    Returns
    -------
    list of Recording
        Up to ``files`` captures (fewer when the run holds fewer).

    Examples
    --------
    >>> from pneufdd.sim import simulate
    >>> run = simulate("press-fit-cell", cycles=3, seed=1)
    >>> caps = cut_captures(run, files=2, pre_trigger_s=0.2)
    >>> len(caps), caps[0].metadata["cycle_start_s"]  # its cycle, then the next one's trigger
    (1, [0.206, 3.35])
    """
    meta = recording.metadata
    cycle_starts = [float(t) for t in meta.get("cycle_start_s", [])]
    if not cycle_starts:
        raise InputError(
            describe("metadata 'cycle_start_s' of the run", None, "a simulated run's cycle starts")
        )
    if files < 1 or cycles_per_file < 1:
        raise InputError(describe("files, cycles per file", (files, cycles_per_file), ">= 1"))
    if not (math.isfinite(pre_trigger_s) and pre_trigger_s >= 0.0):
        raise InputError(describe("pre-trigger [s]", pre_trigger_s, ">= 0"))
    if capture_s is not None and not (math.isfinite(capture_s) and capture_s > 0.0):
        raise InputError(describe("capture length [s]", capture_s, "> 0"))
    step_starts = None
    if start_in_step is not None:
        step_starts = _mid_step(step_start, recording.duration, start_in_step)
    windows = _windows(
        cycle_starts,
        step_starts,
        recording.duration,
        files,
        cycles_per_file,
        pre_trigger_s,
        capture_s,
    )
    # on the slowest channel's sample grid, so every channel spans the same time
    grid = 1.0 / min(recording.info(n).rate_hz for n in recording.channels)
    out = []
    for k, (begin_s, end_s, _) in enumerate(windows):
        begin = math.floor(begin_s / grid + 1e-6) * grid
        end = min(math.floor(end_s / grid + 1e-6) * grid, recording.duration)
        part = crop(recording, begin, end)
        inside = [round(t - begin, 9) for t in cycle_starts if begin <= t < end]
        new = dict(meta)
        new["cycle_start_s"] = inside
        new["capture"] = {
            "kind": "triggered",
            "index": k,
            "start_in_run_s": round(begin, 9),
            "pre_trigger_s": pre_trigger_s,
            "cycles_per_file": cycles_per_file,
        }
        out.append(part.with_metadata(new))
    return out


def _mid_step(step_start: Any, duration: float, step: int) -> list[float]:
    """Halfway through step ``step`` (1-based) of every cycle [s]."""
    if step_start is None:
        raise InputError(describe("step starts of the run", None, "given with start_in_step"))
    starts = np.asarray(step_start, dtype=np.float64)
    n_cycles, n_steps = starts.shape
    if not 1 <= step <= n_steps:
        raise InputError(describe("step to start in", step, f"1 to {n_steps}"))
    ends = np.append(starts.reshape(-1)[1:], duration).reshape(n_cycles, n_steps)
    return [float(t) for t in 0.5 * (starts[:, step - 1] + ends[:, step - 1])]


def simulate_captures(
    machine: Any,
    files: int,
    cycles_per_file: int = 1,
    pre_trigger_s: float = 0.0,
    capture_s: float | None = None,
    start_in_step: int | None = None,
    leaks: Any = None,
    seed: int | None = 0,
    max_cycle_s: float = 120.0,
    progress: Any = None,
    schedule: Any = None,
    faults: Any = None,
    nuisances: Any = None,
) -> list[Recording]:
    """Simulate a machine and cut the run into ``files`` triggered captures.

    One cycle runs before the first capture (its pre-trigger shows that cycle's end).
    A fixed ``capture_s`` longer than the file's cycles skips the cycles it covers, so
    the run is extended until every capture fits.

    Examples
    --------
    >>> caps = simulate_captures("press-fit-cell", files=2, pre_trigger_s=0.1, seed=1)
    >>> [c.metadata["cycle_start_s"] for c in caps]
    [[0.106, 3.25], [0.1, 3.244]]
    """
    from pneufdd.sim.simulate import run_simulation

    stride = cycles_per_file + 1 + (1 if start_in_step else 0)
    cycles = 1 + files * stride
    while True:
        result = run_simulation(
            machine,
            cycles,
            leaks,
            seed,
            progress,
            keep_outputs=False,
            max_cycle_s=max_cycle_s,
            schedule=schedule,
            faults=faults,
            nuisances=nuisances,
        )
        caps = cut_captures(
            result.recording,
            files,
            cycles_per_file,
            pre_trigger_s,
            capture_s,
            start_in_step,
            result.step_start,
        )
        if len(caps) >= files:
            return caps
        per = max(1.0, (cycles - 1) / max(len(caps), 1))
        cycles = 2 + math.ceil(per * files * 1.2)


def start_mid_sequence(recording: Recording, step_start: Any, step: int) -> Recording:
    """A continuous run that starts halfway through step ``step`` (1-based) of its first cycle.

    The solenoids the sequence has on in that step are on at t = 0 (a recording
    started in mid-sequence); the later cycles are whole.

    Examples
    --------
    >>> from pneufdd.sim import run_simulation
    >>> res = run_simulation("press-fit-cell", cycles=2, seed=1, keep_outputs=False)
    >>> rec = start_mid_sequence(res.recording, res.step_start, 4)
    >>> len(rec.metadata["cycle_start_s"]), int(rec.channel("U_PRESS_B")[1][0])
    (1, 1)
    """
    begin = _mid_step(step_start, recording.duration, step)[0]
    part = crop(recording, begin, recording.duration)
    meta = dict(recording.metadata)
    starts = [float(t) for t in meta.get("cycle_start_s", [])]
    meta["cycle_start_s"] = [round(t - begin, 9) for t in starts if t >= begin]
    meta["capture"] = {"kind": "continuous", "start_in_run_s": round(begin, 9)}
    return part.with_metadata(meta)
