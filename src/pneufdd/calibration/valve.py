"""An actuator's supply path (valve and tube) identified from its line flow, before the fit.

Where a plant measures a line's flow and pressure (``Q_<ID>_A`` and ``P_<ID>_A``,
or the B line's) besides the supply pressure ``P_In``, the flow capacity from the
valve manifold to the cylinder is identified from the samples, as section 4.2.1
does for the CPE14 valve (:func:`pneufdd.identification.fit_valve`, eq. 4.6 with the
zero-flow correction of Figs. 4.7-4.8): upstream ``P_In``, downstream the line
pressure, flow the line's. What is identified is the valve and the tube in series
(the twin's fill path, ``series_cv(valve, tube)``); the calibration then keeps the
twin's valve Cv such that the series with its (assumed or fitted) tube gives the
identified path (:func:`valve_cv_for_path`), whatever the fitted size does to the
tube.

Why: the step durations and the supply air per step cannot tell a large valve from
a small one when throttles set the speed, and a drafted actuator's valve is sized
with its cylinder. On a varied press-fit-cell plant that gave the ram a
path Cv of 0.99 where the plant's is 0.60: the twin's fill peak ran into the
drafted 500 SLPM flow sensor's range, and a leak behind the closed-centre valve
was sized 32 % too large.

Samples used: the line is connected to the manifold (from the solenoids and the
valve kind), its flow is at least :data:`MIN_FLOW_FRACTION` of the line's peak,
and the flow changes slowly against the flow sensor's lag (:data:`MAX_LAG_ERROR`).
The zero-flow drop is the median ``P_In - P_line`` while the line is connected and
its flow is below :data:`ZERO_FLOW_FRACTION` of the peak (both sensors' zero errors
and the manifold's distance).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pneufdd.array_types import BoolArray, FloatArray
from pneufdd.errors import InputError
from pneufdd.identification.valve import fit_valve
from pneufdd.recording.model import Recording
from pneufdd.signals.digital import edge_times
from pneufdd.sim import MachineDescription
from pneufdd.sim.compile import tube_cv
from pneufdd.sim.description import Actuator

__all__ = ["PathIdentification", "connected_to_supply", "identify_paths", "valve_cv_for_path"]


MIN_FLOW_FRACTION = 0.2
"""Smallest flow used, as a part of the line's peak flow [-]."""

ZERO_FLOW_FRACTION = 0.02
"""Flow below which a connected line is taken as at zero flow, part of the peak [-]."""

MAX_LAG_ERROR = 0.05
"""Largest ``tau |dQ/dt| / Q`` of a sample used: the flow sensor's first-order lag
``tau`` may misstate the flow by at most this part [-]."""

MIN_POINTS = 50
"""Fewest samples for an identification [-]."""

MAX_REL_STD = 0.1
"""Largest relative standard error of an identified path Cv that is used [-]."""


@dataclass(frozen=True)
class PathIdentification:
    """One actuator's fill path identified from its line flow (section 4.2.1).

    Attributes
    ----------
    actuator : str
        Actuator id.
    path_cv, path_cv_std : float
        Flow coefficient of valve and tube in series, and its standard error
        [US gal/(min psi^0.5)] (of the samples' scatter: a lower bound).
    lines : tuple of str
        The lines whose flow was used (``"A"``, ``"B"``).
    points : int
        Samples used.
    """

    actuator: str
    path_cv: float
    path_cv_std: float
    lines: tuple[str, ...]
    points: int

    def describe(self) -> str:
        """One line: ``valve + tube Cv 0.602 +- 0.004 from line A (812 samples)``."""
        lines = " and ".join(self.lines)
        return (
            f"valve + tube Cv {self.path_cv:.3f} +- {self.path_cv_std:.3f} from line "
            f"{lines} ({self.points} samples)"
        )


def _held(rec: Recording, channel: str, time: FloatArray) -> BoolArray:
    """A digital channel's value at ``time`` (sample and hold); all False if absent."""
    if channel not in rec.channels:
        return np.zeros(time.size, dtype=bool)
    t, u = rec.channel(channel)
    idx = np.searchsorted(np.asarray(t, np.float64), time, side="right") - 1
    values = np.asarray(u) > 0.5
    out: BoolArray = np.where(idx >= 0, values[np.clip(idx, 0, None)], False)
    return out


def _last_pulse_was_a(rec: Recording, ident: str, time: FloatArray) -> BoolArray:
    """Bistable valve: whether the last solenoid switched on before ``time`` was A's."""
    on_a, on_b = edge_times(rec, f"U_{ident}_A")[0], edge_times(rec, f"U_{ident}_B")[0]
    when = np.concatenate([on_a, on_b])
    if when.size == 0:
        return np.zeros(time.size, dtype=bool)
    order = np.argsort(when, kind="stable")
    when = when[order]
    is_a = np.concatenate([np.ones(on_a.size, bool), np.zeros(on_b.size, bool)])[order]
    idx = np.searchsorted(when, time, side="right") - 1
    out: BoolArray = np.where(idx >= 0, is_a[np.clip(idx, 0, None)], False)
    return out


