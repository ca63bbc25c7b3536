"""Tiny synthetic recordings for the signals/features tests (not a simulator).

Square-wave valve and switch patterns of a 58-step sequence shaped like Fig. 3.4,
with toy analog signals whose exact values the tests know: an s-curve LVDT stroke,
half-sine flow bumps and first-order chamber pressures.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pneufdd import Recording

P_ATM = 101_325.0
P_SUPPLY = 5.3e5
SLPM = 1.294 / 60_000.0  # kg/s per SLPM on the dissertation basis
OTHERS = ["DGPL", "HMPL_HZ", "HMPL_V", "HMPL_VS", "HGD2", "DRQD"]
ACTUATORS = ["DNC", "DRQD", "DGPL", "SLT", "HMPL_H", *OTHERS[:-1]]
STROKE_S = {
    "DNC": 0.38,
    "DRQD": 0.20,
    "DGPL": 0.30,
    "SLT": 0.15,
    "HMPL_H": 0.25,
    "HMPL_HZ": 0.22,
    "HMPL_V": 0.18,
    "HMPL_VS": 0.12,
    "HGD2": 0.10,
}
DNC_STROKE_M = 0.200
T_P = 0.025
PLC_DELAY = 0.045
PULSE = 0.06
VAC_S = 0.12
BUMP_TAIL = 0.03  # flow bumps end 30 ms after arrival, before the next step


def sequence() -> list[list[tuple[str, str]]]:
    """58 steps: (actuator, 'A' extend | 'B' retract | 'V' vacuum on (held) | 'R' its
    release) per parallel motion."""
    steps: list[list[tuple[str, str]]] = [
        [("DRQD", "A")],
        [("DNC", "B"), ("DRQD", "B"), ("HMPL_H", "A")],
        [("HMPL_H", "B"), ("SLT", "A")],
        [("VAC", "V")],
        [("SLT", "B")],
    ]
    for k in range(25):
        act = OTHERS[k % len(OTHERS)]
        steps += [[(act, "A")], [(act, "B")]]
    steps += [[("VAC", "R")], [("SLT", "A")], [("DNC", "A"), ("SLT", "B")]]
    assert len(steps) == 58
    return steps


def valve_sets() -> list[frozenset[str]]:
    out = []
    for step in sequence():
        names = {"V": "U_VAC", "R": "U_VAC:off"}
        out.append(frozenset(names.get(s, f"U_{a}_{s}") for a, s in step))
    return out


@dataclass
class Truth:
    step_starts: list[list[float]] = field(default_factory=list)
    dnc_retract: list[tuple[float, float]] = field(default_factory=list)  # (start, end) [s]
    dnc_extend: list[tuple[float, float]] = field(default_factory=list)
    duration: float = 0.0


def _profile(u: np.ndarray) -> np.ndarray:
    """Travelled fraction of a stroke at time fraction u: a linear speed-up over 30 %
    (constant acceleration), constant speed, cushioning to 40 % speed over the last
    20 %, then the stop. The area under the speed curve is 0.79."""
    v = np.interp(u, [0.0, 0.3, 0.8, 1.0], [0.0, 1.0, 1.0, 0.4])
    dist = np.concatenate([[0.0], np.cumsum((v[1:] + v[:-1]) / 2 * np.diff(u))])
    return dist / 0.79


def make_recording(
    cycles: int = 3,
    leaks: dict[str, float] | None = None,
    seed: int = 0,
    bounce: bool = False,
    nan_fraction: float = 0.0,
    truncate_s: float | None = None,
    stuck: tuple[str, int, float, float] | None = None,
    noise: bool = True,
    forward_only: bool = False,
    digital_rate: float = 100.0,
    analog_rate: float = 1000.0,
) -> tuple[Recording, Truth]:
    """Build a recording of ``cycles`` cycles; ``leaks`` maps 'supply'/'DNC_B'/... to turns."""
    rng = np.random.default_rng(seed)
    leaks = dict(leaks or {})
    supply = leaks.get("supply", 0.0)
    valves: dict[str, list[tuple[float, float]]] = {}
    switch_on: dict[str, list[tuple[float, float]]] = {}
    extended = {a: False for a in ACTUATORS}
    extended["DNC"] = True
    since = {a: 0.0 for a in ACTUATORS}
    motions: list[tuple[str, str, float, float, float]] = []  # act, dir, t_valve, t0, t1
    truth = Truth()
    t = 0.3
    vac_on = 0.0
    for _c in range(cycles):
        starts = []
        for step in sequence():
            starts.append(t)
            arrive = t
            for act, side in step:
                name = "U_VAC" if side in "VR" else f"U_{act}_{side}"
                if side == "V":
                    vac_on = t
                    arrive = max(arrive, t + VAC_S)
                    continue
                if side == "R":
                    valves.setdefault(name, []).append((vac_on, t))
                    arrive = max(arrive, t + VAC_S)
                    continue
                ts = STROKE_S[act] * (1 + 0.01 * rng.standard_normal())
                ts *= 1 + 0.02 * supply
                if act == "DNC":
                    ts *= (
                        (1 + 0.08 * leaks.get("DNC_B", 0))
                        if side == "B"
                        else (1 - 0.02 * leaks.get("DNC_B", 0))
                    )
                    ts *= (1 + 0.08 * leaks.get("DNC_A", 0)) if side == "A" else 1
                t0, t1 = t + T_P, t + T_P + ts
                held = t1 + 0.01 if act == "DNC" else t + PULSE
                valves.setdefault(name, []).append((t, held))
                leave = f"S_{act}_{'A' if side == 'A' else 'B'}"
                reach = f"S_{act}_{'B' if side == 'A' else 'A'}"
                switch_on.setdefault(leave, []).append((since[act], t0 + 0.004))
                since[act] = t1
                extended[act] = side == "A"
                motions.append((act, side, t, t0, t1))
                if act == "DNC":
                    (truth.dnc_extend if side == "A" else truth.dnc_retract).append((t0, t1))
                arrive = max(arrive, t1)
                del reach
            t = arrive + PLC_DELAY + 0.002 * rng.random()
        truth.step_starts.append(starts)
    end = t + 0.5
    for act in ACTUATORS:
        sw = f"S_{act}_{'B' if extended[act] else 'A'}"
        switch_on.setdefault(sw, []).append((since[act], end + 1))
    if truncate_s is not None:
        end = min(end, truncate_s)
    truth.duration = end

    nd = round(end * digital_rate)
    digital: dict[str, np.ndarray] = {}

    def square(intervals: list[tuple[float, float]]) -> np.ndarray:
        delta = np.zeros(nd + 1, dtype=np.int64)
        for a, b in intervals:
            ia = min(int(np.ceil(a * digital_rate - 1e-9)), nd)
            ib = min(int(np.ceil(b * digital_rate - 1e-9)), nd)
            delta[ia] += 1
            delta[ib] -= 1
        return (np.cumsum(delta)[:nd] > 0).astype(np.uint8)

    for act in ACTUATORS:
        for side in "AB":
            digital[f"U_{act}_{side}"] = square(valves.get(f"U_{act}_{side}", []))
            digital[f"S_{act}_{side}"] = square(switch_on.get(f"S_{act}_{side}", []))
    digital["U_VAC"] = square(
        valves["U_VAC"] + ([(vac_on, end + 1)] if vac_on > valves["U_VAC"][-1][0] else [])
    )
    if bounce:
        for name in [n for n in digital if n.startswith("S_")]:
            x = digital[name]
            rises = np.flatnonzero(np.diff(x.astype(np.int8)) > 0) + 1
            for k in rises:
                g = int(rng.integers(1, 3))
                if k + 1 + g < nd and np.all(x[k : k + 1 + g + 1] == 1):
                    x[k + 1 : k + 1 + g] = 0
    if stuck is not None:
        name, value, a, b = stuck
        ia, ib = int(a * digital_rate), int(b * digital_rate)
        digital[name][ia:ib] = value

    na = round(end * analog_rate)
    ta = np.arange(na) / analog_rate
    x = np.full(na, DNC_STROKE_M)
    q_in = np.full(na, 20.0 * supply * SLPM)
    q_a = np.zeros(na)
    q_b = np.zeros(na)
    for act, side, tv, t0, t1 in motions:
        i0, i1 = np.searchsorted(ta, [tv, t1 + BUMP_TAIL])
        u = (ta[i0:i1] - tv) / (t1 + BUMP_TAIL - tv)
        amp = (150.0 if act == "DNC" else 60.0) * SLPM
        if act == "DNC" and side == "B":
            amp *= 1 + 0.1 * leaks.get("DNC_B", 0)
        bump = amp * np.sin(np.pi * u)
        q_in[i0:i1] += bump
        if act == "DNC":
            j0, j1 = np.searchsorted(ta, [t0, t1])
            s = np.minimum(_profile((ta[j0:j1] - t0) / (t1 - t0)), 1.0)
            x[j0:j1] = DNC_STROKE_M * (s if side == "A" else 1 - s)
            x[j1:] = DNC_STROKE_M if side == "A" else 0.0
            fill, exhaust = (q_a, q_b) if side == "A" else (q_b, q_a)
            fill[i0:i1] += bump
            exhaust[i0:i1] -= 0.8 * bump
    p_in = P_SUPPLY - 2.0e7 * q_in
    # First-order chamber pressures after each DNC command.
    cmd_t = np.array([m[2] for m in motions if m[0] == "DNC"])
    cmd_a = np.array([m[1] == "A" for m in motions if m[0] == "DNC"])
    k = np.searchsorted(cmd_t, ta, side="right") - 1
    since_cmd = np.where(k >= 0, ta - cmd_t[np.maximum(k, 0)], np.inf)
    a_on = np.where(k >= 0, cmd_a[np.maximum(k, 0)], True)
    rise = 1 - np.exp(-since_cmd / 0.05)
    b_level = P_SUPPLY - 0.3e5 * leaks.get("DNC_B", 0)
    p_a = np.where(a_on, P_ATM + (P_SUPPLY - P_ATM) * rise, P_SUPPLY - (P_SUPPLY - P_ATM) * rise)
    p_b = np.where(a_on, b_level - (b_level - P_ATM) * rise, P_ATM + (b_level - P_ATM) * rise)
    analog = {
        "P_In": p_in,
        "Q_In": q_in,
        "P_DNC_A": p_a,
        "P_DNC_B": p_b,
        "Q_DNC_A": q_a,
        "Q_DNC_B": q_b,
        "X_DNC": x,
    }
    if forward_only:
        analog["Q_DNC_A"] = np.maximum(q_a, 0.0)
        analog["Q_DNC_B"] = np.maximum(q_b, 0.0)
    if noise:
        analog["X_DNC"] = x + 2e-4 * rng.standard_normal(na)
        analog["P_In"] = p_in + 200.0 * rng.standard_normal(na)
    if nan_fraction > 0:
        for name in analog:
            v = analog[name].copy()
            n_gaps = max(1, int(nan_fraction * na / 10))
            for s0 in rng.integers(0, na - 10, n_gaps):
                v[s0 : s0 + 10] = np.nan
            analog[name] = v
    units = {
        "P_In": "Pa",
        "Q_In": "kg/s",
        "P_DNC_A": "Pa",
        "P_DNC_B": "Pa",
        "Q_DNC_A": "kg/s",
        "Q_DNC_B": "kg/s",
        "X_DNC": "m",
    }
    meta = {
        "machine": "synthetic",
        "leaks": [{"location": loc, "size": size, "unit": "turns"} for loc, size in leaks.items()],
    }
    if forward_only:
        meta["flow_meter_direction"] = "forward"
    rec = Recording.from_arrays(analog, analog_rate, digital, digital_rate, units, metadata=meta)
    return rec, truth
