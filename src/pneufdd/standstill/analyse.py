"""Recordings of a standstill test -> one measurement per state and meter.

:func:`held_states` finds, in a recording, the intervals in which the machine held
one of the plan's states: every actuator at the state's end (its end switch), a
monostable valve's solenoid on or off as the state has it, a 5/3 closed-centre valve
held energised at the pressurised end or with both solenoids off in its centre. Only
an interval of at least the plan's settle time and 90 % of its window counts.
:func:`measure_states` then reads each interval:

* ``flow`` mode: the median of the supply flow meter (and of each line flow meter)
  over the last ``window_s`` of the interval, and the median supply pressure. The
  median, not the mean: a forward-only meter clips its noise at zero flow (press-fit-
  cell's SFAB reads 0.8 SLPM on average with no flow, its median 0);
* ``decay`` mode: the pressure from the supply shut-off valve's closing (the rising
  edge of ``U_SHUTOFF`` when recorded, else :func:`~pneufdd.identification.decay.
  decay_start`) over at most its first bar of fall, fitted with the twin's thermal
  model (:func:`~pneufdd.identification.decay.fit_pressure_decay`, the state's
  volume-weighted thermal time constant): the leaks' total ``Cd A / V``, times the
  state's connected volume, is their total effective area.

:mod:`pneufdd.standstill.estimate` turns the measurements into leaks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.errors import ChannelError, InputError, describe
from pneufdd.identification.decay import decay_start, fit_pressure_decay
from pneufdd.recording import Recording
from pneufdd.standstill.plan import MAX_DROP_PA, StandstillPlan

__all__ = ["SHUTOFF_CHANNEL", "Measurement", "held_states", "measure_states"]

SHUTOFF_CHANNEL = "U_SHUTOFF"
"""The recorded PLC output of the supply shut-off valve (1 = closed), decay mode."""
METER_LAG_SAMPLES = 30
"""Samples over which a flow meter's reading is correlated (its 15 ms response at
1 kHz, twice): the effective count of a window's median is its samples / 30."""


@dataclass(frozen=True)
class Measurement:
    """One state held once, as measured.

    Attributes
    ----------
    state : int
        Index into the plan's states.
    start_s, end_s : float
        The interval the state was held [s].
    pressure_pa : float
        Median supply pressure over the window (flow) or at the closing (decay) [Pa].
    flows_kg_s : dict of str to (float, float)
        Flow mode: per meter channel, its median reading and standard error [kg/s].
    area_m2 : float
        Decay mode: the leaks' total effective area [m^2] (NaN in flow mode).
    area_std_m2 : float
        Its standard error from the fit [m^2].
    recording : int
        Index of the recording it came from.
    """

    state: int
    start_s: float
    end_s: float
    pressure_pa: float
    flows_kg_s: dict[str, tuple[float, float]]
    area_m2: float = float("nan")
    area_std_m2: float = float("nan")
    recording: int = 0


def _on_grid(rec: Recording, name: str, grid: FloatArray) -> npt.NDArray[np.bool_]:
    if name not in rec.channels:
        raise ChannelError(describe("channels of the standstill recording", name, "recorded"))
    t, v = rec.channel(name)
    k = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 1)
    return np.asarray(v[k] > 0.5)


def held_states(rec: Recording, plan: StandstillPlan) -> list[tuple[int, float, float]]:
    """``(state index, start, end)`` of every interval the recording holds a state [s].

    Raises
    ------
    ChannelError
        If an end switch or a solenoid the states need is not recorded.
    """
    switches = [f"S_{i}_{s}" for i in plan.valve_kinds for s in "AB"]
    t, _ = rec.channel(switches[0])
    grid = t
    on = {name: _on_grid(rec, name, grid) for name in switches}
    for ident, kind in plan.valve_kinds.items():
        names = [f"U_{ident}_A"] if kind == "5/2-monostable" else [f"U_{ident}_A", f"U_{ident}_B"]
        if kind != "5/2-bistable":
            for name in names:
                on[name] = _on_grid(rec, name, grid)
    need = plan.settle_s + 0.9 * plan.window_s
    out = []
    for k, state in enumerate(plan.states):
        ok = np.ones(grid.size, dtype=bool)
        for ident, kind in plan.valve_kinds.items():
            ext = on[f"S_{ident}_B"] & ~on[f"S_{ident}_A"]
            ok &= ext if state.ends[ident] == "extended" else ~ext & on[f"S_{ident}_A"]
            position = state.positions[ident]
            if kind == "5/2-monostable":
                ok &= on[f"U_{ident}_A"] == (position == "A")
            elif kind == "5/3-closed-centre":
                ok &= on[f"U_{ident}_A"] == (position == "A")
                ok &= on[f"U_{ident}_B"] == (position == "B")
        edges = np.diff(np.r_[0, ok.astype(np.int8), 0])
        for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0], strict=True):
            start, end = float(grid[a]), float(grid[b - 1])
            if end - start >= need:
                out.append((k, start, end))
    return sorted(out, key=lambda x: x[1])


