"""Draft a machine description from a plant's recordings (issue 10, ``pneufdd machine draft``).

What the PLC's signals tell (rules, also in ``docs/calibration.md``):

* **Actuators** from the solenoid and switch channels ``U_<ACT>_A/B``, ``S_<ACT>_A/B``;
  a lone ``U_<ID>`` with ``S_<ID>`` is a vacuum ejector.
* **Valve kind** from the solenoid pattern: one solenoid (``U_<ACT>_A`` only) is a
  5/2 monostable valve (spring return); two solenoids are a 5/2 bistable valve,
  unless line pressure sensors show a chamber cut off from the supply while neither
  solenoid is energised (a 5/3 closed-centre valve traps the air).
* **Sequence** learned from the recording (:func:`pneufdd.signals.learn_sequence`):
  each step's valve events, how each solenoid is released (at its end switch:
  ``until``; after a fixed time: ``for_s``; by a later step: ``hold`` and ``reset``),
  the switch edges it awaits and its dwell timer (the median gap from the last awaited
  edge to the next step).
* **Sensors** from the analog channels, their noise from the sample-to-sample
  scatter; **supply** set point and line restriction from ``P_In`` against ``Q_In``
  (:func:`pneufdd.identification.fit_supply_path`).

What the signals cannot give (bore, stroke, masses, friction, tubes, valve sizes,
vacuum nozzle) gets the documented defaults of :data:`DEFAULTS`, and every such line
of the written TOML ends with ``# assumed``. ``pneufdd machine calibrate`` then fits
what the recordings inform.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.calibration.draft_codes import apply_actuator_code, apply_valve_code, check_code_ids
from pneufdd.calibration.gaps import gaps_repaired
from pneufdd.errors import ChannelError, InputError, describe
from pneufdd.identification.supply import fit_supply_path
from pneufdd.physics.constants import P_ATM, PSI
from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.recording.model import Channel, Recording
from pneufdd.signals.digital import debounced_edges
from pneufdd.signals.quantisation import QUANTISATION_NOISE, quantum
from pneufdd.signals.segmentation import (
    RELEASE,
    StepSpec,
    actuator_of,
    held_valves,
    learn_sequence,
    segment,
)
from pneufdd.sim.description import DRAFT_MODEL

__all__ = ["DEFAULTS", "DraftedMachine", "draft_machine"]


ASSUMED = "assumed"

DEFAULTS: dict[str, Any] = {
    "actuator": {
        "kind": "linear",
        "bore_mm": 20.0,
        "rod_mm": 8.0,
        "stroke_mm": 50.0,
        "moving_mass_kg": 0.5,
        "static_friction_n": 20.0,
        "coulomb_friction_n": 15.0,
        "viscous_friction_n_s_m": 30.0,
        "dead_volume_a_cm3": 1.5,
        "dead_volume_b_cm3": 1.5,
        "tube_length_m": 1.5,
        "tube_inner_diameter_mm": 2.9,
        "meter_out_cv": 0.05,
    },
    "valve": {"cv": 0.16, "xt": 0.9},
    "supply": {
        "house_margin_psi": 20.0,
        "regulator_set_psig": 87.0,
        "regulator_cv": 1.0,
        "reservoir_volume_l": 1.0,
        "line_cv": 0.5,
        "manifold_volume_l": 0.05,
    },
    "vacuum": {
        "nozzle_diameter_mm": 0.95,
        "evacuation_time_s": 0.12,
        "release_time_s": 0.06,
    },
}
"""Defaults for what the signals cannot tell: an ISO 6432 20 mm cylinder (the most
common small actuator), 4 mm tubing (PUN-4, 2.9 mm bore) of 1.5 m, a 4 mm-port
valve (Cv 0.16, about 160 l/min), a one-way flow control half open, a 6 bar(g)
supply. Each is marked ``# assumed`` in the draft."""

