"""A small synthetic sequenced machine for the diagnosis engine's tests.

Two actuators X and Y on one supply; 12 steps. X's extend line (X_A) is pressurised
in steps 3-7, its retract line (X_B) in the others; Y_A in steps 9-11, Y_B in the
others. A leak adds flow to Q_In in the steps its line is pressurised (section
5.3.1.2-5.3.1.3) and lowers the supply pressure slightly; X's own lines carry
sensors P_X_A, Q_X_A. The house air fluctuates from cycle to cycle (section 4.4.1):
all pressures and flows scale together with the supply level. Effects are mildly
nonlinear in leak size.
"""

from __future__ import annotations

import numpy as np

from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.features.step_table import StepTable

N_STEPS = 12
CHANNELS = ("P_In", "Q_In", "P_X_A", "Q_X_A")
UNITS = ("Pa", "kg/s", "Pa", "kg/s")
LOCATIONS = ("supply", "X_A", "X_B", "Y_A", "Y_B")
STEPS = np.arange(N_STEPS)
ACTIVE = {
    "supply": np.ones(N_STEPS, bool),
    "X_A": (STEPS >= 2) & (STEPS <= 6),
    "X_B": ~((STEPS >= 2) & (STEPS <= 6)),
    "Y_A": (STEPS >= 8) & (STEPS <= 10),
    "Y_B": ~((STEPS >= 8) & (STEPS <= 10)),
}
BASE_FLOW = 1e-3 * (1.0 + 0.8 * np.sin(STEPS))  # [kg/s]
BASE_DURATION = 0.3 + 0.05 * (STEPS % 3)  # [s]


def _nonlinear(size: float) -> float:
    return size * (1.0 - 0.15 * size / 2e-3)


def _means(leaks: dict[str, float], supply_level: np.ndarray) -> np.ndarray:
    """Noise-free summaries (n, steps, channels, 3) and durations."""
    n = supply_level.size
    scale = 1.0 + 0.03 * supply_level[:, None]
    q_in = BASE_FLOW * scale
    p_in = 6.0e5 * (1.0 + 0.02 * supply_level[:, None]) * np.ones((n, N_STEPS))
    p_xa = np.where(ACTIVE["X_A"], 5.5e5, 1.2e5) * (1.0 + 0.02 * supply_level[:, None])
    q_xa = np.where(ACTIVE["X_A"], 4e-4, 0.0) * scale
    dur = BASE_DURATION * (1.0 - 0.02 * supply_level[:, None])
    for loc, size in leaks.items():
        eff = _nonlinear(size)
        q_in = q_in + eff * ACTIVE[loc]
        p_in = p_in - 2.0e7 * eff * np.ones(N_STEPS)
        if loc == "X_A":
            q_xa = q_xa + eff * ACTIVE["X_A"]
            p_xa = p_xa - 3.0e7 * eff * ACTIVE["X_A"]
            dur = dur + 20.0 * eff * (STEPS == 2)
        if loc == "X_B":
            p_xa = p_xa + 1.0e7 * eff * ~ACTIVE["X_A"]
            dur = dur + 20.0 * eff * (STEPS == 7)
    return np.stack([p_in, q_in, p_xa, q_xa], axis=2), dur