def connected_to_supply(
    rec: Recording, actuator: Actuator, side: str, time: FloatArray
) -> BoolArray:
    """Whether line ``side`` (``"A"`` or ``"B"``) of ``actuator`` is open to the manifold.

    From the solenoids and the valve kind: a 5/2 monostable supplies A while its
    solenoid is on and B otherwise (a 3/2 single-acting one never B); a 5/3
    closed-centre supplies the side whose solenoid alone is on; a 5/2 bistable the
    side of the last solenoid switched on (neither before the first).
    """
    ident = actuator.id
    u_a = _held(rec, f"U_{ident}_A", time)
    u_b = _held(rec, f"U_{ident}_B", time)
    kind = actuator.valve.kind
    if kind == "5/2-monostable":
        return u_a if side == "A" else ~u_a
    if kind == "3/2-monostable":  # single-acting: the spring side is vented, never supplied
        return u_a if side == "A" else np.zeros_like(u_a)
    if kind == "5/3-closed-centre":
        return u_a & ~u_b if side == "A" else u_b & ~u_a
    last_a = _last_pulse_was_a(rec, ident, time)
    started = np.cumsum(u_a | u_b) > 0  # a solenoid has been on
    return last_a if side == "A" else started & ~last_a


def _flow_time_constant(machine: MachineDescription, channel: str) -> float:
    for s in machine.sensors:
        if s.channel == channel:
            return float(s.time_constant_s)
    return 0.0  # not a sensor of the description: no lag assumed


def _line_samples(
    rec: Recording, actuator: Actuator, side: str, tau: float
) -> tuple[FloatArray, FloatArray, FloatArray, float] | None:
    """Upstream and line pressures [Pa], flow [kg/s] of the usable samples, and the
    zero-flow drop [Pa]; None without the channels or without zero-flow samples."""
    names = ("P_In", f"P_{actuator.id}_{side}", f"Q_{actuator.id}_{side}")
    if not all(n in rec.channels for n in names):
        return None
    t, p_in = rec.channel(names[0])
    tl, p_line = rec.channel(names[1])
    tq, q = rec.channel(names[2])
    if not (t.size == tl.size == tq.size):  # pragma: no cover - one analog time base
        return None
    p_in = np.asarray(p_in, np.float64)
    p_line = np.asarray(p_line, np.float64)
    q = np.asarray(q, np.float64)
    connected = connected_to_supply(rec, actuator, side, np.asarray(t, np.float64))
    if not np.any(connected):
        return None
    peak = float(np.max(q[connected]))
    if peak <= 0.0:
        return None
    zero = connected & (np.abs(q) < ZERO_FLOW_FRACTION * peak)
    if np.count_nonzero(zero) < MIN_POINTS:
        return None
    drop0 = float(np.median(p_in[zero] - p_line[zero]))
    dt = float(np.median(np.diff(t)))
    slope = np.gradient(q, dt)
    steady = tau * np.abs(slope) <= MAX_LAG_ERROR * np.maximum(q, 1e-12)
    use = connected & steady & (q >= MIN_FLOW_FRACTION * peak)
    return p_in[use], p_line[use], q[use], drop0


def identify_paths(
    machine: MachineDescription, recordings: Sequence[Recording]
) -> dict[str, PathIdentification]:
    """The fill path Cv of every actuator whose line flow and pressure are recorded.

    Parameters
    ----------
    machine : MachineDescription
        Gives the valve kinds and xT, and the flow sensors' time constants [s].
    recordings : sequence of Recording
        Leak-free recordings with ``P_In``, ``P_<ID>_<side>`` and ``Q_<ID>_<side>``.

    Returns
    -------
    dict
        Actuator id -> :class:`PathIdentification`; actuators without the channels,
        with too few samples or an uncertain fit are left out (their valve stays a
        calibrated or drafted value).
    """
    found: dict[str, PathIdentification] = {}
    for actuator in machine.actuators:
        fits = []
        for side in "AB":
            channel = f"Q_{actuator.id}_{side}"
            tau = _flow_time_constant(machine, channel)
            parts = [_line_samples(rec, actuator, side, tau) for rec in recordings]
            usable = [p for p in parts if p is not None]
            if not usable:
                continue
            p_in = np.concatenate([u[0] for u in usable])
            p_line = np.concatenate([u[1] for u in usable])
            q = np.concatenate([u[2] for u in usable])
            drop0 = float(np.median([u[3] for u in usable]))
            if q.size < MIN_POINTS:
                continue
            try:
                fit = fit_valve(
                    p_in, p_line, q, zero_drop=(drop0, 0.0), fit_xt=False, xt=actuator.valve.xt
                )
            except InputError:
                continue
            if fit.cv_std <= MAX_REL_STD * fit.cv:
                fits.append((side, fit.cv, fit.cv_std, q.size))
        if not fits:
            continue
        weights = np.array([1.0 / max(f[2], 1e-12) ** 2 for f in fits])
        values = np.array([f[1] for f in fits])
        cv = float(np.dot(weights, values) / weights.sum())
        found[actuator.id] = PathIdentification(
            actuator=actuator.id,
            path_cv=cv,
            path_cv_std=float(1.0 / math.sqrt(weights.sum())),
            lines=tuple(f[0] for f in fits),
            points=int(sum(f[3] for f in fits)),
        )
    return found


def valve_cv_for_path(path_cv: float, tube_length_m: float, tube_inner_diameter_mm: float) -> float:
    """The valve Cv that, in series with the tube, gives ``path_cv`` (capped at 50).

    ``1/Cv_path^2 = 1/Cv_valve^2 + 1/Cv_tube^2`` (:func:`pneufdd.sim.compile.series_cv`).

    Examples
    --------
    >>> from pneufdd.sim.compile import series_cv, tube_cv
    >>> path = series_cv(0.74, tube_cv(0.83, 7.0))
    >>> round(valve_cv_for_path(path, 0.83, 7.0), 3)
    0.74
    """
    tube = tube_cv(tube_length_m, tube_inner_diameter_mm)
    rest = 1.0 / path_cv**2 - 1.0 / tube**2
    return 50.0 if rest <= 1.0 / 50.0**2 else min(1.0 / math.sqrt(rest), 50.0)