UNTIL_TOLERANCE_S = 0.03
"""A solenoid released within this time of its end switch's arrival is ``until`` [s]:
one PLC scan plus the 100 Hz sampling of both signals."""


@dataclass
class _Line:
    key: str
    value: Any
    note: str = ""


@dataclass
class DraftedMachine:
    """A drafted description: the TOML mapping and, per key path, how it was obtained."""

    data: dict[str, Any]
    notes: dict[str, str] = field(default_factory=dict)

    def to_toml(self, header: str = "") -> str:
        """The description as TOML, each assumed line marked ``# assumed``."""
        out = [f"# {line}" if line else "#" for line in header.splitlines()]
        out.append("# Lines ending in '# assumed' are defaults the signals cannot tell;")
        out.append("# 'pneufdd machine calibrate' fits what the recordings inform.")
        for section in ("machine", "supply", "vacuum"):
            if section in self.data:
                out += ["", f"[{section}]"]
                out += self._items(self.data[section], section)
        for i, act in enumerate(self.data.get("actuator", [])):
            out += ["", "[[actuator]]"]
            out += self._items(act, f"actuator[{i}]")
        for i, sensor in enumerate(self.data.get("sensor", [])):
            out += ["", "[[sensor]]"]
            out += self._items(sensor, f"sensor[{i}]")
        for i, step in enumerate(self.data.get("step", [])):
            out += ["", f"[[step]]  # {i + 1}"]
            out += self._items(step, f"step[{i}]")
        return "\n".join(out) + "\n"

    def _items(self, table: dict[str, Any], path: str) -> list[str]:
        lines = []
        for key, value in table.items():
            note = self.notes.get(f"{path}.{key}", "")
            text = f"{key} = {_toml(value)}"
            lines.append(f"{text:<44} # {note}" if note else text)
        return lines


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(round(value, 6))
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    raise TypeError(type(value).__name__)  # pragma: no cover - only the types above


def _edge_times(recording: Recording, name: str, dwell_s: float) -> tuple[FloatArray, FloatArray]:
    info = recording.info(name)
    clean, e = debounced_edges(info.values, info.rate_hz, dwell_s)
    rising = np.r_[0, e.rising] if clean.size and clean[0] == 1 else e.rising
    return info.t0 + rising / info.rate_hz, info.t0 + e.falling / info.rate_hz


def _actuators(recording: Recording) -> tuple[list[str], str | None]:
    valves = [n for n in recording.digital_channels if n.startswith("U_")]
    switches = [n for n in recording.digital_channels if n.startswith("S_")]
    ids: list[str] = []
    vacuum = None
    for name in valves + switches:
        if name.endswith(("_A", "_B")):
            ident = actuator_of(name[2:])
            if ident not in ids:
                ids.append(ident)
        elif name.startswith("U_"):
            if vacuum not in (None, name[2:]):
                raise ChannelError(
                    describe("solenoids without _A/_B (vacuum ejectors)", [vacuum, name[2:]], "one")
                )
            vacuum = name[2:]
    if not ids:
        raise ChannelError(
            describe("actuator channels U_<ACT>_A/B", valves, "at least one actuator's solenoid")
        )
    return ids, vacuum


def _median(values: Sequence[float]) -> float:
    return float(np.median(values)) if len(values) else float("nan")


def _release_mode(
    recording: Recording,
    solenoid: str,
    starts: FloatArray,
    ends: FloatArray,
    arrival: str | None,
) -> tuple[str, float]:
    """``("until", 0)``, ``("pulse", for_s)`` or ``("hold", 0)`` for a set solenoid."""
    rise, fall = _edge_times(recording, solenoid, 0.015)
    held, until, widths = 0, 0, []
    arr = _edge_times(recording, arrival, 0.025)[0] if arrival else np.empty(0)
    for lo, hi in zip(starts, ends, strict=True):
        r = rise[(rise >= lo - 0.011) & (rise <= lo + 0.011)]
        if r.size == 0:
            continue
        f = fall[fall > r[0]]
        if f.size == 0:
            held += 1
            continue
        a = arr[(arr > r[0]) & (arr <= f[0] + UNTIL_TOLERANCE_S)]
        if a.size and abs(f[0] - a[-1]) <= UNTIL_TOLERANCE_S:
            until += 1
        elif f[0] >= hi - 0.011:
            held += 1
        else:
            widths.append(float(f[0] - r[0]))
    if until >= max(held, len(widths)) and until > 0:
        return "until", 0.0
    if held >= len(widths):
        return "hold", 0.0
    return "pulse", round(max(_median(widths), 0.01), 2)


