"""Builders shared by the recording tests: a small rig-like recording and bit comparison."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np

from pneufdd.recording import Channel, Recording

ANALOG_CODES = (
    "P_In",
    "Q_In",
    "P_DNC_A",
    "P_DNC_B",
    "Q_DNC_A",
    "Q_DNC_B",
    "X_DNC",
    "P_HMPL_A",
    "P_HMPL_B",
    "P_DRQD_A",
    "P_DRQD_B",
)
ACTUATORS = ("DNC", "HMPL_H", "HMPL_V", "HMPL_VS", "DRQD", "SLT", "HGD1", "HGD2", "DSL", "ADVU")


def rig_recording(seconds: float = 2.0, seed: int = 0) -> Recording:
    """11 float32 analog channels at 1 kHz and 40 digital channels at 100 Hz (sec. 3.2.4)."""
    rng = np.random.default_rng(seed)
    n_analog = round(seconds * 1000.0)
    n_digital = round(seconds * 100.0)
    channels = []
    for code in ANALOG_CODES:
        unit = {"P": "Pa", "Q": "kg/s", "X": "m"}[code[0]]
        scale = {"P": 6.0e5, "Q": 1.0e-3, "X": 0.1}[code[0]]
        values = (scale * (1.0 + 0.01 * rng.standard_normal(n_analog))).astype(np.float32)
        values[rng.integers(0, n_analog, 3)] = np.nan  # dropped samples
        channels.append(Channel(code, values, 1000.0, unit))
    for act in ACTUATORS:
        for prefix in ("U", "S"):
            for side in ("A", "B"):
                values = (rng.random(n_digital) < 0.3).astype(np.uint8)
                channels.append(Channel(f"{prefix}_{act}_{side}", values, 100.0, "1", "digital"))
    return Recording(
        channels,
        start_time=datetime(2011, 6, 14, 9, 30, 12, 345678, tzinfo=UTC),
        metadata={"machine": "festo-dsd", "scenario": "leak DNC_A 10 turns", "seed": seed},
    )


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """True when the arrays have one dtype and identical bytes (NaN payloads, -0.0)."""
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def identical(a: Recording, b: Recording) -> bool:
    """Exact equality including the bits of every value, tzinfo and channel order."""
    return (
        a.equals(b)
        and a.channels == b.channels
        and a.start_time.utcoffset() == b.start_time.utcoffset()
        and a.start_time.isoformat() == b.start_time.isoformat()
        and a.metadata == b.metadata
        and all(
            same_bits(a.info(n).values, b.info(n).values)
            and a.info(n).kind == b.info(n).kind
            and a.info(n).rate_hz == b.info(n).rate_hz
            and a.info(n).t0 == b.info(n).t0
            for n in a.channels
        )
    )