def _window(rec: Recording, name: str, lo: float, hi: float) -> tuple[FloatArray, FloatArray]:
    t, v = rec.channel(name)
    sel = (t >= lo) & (t <= hi) & np.isfinite(v)
    return t[sel], np.asarray(v[sel], dtype=np.float64)


def _median(values: FloatArray) -> tuple[float, float]:
    """Median and its standard error over correlated samples [the values' unit]."""
    if values.size == 0:
        return float("nan"), float("nan")
    steps = np.diff(np.unique(values))
    quantum = float(steps.min()) if steps.size else 0.0
    n_eff = max(values.size / METER_LAG_SAMPLES, 1.0)
    spread = 1.2533 * float(np.std(values)) / np.sqrt(n_eff)
    return float(np.median(values)), float(np.hypot(spread, quantum / np.sqrt(12.0)))


def _flow(
    rec: Recording, plan: StandstillPlan, k: int, start: float, end: float, index: int
) -> Measurement:
    lo, hi = max(start, end - plan.window_s), end - 0.05
    flows = {}
    for channel in [plan.supply_flow_channel, *plan.line_flow_channels.values()]:
        if channel not in rec.channels:
            raise ChannelError(
                describe("channels of the standstill recording", channel, "recorded")
            )
        flows[channel] = _median(_window(rec, channel, lo, hi)[1])
    pressure = float("nan")
    if plan.supply_pressure_channel in rec.channels:
        pressure = _median(_window(rec, plan.supply_pressure_channel, lo, hi)[1])[0]
    return Measurement(k, start, end, pressure, flows, recording=index)


def _closing(rec: Recording, t: FloatArray, p: FloatArray, start: float) -> int:
    """Index of the shut-off valve's closing in a decay window."""
    if SHUTOFF_CHANNEL in rec.channels:
        closed = _on_grid(rec, SHUTOFF_CHANNEL, t)
        rising = np.nonzero(np.diff(closed.astype(np.int8)) == 1)[0]
        if rising.size:
            return int(rising[0]) + 1
    return decay_start(t, p) if p.size >= 5 else 0


def _decay(
    rec: Recording, plan: StandstillPlan, k: int, start: float, end: float, index: int
) -> Measurement:
    state = plan.states[k]
    channel = plan.supply_pressure_channel
    if channel not in rec.channels:
        raise ChannelError(describe("channels of the standstill recording", channel, "recorded"))
    t, p = _window(rec, channel, start + 0.5 * plan.settle_s, end - 0.05)
    first = _closing(rec, t, p, start)
    t, p = t[first:], p[first:]
    # a fall of at most one bar (docs/physics-validation.md), at least 0.5 s of it
    keep = np.nonzero(p < p[0] - MAX_DROP_PA)[0] if p.size else np.empty(0, dtype=int)
    stop = max(int(keep[0]) if keep.size else p.size, min(p.size, 500))
    t, p = t[:stop], p[:stop]
    if p.size < 5:
        raise InputError(
            describe(f"samples of {channel} in the decay of state {state.name!r}", p.size, ">= 5")
        )
    # decimate to at most 500 samples: the fit integrates the curve per evaluation
    step = max(p.size // 500, 1)
    fit = fit_pressure_decay(t[::step], p[::step], model="thermal",
                             thermal_time_s=state.thermal_time_s)  # fmt: skip
    volume = state.connected_volume_m3
    return Measurement(
        k,
        start,
        end,
        float(fit.initial_pressure_pa),
        {},
        area_m2=fit.conductance_per_volume * volume,
        area_std_m2=fit.conductance_std * volume,
        recording=index,
    )


def measure_states(recordings: Sequence[Recording], plan: StandstillPlan) -> list[Measurement]:
    """Every state held in ``recordings``, measured (module docstring).

    Raises
    ------
    InputError
        If no recording holds any state of the plan long enough.
    """
    out = []
    for index, rec in enumerate(recordings):
        for k, start, end in held_states(rec, plan):
            read = _flow if plan.mode == "flow" else _decay
            out.append(read(rec, plan, k, start, end, index))
    if not out:
        raise InputError(
            describe(
                "states of the plan held in the recordings",
                0,
                f"at least one held for {plan.settle_s:g} s + {plan.window_s:g} s "
                "(the recording covers the standstill test, its switches and solenoids)",
            )
        )
    return out