def _awaited_edge_times(
    recording: Recording, switches: Sequence[tuple[str, int]], lo: float, hi: float
) -> float:
    last = lo
    for name, state in switches:
        rise, fall = _edge_times(recording, name, 0.025)
        times = rise if state == 1 else fall
        inside = times[(times > lo + 1e-9) & (times <= hi + 1e-9)]
        if inside.size:
            last = max(last, float(inside[0]))
    return last


def _closed_centre(recording: Recording, ident: str) -> bool | None:
    """Whether line pressures show a closed centre; None without line sensors."""
    names = [f"P_{ident}_A", f"P_{ident}_B", f"U_{ident}_A", f"U_{ident}_B", "P_In"]
    if not all(n in recording.channels for n in names):
        return None
    t, pin = recording.channel("P_In")
    gaps = []
    for side in "AB":
        _, p = recording.channel(f"P_{ident}_{side}")
        tu, ua = recording.channel(f"U_{ident}_A")
        _, ub = recording.channel(f"U_{ident}_B")
        last_side = np.zeros(tu.size, dtype=bool)  # the valve was last driven to this side
        state = 0
        for k in range(tu.size):
            if ua[k] and not ub[k]:
                state = 1
            elif ub[k] and not ua[k]:
                state = 2
            last_side[k] = state == (1 if side == "A" else 2) and not (ua[k] or ub[k])
        idx = np.clip(np.searchsorted(tu, t, side="right") - 1, 0, tu.size - 1)
        # samples a DAQ left empty (NaN) say nothing about the valve
        mask = last_side[idx] & np.isfinite(pin) & np.isfinite(p)
        if np.count_nonzero(mask) > 100:
            gaps.append(float(np.median(pin[mask] - p[mask])))
    if not gaps:
        return None
    return max(gaps) > 0.2e5


def _releases(recording: Recording, ids: Sequence[str]) -> frozenset[str]:
    """Solenoids whose release is a PLC command that starts a step.

    A spring-return (single-solenoid) valve or a vacuum valve moves on release; a
    solenoid held across steps (:func:`~pneufdd.signals.segmentation.held_valves`) is
    released by a later step; so is one whose release coincides with another
    solenoid firing but not with the arrival of its own actuator at the end it drives
    to (a ``reset`` in the next step, not an ``until``).
    """
    solenoids = [n for n in recording.digital_channels if n.startswith("U_")]
    out = set(held_valves(recording))
    edges_of = {n: _edge_times(recording, n, 0.015) for n in solenoids}
    for name in solenoids:
        ident, _, side = name[2:].rpartition("_")
        if not name.endswith(("_A", "_B")) or (
            ident in ids and side == "A" and f"U_{ident}_B" not in recording.channels
        ):
            out.add(name)
            continue
        falls = edges_of[name][1]
        if falls.size == 0:
            continue
        others = np.sort(np.concatenate([edges_of[o][0] for o in solenoids if o != name]))
        target = f"S_{ident}_{'B' if side == 'A' else 'A'}"
        arrivals = (
            _edge_times(recording, target, 0.025)[0]
            if target in recording.channels
            else np.empty(0)
        )

        def near(times: FloatArray, at: FloatArray, tol: float) -> npt.NDArray[np.bool_]:
            if times.size == 0:
                return np.zeros(at.size, dtype=bool)
            k = np.clip(np.searchsorted(times, at), 1, times.size - 1)
            gap = np.minimum(np.abs(times[k] - at), np.abs(times[k - 1] - at))
            return np.asarray(gap <= tol)

        with_step = near(others, falls, 0.011)
        with_arrival = near(arrivals, falls, UNTIL_TOLERANCE_S)
        if np.mean(with_step & ~with_arrival) > 0.5:
            out.add(name)
    return frozenset(out)


