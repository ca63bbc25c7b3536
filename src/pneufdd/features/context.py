"""Per-recording caches and the per-cycle view feature functions read from.

:class:`RecordingData` checks units once, filters each LVDT once for the whole
recording (:func:`pneufdd.signals.filtering.kinematics`) and debounces the switches;
:class:`CycleView` cuts one complete cycle's strokes and steps out of it.

Conventions (see ``docs/signals.md``):

* flow sign: positive towards the actuator (supply into a chamber), negative out
  of it (exhaust). What a meter can measure (section 3.4.1: one direction only) is
  taken from ``metadata["flow_meter_direction"]`` (``"forward"``, ``"reverse"`` or
  ``"both"``, for all meters or as ``{channel: direction}``), else from the sensor's
  ``direction`` in a machine description stored in the metadata
  (``metadata["machine"]["description"]["sensor"]``, ``"bidirectional"`` = both),
  else it is inferred: a channel that never shows flow of one sign cannot measure it.
* a signal window with less than ``min_valid`` finite samples gives NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, UnitError, describe
from pneufdd.features.registry import Unavailable
from pneufdd.recording.model import Recording
from pneufdd.signals.digital import debounced_edges
from pneufdd.signals.filtering import DEFAULT_CUTOFF_HZ, Kinematics, kinematics
from pneufdd.signals.segmentation import DEFAULT_SWITCH_DWELL_S, Cycle, RecordedStep

__all__ = ["CycleView", "MeasuredStroke", "Options", "RecordingData"]


EXPECTED_UNIT = {"P": "Pa", "Q": "kg/s", "X": "m"}
DIRECTIONS = ("both", "forward", "reverse")


@dataclass(frozen=True)
class Options:
    """Settings shared by all feature functions.

    Attributes
    ----------
    cutoff_hz : float
        LVDT low-pass cut-off [Hz].
    wavelet : str
        PyWavelets mother wavelet for the DWT features (section 5.3.3).
    min_valid : float
        Least fraction of finite samples a window needs [-].
    start_fraction : float
        Motion starts when the velocity first exceeds this fraction of its peak [-].
    end_tolerance : float
        Arrival: position within this fraction of the stroke of its end value [-].
    switch_min_dwell_s : float
        Debounce dwell of the proximity switches [s].
    """

    cutoff_hz: float = DEFAULT_CUTOFF_HZ
    wavelet: str = "db4"
    min_valid: float = 0.9
    start_fraction: float = 0.05
    end_tolerance: float = 0.005
    switch_min_dwell_s: float = DEFAULT_SWITCH_DWELL_S


class RecordingData:
    """Unit-checked arrays and cached derived signals of one recording."""

    def __init__(self, recording: Recording, options: Options | None = None) -> None:
        self.recording = recording
        self.options = options or Options()
        self._arrays: dict[str, tuple[FloatArray, float, float]] = {}
        self._kin: dict[str, Kinematics] = {}
        self._switch: dict[str, tuple[FloatArray, FloatArray]] = {}
        self._direction: dict[str, str] = {}
        self._cumulative: dict[tuple[str, float], tuple[FloatArray, npt.NDArray[np.int64]]] = {}

    def has(self, name: str) -> bool:
        """Whether the recording has channel ``name``."""
        return name in self.recording.channels

    def analog(self, name: str) -> tuple[FloatArray, float, float]:
        """``(values, fs [Hz], t0 [s])`` of an analog channel, its unit checked."""
        cached = self._arrays.get(name)
        if cached is not None:
            return cached
        self.recording.require([name], "feature extraction")
        ch = self.recording.info(name)
        expected = EXPECTED_UNIT.get(name.split("_", 1)[0])
        if expected is not None and ch.unit != expected:
            raise UnitError(describe(f"unit of channel {name!r}", ch.unit, [expected]))
        out = (np.asarray(ch.values, dtype=np.float64), ch.rate_hz, ch.t0)
        self._arrays[name] = out
        return out

    def cumulative(self, name: str, sign: float) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        """Running trapezoid integral of ``max(sign * x, 0)`` and running count of valid samples.

        NaN gaps are bridged linearly for the integral; ``integral[i]`` is the
        integral from sample 0 to sample i [unit s], ``valid[i]`` the number of finite
        samples before sample i.
        """
        key = (name, sign)
        if key not in self._cumulative:
            from pneufdd.signals.filtering import fill_gaps

            x, fs, _ = self.analog(name)
            filled, gaps = fill_gaps(x)
            part = np.maximum(sign * filled, 0.0)
            integral = np.r_[0.0, np.cumsum((part[1:] + part[:-1]) * (0.5 / fs))]
            valid = np.r_[0, np.cumsum(~gaps)].astype(np.int64)
            self._cumulative[key] = (integral, valid)
        return self._cumulative[key]

    def kinematics(self, actuator: str) -> Kinematics | None:
        """Filtered LVDT ``X_<ACT>`` of the whole recording, or None without one."""
        name = f"X_{actuator}"
        if not self.has(name):
            return None
        if name not in self._kin:
            x, fs, _ = self.analog(name)
            self._kin[name] = kinematics(x, fs, self.options.cutoff_hz)
        return self._kin[name]

    def switch_edges(self, name: str) -> tuple[FloatArray, FloatArray] | None:
        """Debounced ``(rising, falling)`` edge times of a switch [s], or None."""
        if not self.has(name):
            return None
        if name not in self._switch:
            ch = self.recording.info(name)
            _, e = debounced_edges(ch.values, ch.rate_hz, self.options.switch_min_dwell_s)
            self._switch[name] = (ch.t0 + e.rising / ch.rate_hz, ch.t0 + e.falling / ch.rate_hz)
        return self._switch[name]

    def flow_direction(self, name: str) -> str:
        """``"both"``, ``"forward"`` or ``"reverse"``: what the flow meter can measure."""
        if name in self._direction:
            return self._direction[name]
        metadata = self.recording.metadata
        meta: Any = metadata.get("flow_meter_direction")
        declared = meta.get(name) if isinstance(meta, dict) else meta
        if declared is None:
            declared = _described_direction(metadata, name)
        if declared == "bidirectional":
            declared = "both"
        if declared is not None:
            if declared not in DIRECTIONS:
                raise InputError(
                    describe(f"metadata flow_meter_direction of {name!r}", declared, DIRECTIONS)
                )
            direction = str(declared)
        else:
            q, _, _ = self.analog(name)
            finite = q[np.isfinite(q)]
            scale = float(np.max(np.abs(finite))) if finite.size else 0.0
            threshold = 0.02 * scale
            pos = bool(finite.size and finite.max() > threshold)
            neg = bool(finite.size and finite.min() < -threshold)
            direction = "both" if pos == neg else ("forward" if pos else "reverse")
        self._direction[name] = direction
        return direction


def _described_direction(metadata: dict[str, Any], name: str) -> str | None:
    """Direction of meter ``name`` in a machine description stored in the metadata."""
    machine = metadata.get("machine")
    raw = machine.get("description") if isinstance(machine, dict) else None
    sensors = raw.get("sensor") if isinstance(raw, dict) else None
    for sensor in sensors if isinstance(sensors, list) else []:
        if isinstance(sensor, dict) and sensor.get("channel") == name:
            direction = sensor.get("direction")
            return str(direction) if direction is not None else "forward"
    return None


@dataclass
class MeasuredStroke:
    """One actuator motion inside a cycle.

    Attributes
    ----------
    step : RecordedStep
        The step in which the solenoid fired.
    t_valve : float
        Valve firing [s].
    t_start : float
        Piston starts travelling [s] (NaN if unknown).
    t_end : float
        Piston reaches the stroke end [s] (NaN if unknown).
    source : str
        ``"lvdt"`` or ``"switches"``.
    v_max : float
        Peak speed [m/s] (NaN without LVDT).
    v_balance : float
        Median speed over 50-90 % of the travel [m/s] (NaN without LVDT).
    reason : str
        Why times are NaN, if they are.
    """

    step: RecordedStep
    t_valve: float
    t_start: float = float("nan")
    t_end: float = float("nan")
    source: str = "switches"
    v_max: float = float("nan")
    v_balance: float = float("nan")
    reason: str = ""


@dataclass
class CycleView:
    """One complete cycle of a recording, as the feature functions see it."""

    data: RecordingData
    cycle: Cycle
    _strokes: dict[tuple[str, str], MeasuredStroke] = field(default_factory=dict)
    _cache: dict[Any, Any] = field(default_factory=dict)

    @cached_property
    def options(self) -> Options:
        """The extraction options."""
        return self.data.options

    def step(self, number: int) -> RecordedStep:
        """Step ``number`` (1-based)."""
        return self.cycle.steps[number - 1]

    def window(self, name: str, t0: float, t1: float) -> FloatArray:
        """Samples of analog ``name`` with times in ``[t0, t1)``; raises Unavailable if gappy."""
        x, fs, c0 = self.data.analog(name)
        i0 = max(int(np.ceil((t0 - c0) * fs - 1e-9)), 0)
        i1 = min(int(np.ceil((t1 - c0) * fs - 1e-9)), x.size)
        seg = x[i0:i1]
        if seg.size == 0:
            raise Unavailable(f"{name}: no samples between {t0:.3f} s and {t1:.3f} s")
        valid = np.isfinite(seg).mean()
        if valid < self.options.min_valid:
            raise Unavailable(
                f"{name}: only {valid:.0%} valid samples between {t0:.3f} s and {t1:.3f} s "
                f"(needs {self.options.min_valid:.0%})"
            )
        return seg

    def integral(self, name: str, t0: float, t1: float, sign: float = 1.0) -> float:
        """Trapezoid integral of ``max(sign * x, 0)`` over ``[t0, t1)`` [unit s].

        Raises Unavailable when fewer than ``min_valid`` of the samples are finite.
        """
        x, fs, c0 = self.data.analog(name)
        i0 = max(int(np.ceil((t0 - c0) * fs - 1e-9)), 0)
        i1 = min(int(np.ceil((t1 - c0) * fs - 1e-9)), x.size)
        if i1 - i0 < 2:
            raise Unavailable(f"{name}: fewer than 2 samples between {t0:.3f} s and {t1:.3f} s")
        integral, valid = self.data.cumulative(name, sign)
        fraction = (valid[i1] - valid[i0]) / (i1 - i0)
        if fraction < self.options.min_valid:
            raise Unavailable(
                f"{name}: only {fraction:.0%} valid samples between {t0:.3f} s and {t1:.3f} s "
                f"(needs {self.options.min_valid:.0%})"
            )
        return float(integral[i1 - 1] - integral[i0])

    def stroke(self, actuator: str, motion: str) -> MeasuredStroke:
        """The ``motion`` (``"extend"``/``"retract"``) of ``actuator`` in this cycle."""
        key = (actuator, motion)
        if key not in self._strokes:
            from pneufdd.features.motion import detect_stroke

            step = self.cycle.find(actuator, motion)
            if step is None:
                raise Unavailable(f"{actuator} does not {motion} in this cycle")
            self._strokes[key] = detect_stroke(self, actuator, motion, step)
        return self._strokes[key]