def synth_table(
    n_cycles: int,
    leaks: dict[str, float] | None = None,
    seed: int = 0,
    fluctuation: float = 1.0,
    level_offset: float = 0.0,
    machine: str = "synth",
    with_traces: bool = True,
) -> StepTable:
    """Cycles of the synthetic machine with the given leaks (mass flow [kg/s])."""
    rng = np.random.default_rng(seed)
    level = level_offset + fluctuation * rng.normal(size=n_cycles)
    means, dur = _means(leaks or {}, level)
    noise = np.array([300.0, 5e-6, 300.0, 5e-6])
    mean_vals = means + noise * rng.normal(size=means.shape)
    summaries = np.stack([mean_vals, mean_vals - 2 * noise, mean_vals + 2 * noise], axis=3)
    summaries[..., 1] += noise * rng.normal(size=means.shape)
    summaries[..., 2] += noise * rng.normal(size=means.shape)
    dur = dur + 2e-3 * rng.normal(size=dur.shape)
    start = np.cumsum(np.concatenate([np.zeros((n_cycles, 1)), dur[:, :-1]], axis=1), axis=1)
    start += 10.0 * np.arange(n_cycles)[:, None]
    traces = offsets = None
    if with_traces:
        per_step = 20
        offsets = np.arange(N_STEPS + 1) * per_step
        shape = np.linspace(0.5, 1.5, per_step)
        traces = np.repeat(mean_vals.transpose(0, 2, 1), per_step, axis=2) * np.tile(shape, N_STEPS)
        traces = traces + np.repeat(noise, 1)[None, :, None] * rng.normal(size=traces.shape)
    return StepTable(
        machine=machine,
        step_start=start,
        step_end=start + dur,
        channels=CHANNELS,
        units=UNITS,
        summaries=summaries,
        traces=traces,
        trace_offsets=offsets,
        trace_rate_hz=100.0,
    )


def synth_signatures(sizes=(2e-4, 6e-4, 1.5e-3)) -> SignatureSet:
    """Noise-free feature changes of each location at ``sizes`` [kg/s]."""
    zero = np.zeros(1)
    base_means, base_dur = _means({}, zero)

    def features(means, dur):
        summaries = np.stack([means, means, means], axis=3)
        per = np.transpose(summaries, (0, 2, 3, 1)).reshape(1, -1)
        return np.concatenate([dur, per], axis=1)[0]

    base = features(base_means, base_dur)
    deltas = np.array(
        [[features(*_means({loc: s}, zero)) - base for s in sizes] for loc in LOCATIONS]
    )
    table = synth_table(1, with_traces=False)
    return SignatureSet(
        LOCATIONS,
        np.tile(np.asarray(sizes), (len(LOCATIONS), 1)),
        deltas,
        table.feature_names(),
        np.full(len(LOCATIONS), 6.0e5),
    )


def synth_description() -> dict:
    """A valid machine description (TOML mapping) named like the synthetic machine."""

    def actuator(ident: str) -> dict:
        return {
            "id": ident,
            "kind": "linear",
            "bore_mm": 20.0,
            "rod_mm": 8.0,
            "stroke_mm": 50.0,
            "moving_mass_kg": 0.3,
            "static_friction_n": 10.0,
            "coulomb_friction_n": 8.0,
            "viscous_friction_n_s_m": 20.0,
            "dead_volume_a_cm3": 1.0,
            "dead_volume_b_cm3": 1.0,
            "tube_length_m": 1.0,
            "tube_inner_diameter_mm": 4.0,
            "valve": {"kind": "5/2-bistable", "cv": 0.2},
        }

    return {
        "machine": {"name": "synth"},
        "supply": {
            "house_psig": 95.0,
            "regulator_set_psig": 72.0,
            "regulator_cv": 0.9,
            "reservoir_volume_l": 2.0,
            "line_cv": 0.3,
            "manifold_volume_l": 0.05,
        },
        "actuator": [actuator("X"), actuator("Y")],
        "sensor": [
            {"channel": "P_In", "kind": "pressure", "location": "supply", "range": [0, 10]},
            {"channel": "Q_In", "kind": "flow", "location": "supply", "range": [0, 200]},
            {"channel": "P_X_A", "kind": "pressure", "location": "X_A", "range": [0, 10]},
            {"channel": "Q_X_A", "kind": "flow", "location": "X_A", "range": [0, 200]},
        ],
        "step": [
            {"do": [{"set": "U_X_A", "until": "S_X_B"}]},
            {"do": [{"set": "U_X_B", "until": "S_X_A"}]},
            {"do": [{"set": "U_Y_A", "until": "S_Y_B"}]},
            {"do": [{"set": "U_Y_B", "until": "S_Y_A"}]},
        ],
    }