def _step_times(
    recording: Recording, sequence: Sequence[StepSpec]
) -> tuple[FloatArray, FloatArray]:
    """Start and end of every step of the complete cycles (cycles x steps) [s]."""
    cycles = list(segment(recording, sequence).complete)
    if not cycles:
        raise InputError(describe("complete cycles of the first recording", 0, ">= 1"))
    starts = np.array([[s.start_s for s in c.steps] for c in cycles])
    ends = np.array([[s.end_s for s in c.steps] for c in cycles])
    return starts, ends


def _draft_machine_table(
    recording: Recording, name: str, n_recordings: int, notes: dict[str, str]
) -> dict[str, Any]:
    """The ``[machine]`` table: name, title and a PLC scan time within the sampling."""
    rate = recording.rate(recording.digital_channels[0])
    notes["machine.scan_time_s"] = ASSUMED
    return {
        "name": name,
        "title": f"{name}: drafted from {n_recordings} recording(s) by pneufdd machine draft",
        "scan_time_s": round(min(0.005, 0.5 / rate), 4),
    }


def _supply_set_point(recording: Recording) -> tuple[float, float, str]:
    """Regulator set point [psig], supply line Cv [-] and how they were found.

    From ``P_In`` against ``Q_In`` (eq. 4.20) when both are recorded, else the set
    point from the highest ``P_In``; otherwise the defaults.
    """
    sup = DEFAULTS["supply"]
    set_psig, line_cv, how = sup["regulator_set_psig"], sup["line_cv"], ASSUMED
    if "P_In" in recording.channels and "Q_In" in recording.channels:
        p = recording.channel("P_In")[1].astype(np.float64)
        q = recording.channel("Q_In")[1].astype(np.float64)
        n = min(p.size, q.size)
        fit = fit_supply_path(p[:n], q[:n])
        if np.isfinite(fit.path_cv) and np.isfinite(fit.path_set_point_pa):
            set_psig = (fit.path_set_point_pa - P_ATM) / PSI
            line_cv = fit.path_cv
            how = "from P_In against Q_In (eq. 4.20)"
    elif "P_In" in recording.channels:
        p = recording.channel("P_In")[1].astype(np.float64)
        set_psig = (float(np.nanpercentile(p, 99)) - P_ATM) / PSI
        how = "from the highest P_In"
    return set_psig, line_cv, how


def _draft_supply(recording: Recording, notes: dict[str, str]) -> dict[str, Any]:
    """The ``[supply]`` table: set point and line from the signals, the rest assumed."""
    sup = DEFAULTS["supply"]
    set_psig, line_cv, how = _supply_set_point(recording)
    set_psig = float(np.clip(set_psig, 5.0, 140.0))
    supply: dict[str, Any] = {}
    supply["house_psig"] = round(set_psig + sup["house_margin_psi"], 2)
    notes["supply.house_psig"] = ASSUMED
    supply["regulator_set_psig"] = round(set_psig, 2)
    notes["supply.regulator_set_psig"] = how
    for key in ("regulator_cv", "reservoir_volume_l"):
        supply[key] = sup[key]
        notes[f"supply.{key}"] = ASSUMED
    supply["line_cv"] = round(float(np.clip(line_cv, 0.02, 50.0)), 4)
    notes["supply.line_cv"] = how
    supply["manifold_volume_l"] = sup["manifold_volume_l"]
    notes["supply.manifold_volume_l"] = ASSUMED
    return supply


def _draft_vacuum(ident: str, notes: dict[str, str]) -> dict[str, Any]:
    """The ``[vacuum]`` table of the ejector ``ident``: every value assumed."""
    for key in DEFAULTS["vacuum"]:
        notes[f"vacuum.{key}"] = ASSUMED
    return {"id": ident, **DEFAULTS["vacuum"]}


def _draft_actuator(
    recording: Recording, i: int, ident: str, notes: dict[str, str]
) -> dict[str, Any]:
    """The ``i``-th ``[[actuator]]``: stroke from its position, valve kind from its
    solenoids (and line pressures), initial position from its switches."""
    rec = recording
    act: dict[str, Any] = {"id": ident, "model": DRAFT_MODEL}
    for key, value in DEFAULTS["actuator"].items():
        act[key] = value
        notes[f"actuator[{i}].{key}"] = ASSUMED
    if f"X_{ident}" in rec.channels:
        x = rec.channel(f"X_{ident}")[1].astype(np.float64) * 1e3
        lo, hi = np.nanpercentile(x, [1, 99])
        act["stroke_mm"] = round(float(hi - lo), 1)
        notes[f"actuator[{i}].stroke_mm"] = f"from X_{ident}"
    has_b = f"U_{ident}_B" in rec.channels
    closed = _closed_centre(rec, ident) if has_b else None
    kind = "5/2-bistable" if has_b else "5/2-monostable"
    if closed:
        kind = "5/3-closed-centre"
    at_b = f"S_{ident}_B" in rec.channels and int(rec.channel(f"S_{ident}_B")[1][0]) == 1
    act["initial"] = "extended" if at_b and has_b else "retracted"
    notes[f"actuator[{i}].initial"] = "from the switches at the start"
    act["valve"] = {"kind": kind, **DEFAULTS["valve"]}
    valve_how = (
        "kind from the solenoids and line pressures"
        if closed is not None
        else "kind from the solenoids"
    )
    notes[f"actuator[{i}].valve"] = f"{valve_how}; cv, xt assumed"
    return act


def _sensor_location(channel: str, ids: Sequence[str]) -> str | None:
    """``supply`` or ``<ACT>[_A/_B]`` of a pressure, flow or position channel, else None."""
    if channel in ("P_In", "Q_In"):
        return "supply"
    if (channel[:2] in ("P_", "Q_") and channel[2:-2] in ids) or (
        channel.startswith("X_") and channel[2:] in ids
    ):
        return channel[2:]
    return None


def _shown_range(kind: str, values: FloatArray) -> tuple[FloatArray, list[float]]:
    """Values in the sensor's display unit (bar gauge, SLPM, mm) and a standard range
    above them."""
    if kind == "pressure":
        shown = (values - P_ATM) / 1e5
        return shown, [0.0, 10.0 if np.nanmax(shown) < 9.5 else 16.0]
    if kind == "flow":
        shown = np.asarray(kg_s_to_slpm(values))
        top = float(np.nanmax(shown))
        return shown, [0.0, float(next((r for r in (50, 200, 500, 1000, 5000) if r > top), 10000))]
    shown = values * 1e3
    lo, hi = float(np.nanmin(shown)), float(np.nanmax(shown))
    pad = 0.15 * (hi - lo) + 5.0
    return shown, [round(lo - pad, 1), round(hi + pad, 1)]


def _draft_sensors(
    recording: Recording, ids: Sequence[str], notes: dict[str, str]
) -> list[dict[str, Any]]:
    """The ``[[sensor]]`` tables of the analog channels the twin can simulate; noise
    from the sample-to-sample scatter, range assumed."""
    sensors: list[dict[str, Any]] = []
    for channel in recording.analog_channels:
        values = recording.channel(channel)[1].astype(np.float64)
        location = _sensor_location(channel, ids)
        if location is None:
            continue
        kind = {"P": "pressure", "Q": "flow", "X": "position"}[channel[0]]
        shown, rng = _shown_range(kind, values)
        diffs = np.diff(shown[np.isfinite(shown)])
        noise = float(np.median(np.abs(diffs)) / 0.6745 / np.sqrt(2.0)) if diffs.size else 0.0
        # a quantised channel's scatter is mostly zero: its noise is at least the
        # rounding error's (signals/quantisation.py), in the shown unit
        step = quantum(shown)
        sensor: dict[str, Any] = {"channel": channel, "kind": kind, "location": location}
        sensor["range"] = rng
        sensor["noise"] = round(max(noise, step * QUANTISATION_NOISE), 4)
        k = len(sensors)
        notes[f"sensor[{k}].range"] = ASSUMED + " (a standard range above the data)"
        notes[f"sensor[{k}].noise"] = (
            f"quantised in steps of {step:.4g}: the rounding error's, step / sqrt(12)"
            if noise < step * QUANTISATION_NOISE
            else "from the sample-to-sample scatter"
        )
        if kind == "flow":
            sensor["direction"] = "forward" if np.nanmin(shown) > -0.5 else "bidirectional"
            sensor["time_constant_s"] = 0.015
            notes[f"sensor[{k}].time_constant_s"] = ASSUMED
        sensors.append(sensor)
    return sensors


def _valve_actions(
    recording: Recording,
    spec: StepSpec,
    ids: Sequence[str],
    starts: FloatArray,
    ends: FloatArray,
) -> list[dict[str, Any]]:
    """A step's ``do`` list: each solenoid set until its end switch, for a time or
    held, and each released one reset."""
    do: list[dict[str, Any]] = []
    for event in sorted(spec.valves):
        if event.endswith(RELEASE):
            do.append({"reset": event.removesuffix(RELEASE)})
            continue
        ident, _, side = event[2:].rpartition("_")
        arrival = None
        if ident in ids and side in "AB":
            target = f"S_{ident}_{'B' if side == 'A' else 'A'}"
            arrival = target if target in recording.channels else None
        mode, width = _release_mode(recording, event, starts, ends, arrival)
        if mode == "until" and arrival is not None:
            do.append({"set": event, "until": arrival})
        elif mode == "pulse":
            do.append({"set": event, "for_s": width})
        else:
            do.append({"set": event})
    return do


def _draft_step(
    recording: Recording,
    j: int,
    spec: StepSpec,
    ids: Sequence[str],
    starts: FloatArray,
    ends: FloatArray,
) -> dict[str, Any]:
    """The ``j``-th ``[[step]]``: its valve actions, the switch edges it awaits and its
    dwell timer (the median gap from the last awaited edge to the step's end), from
    its ``starts`` and ``ends`` in every cycle [s]."""
    rising = sorted(s for s, state in spec.switches if state == 1)
    falling = sorted(s for s, state in spec.switches if state == 0)
    do = _valve_actions(recording, spec, ids, starts, ends)
    step: dict[str, Any] = {"name": f"step {j + 1}: " + ", ".join(sorted(spec.valves))}
    step["do"] = do
    until = sorted(a["until"] for a in do if "until" in a)
    awaited: list[tuple[str, int]] = [(s, 1) for s in rising]
    if rising != until:
        step["wait"] = rising
    if not rising and falling:
        step["wait_off"] = falling
        awaited = [(s, 0) for s in falling]
    gaps = [
        ends[c] - _awaited_edge_times(recording, awaited, starts[c], ends[c])
        for c in range(len(starts))
    ]
    dwell = _median(gaps)
    if dwell >= 0.03:
        step["dwell_s"] = round(dwell, 2)
    return step


def _joined(recordings: Sequence[Recording]) -> Recording:
    """The recordings end to end (triggered captures of one cycle each), time from 0.

    Raises
    ------
    InputError
        If they do not have the same channels at the same rates.
    """
    first = recordings[0]
    layout = [(n, first.info(n).rate_hz, first.info(n).unit) for n in first.channels]
    channels = []
    for k, rec in enumerate(recordings[1:], start=2):
        mine = [(n, rec.info(n).rate_hz, rec.info(n).unit) for n in rec.channels]
        if mine != layout:
            raise InputError(
                describe(
                    f"channels of recording {k} (to join short captures)",
                    [m[0] for m in mine],
                    f"those of the first: {[m[0] for m in layout]} at the same rates",
                )
            )
    for name, rate, unit in layout:
        info = first.info(name)
        values = np.concatenate([rec.info(name).values for rec in recordings])
        channels.append(Channel(name, values, rate, unit, info.kind, info.t0))
    return Recording(channels, start_time=first.start_time, metadata=first.metadata)


def draft_machine(
    recordings: Sequence[Recording],
    name: str = "drafted",
    actuator_codes: Mapping[str, str] | None = None,
    valve_codes: Mapping[str, str] | None = None,
) -> DraftedMachine:
    """Draft a machine description from leak-free recordings of a plant.

    Parameters
    ----------
    recordings : sequence of Recording
        Leak-free recordings (the first, of at least two full cycles starting at the
        sequence's first step, teaches the sequence; when it holds fewer, as a
        triggered capture of one cycle does, all of them joined end to end do).
    name : str
        Machine name.
    actuator_codes, valve_codes : mapping of str to str, optional
        Order codes by actuator id (``{"PRESS": "DSBC-63-100-PPVA-N3"}``): the values
        they give replace the assumed ones, each marked in the TOML with its catalogue
        source (:mod:`pneufdd.calibration.draft_codes`, ``docs/catalogue.md``).

    Returns
    -------
    DraftedMachine
        ``.data`` parses with :func:`pneufdd.sim.load_machine`; ``.to_toml()`` writes it.

    Raises
    ------
    ChannelError
        Without solenoid channels.
    InputError
        Without two repeating cycles; for a code of an actuator the signals do not
        have, a code that does not resolve, or a valve code contradicting the solenoids.
    """
    if not recordings:
        raise InputError(describe("recordings", 0, "at least one"))
    rec = gaps_repaired(recordings[0])  # the gap rule: no inf or 1e308 reaches a statistic
    ids, vacuum = _actuators(rec)
    actuator_codes = dict(actuator_codes or {})
    valve_codes = dict(valve_codes or {})
    check_code_ids(actuator_codes, ids, "--actuator")
    check_code_ids(valve_codes, ids, "--valve")
    try:
        sequence: tuple[StepSpec, ...] = learn_sequence(rec, release=_releases(rec, ids))
    except InputError:
        if len(recordings) < 2:
            raise
        # short captures (one cycle each): learned from all of them joined end to end
        rec = _joined(recordings)
        sequence = learn_sequence(rec, release=_releases(rec, ids))
    starts, ends = _step_times(rec, sequence)
    notes: dict[str, str] = {}
    data: dict[str, Any] = {}
    data["machine"] = _draft_machine_table(rec, name, len(recordings), notes)
    data["supply"] = _draft_supply(rec, notes)
    if vacuum is not None:
        data["vacuum"] = _draft_vacuum(vacuum, notes)
    data["actuator"] = [_draft_actuator(rec, i, ident, notes) for i, ident in enumerate(ids)]
    for i, act in enumerate(data["actuator"]):
        if act["id"] in actuator_codes:
            measured = notes[f"actuator[{i}].stroke_mm"].startswith("from X_")
            stroke = float(act["stroke_mm"]) if measured else None
            apply_actuator_code(act, i, actuator_codes[act["id"]], notes, stroke)
        if act["id"] in valve_codes:
            apply_valve_code(act, i, valve_codes[act["id"]], notes)
    data["sensor"] = _draft_sensors(rec, ids, notes)
    data["step"] = [
        _draft_step(rec, j, spec, ids, starts[:, j], ends[:, j]) for j, spec in enumerate(sequence)
    ]
    return DraftedMachine(data, notes)
