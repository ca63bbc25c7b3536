"""Motion characteristics of a stroke (section 3.3) and their detection.

With an LVDT (``X_<ACT>``), times come from the zero-phase filtered displacement
(section 3.2.4) at the analog rate:

* motion start (start of sustained travel): the start-up of the acceleration that
  section 3.3 judges by eye, found by fitting "at rest at ``c`` until t0, then ``c +
  a (t - t0)^2 + b (t - t0)^3``" to the raw displacement over the first 25 % of the
  travel (least squares, t0 on the sample grid); a speed threshold (the last sample
  before the peak below ``start_fraction`` = 5 % of the peak speed) is the fallback
  and an upper bound;
* arrival: coarse, the first sample after the peak within ``end_tolerance`` (0.5 %)
  of the stroke from the final position, plus the time the remaining distance takes
  at the speed there (at most 5 samples); refined by a hinge fit "constant speed,
  then at rest at the end stop" to the raw displacement around it;
* t_p = start - valve firing, t_s = arrival - start, t_o = t_p + t_s (section 3.3);
* balancing velocity: median speed over 50-90 % of the travel (the uniform
  latter half of a meter-out stroke, before cushioning);
* balancing pressure: chamber pressures at the motion start, where the
  acceleration starts up from zero.

Without an LVDT the proximity switches give the times (100 Hz, +-10 ms): start =
the home-side switch releasing, arrival = the far switch closing; a reed switch
releases a few mm into the travel, so t_p is then an upper bound.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pneufdd.features.context import CycleView, MeasuredStroke
from pneufdd.features.registry import Unavailable, register
from pneufdd.signals.segmentation import RecordedStep

__all__ = ["MOTIONS", "detect_stroke", "exhaust_line", "supply_line"]

MOTIONS = ("extend", "retract")
# The arrival fit uses the raw LVDT over this time before the coarse arrival (and at
# most the last 20 % of the travel): short enough that a cushioned stroke's speed is
# nearly constant in it [s].
ARRIVAL_WINDOW_S = 0.03


def supply_line(motion: str) -> str:
    """Side that is pressurised in ``motion``: A (blind side) to extend, B to retract."""
    return "A" if motion == "extend" else "B"


def exhaust_line(motion: str) -> str:
    """Side that exhausts in ``motion``."""
    return "B" if motion == "extend" else "A"


def detect_stroke(
    view: CycleView, actuator: str, motion: str, step: RecordedStep
) -> MeasuredStroke:
    """Find motion start and arrival of one stroke (LVDT if present, else switches)."""
    stroke = MeasuredStroke(step=step, t_valve=step.start_s)
    kin = view.data.kinematics(actuator)
    opts = view.options
    if kin is not None:
        _, fs, c0 = view.data.analog(f"X_{actuator}")
        i0 = max(int(np.ceil((step.start_s - c0) * fs - 1e-9)), 0)
        i1 = min(int(np.ceil((step.end_s - c0) * fs - 1e-9)), kin.position.size)
        x = kin.position[i0:i1]
        v = kin.velocity[i0:i1]
        if x.size < 10 or np.isfinite(x).mean() < opts.min_valid:
            stroke.reason = f"X_{actuator}: too few valid samples in step {step.index}"
            return stroke
        finite = x[np.isfinite(x)]
        x_start = float(np.median(finite[:5]))
        x_end = float(np.median(finite[-5:]))
        travel = x_end - x_start
        if not np.isfinite(travel) or abs(travel) < 1e-3:
            stroke.reason = f"X_{actuator}: no travel in step {step.index}"
            return stroke
        sign = np.sign(travel)
        speed = np.where(np.isfinite(v), sign * v, -np.inf)
        peak = int(np.argmax(speed))
        v_max = float(speed[peak])
        slow = np.flatnonzero(speed[:peak] < opts.start_fraction * v_max)
        i_start = int(slow[-1]) + 1 if slow.size else 0
        raw, _, _ = view.data.analog(f"X_{actuator}")
        t_fit = _breakaway((raw[i0 : i0 + peak + 1] - x_start) / travel, fs, i_start)
        if t_fit is not None:
            i_start = min(max(round(t_fit * fs), 0), i_start)
        reached = np.flatnonzero(sign * (x[peak:] - x_end) >= -opts.end_tolerance * abs(travel))
        if reached.size == 0:
            stroke.reason = f"X_{actuator}: the stroke does not reach its end in step {step.index}"
            return stroke
        i_end = peak + int(reached[0])
        progress = (x[i_start : i_end + 1] - x_start) / travel
        middle = speed[i_start : i_end + 1][(progress >= 0.5) & (progress <= 0.9)]
        stroke.t_start = c0 + (i0 + i_start) / fs
        # Coarse arrival: the last `end_tolerance` of the travel at the arrival speed.
        left = abs(x_end - x[i_end]) / max(float(speed[i_end]), 0.05 * v_max)
        t_end = (i0 + i_end) / fs + min(left, 5.0 / fs)
        late = np.flatnonzero(sign * (x[: i_end + 1] - x_start) < 0.8 * abs(travel))
        begin = int(late[-1]) + 1 if late.size else 0
        begin = max(begin, i_end - round(ARRIVAL_WINDOW_S * fs))
        t_hinge = _arrival(raw[i0 : i0 + x.size], fs, i_end, begin)
        if t_hinge is not None and abs(t_hinge - (t_end - i0 / fs)) <= 10.0 / fs:
            t_end = i0 / fs + t_hinge
        stroke.t_end = c0 + t_end
        stroke.source = "lvdt"
        stroke.v_max = v_max
        stroke.v_balance = float(np.median(middle)) if middle.size else float("nan")
        return stroke
    leave = f"S_{actuator}_{'A' if motion == 'extend' else 'B'}"
    reach = f"S_{actuator}_{'B' if motion == 'extend' else 'A'}"
    e_leave, e_reach = view.data.switch_edges(leave), view.data.switch_edges(reach)
    if e_leave is None or e_reach is None:
        stroke.reason = f"{actuator} has neither an LVDT X_{actuator} nor switches {leave}, {reach}"
        return stroke
    lo, hi = step.start_s - 1e-9, step.end_s + 1e-9
    falls = e_leave[1][(e_leave[1] >= lo) & (e_leave[1] <= hi)]
    rises = e_reach[0][(e_reach[0] >= lo) & (e_reach[0] <= hi)]
    if falls.size:
        stroke.t_start = float(falls[0])
    if rises.size:
        stroke.t_end = float(rises[0])
    if not (falls.size and rises.size):
        stroke.reason = f"{leave} or {reach} did not switch in step {step.index}"
    return stroke


def _least_squares(
    bases: list[npt.NDArray[np.float64]], y: npt.NDArray[np.float64], w: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Residual sum of squares of the weighted fit of ``y`` on each candidate's bases.

    ``bases[k]`` has shape (candidates, samples); one linear least-squares problem per
    candidate row, solved through its normal equations (all rows at once). Rows
    whose normal matrix is singular get ``inf``.
    """
    k = len(bases)
    gram = np.empty((bases[0].shape[0], k, k))
    rhs = np.empty((bases[0].shape[0], k))
    wy = w * y
    for a in range(k):
        rhs[:, a] = bases[a] @ wy
        for b in range(a, k):
            gram[:, a, b] = gram[:, b, a] = (bases[a] * bases[b]) @ w
    scale = np.prod(np.diagonal(gram, axis1=1, axis2=2), axis=1)
    ok = np.abs(np.linalg.det(gram)) > 1e-12 * np.maximum(scale, 1e-300)
    coef = np.zeros_like(rhs)
    if ok.any():
        coef[ok] = np.linalg.solve(gram[ok], rhs[ok][..., None])[..., 0]
    return np.where(ok, float(wy @ y) - np.einsum("ij,ij->i", coef, rhs), np.inf)


def _breakaway(
    progress: npt.NDArray[np.float64],
    fs: float,
    latest: int,
    span_s: float = 0.1,
    upto: float = 0.25,
) -> float | None:
    """Start of sustained travel [s from the window start] from the first 25 % of travel.

    A piston that starts to travel is at rest at ``c`` before ``t0`` and then moves
    ``c + a (t - t0)^2 + b (t - t0)^3``: the acceleration builds up from (nearly)
    zero as the driving chamber fills, the "start-up of the acceleration curve" of
    section 3.3. For every candidate ``t0`` on the sample grid within ``span_s``
    before ``latest`` (the speed-threshold start, an upper bound) the linear
    least-squares fit of ``(c, a, b)`` to the raw progress is computed; the ``t0``
    of the smallest residual is the start. Every sample up to ``upto`` of the travel
    is used, not a threshold, which averages the LVDT noise out; the rest level
    ``c`` is fitted rather than taken from a few samples (its error would shift
    ``t0``); ``upto`` = 25 % ends the window while the acceleration is still
    building up, before the meter-out flow limits the speed (a longer window makes
    the cubic bend early and dates the start early). None when fewer than 8
    samples are available.
    """
    finite = np.isfinite(progress)
    above = np.flatnonzero(finite & (progress >= upto))
    if above.size == 0 or above[0] < 8:
        return None
    first = max(min(latest, int(above[0]) - 1) - round(span_s * fs), 0)
    stop = int(above[0])
    y = np.where(finite[first:stop], progress[first:stop], 0.0)
    w = finite[first:stop].astype(np.float64)
    t = np.arange(y.size) / fs
    cand = t[: max(min(latest, stop - 1) - first, 0) + 1]
    u2 = np.clip(t[None, :] - cand[:, None], 0.0, None) ** 2
    u3 = u2 * np.sqrt(u2)
    misfit = _least_squares([np.ones_like(u2), u2, u3], y, w)
    return float((first + int(np.argmin(misfit))) / fs)


def _arrival(
    x: npt.NDArray[np.float64], fs: float, coarse: int, begin: int, after_s: float = 0.05
) -> float | None:
    """Arrival at the end stop [s from the window start], by a hinge fit to the raw LVDT.

    Near the end of a stroke the piston travels at a nearly constant (balancing)
    speed and stops at the end stop: ``x = x_end - v max(t1 - t, 0)``. For every
    candidate ``t1`` on the sample grid within 10 samples of ``coarse`` the linear
    fit of ``(x_end, v)`` to the raw samples from ``begin`` (the later of 80 % of
    the travel and ``ARRIVAL_WINDOW_S`` before ``coarse``) to ``after_s`` past
    ``coarse`` is computed; the best ``t1`` is refined between
    samples by a parabola through the residuals of its neighbours. None when the
    window is too short.
    """
    stop = min(coarse + round(after_s * fs), x.size)
    if coarse - begin < 5 or stop - coarse < 5:
        return None
    y = x[begin:stop]
    finite = np.isfinite(y)
    w = finite.astype(np.float64)
    y = np.where(finite, y, 0.0)
    t = np.arange(begin, stop) / fs
    lo, hi = max(coarse - 10, begin + 3), min(coarse + 10, stop - 3)
    cand = np.arange(lo, hi + 1) / fs
    ramp = np.clip(cand[:, None] - t[None, :], 0.0, None)
    misfit = _least_squares([np.ones_like(ramp), ramp], y, w)
    k = int(np.argmin(misfit))
    if not np.isfinite(misfit[k]):
        return None
    shift = 0.0
    if 0 < k < misfit.size - 1 and np.all(np.isfinite(misfit[k - 1 : k + 2])):
        curv = misfit[k - 1] - 2.0 * misfit[k] + misfit[k + 1]
        if curv > 0.0:
            shift = 0.5 * (misfit[k - 1] - misfit[k + 1]) / curv
    return float(cand[k] + shift / fs)


def _times(view: CycleView, actuator: str, motion: str) -> MeasuredStroke:
    s = view.stroke(actuator, motion)
    if not np.isfinite(s.t_start) or not np.isfinite(s.t_end):
        raise Unavailable(s.reason or f"{actuator} {motion}: motion not detected")
    return s


def _lvdt(view: CycleView, actuator: str, motion: str) -> MeasuredStroke:
    s = _times(view, actuator, motion)
    if s.source != "lvdt":
        raise Unavailable(f"velocity of {actuator} needs an LVDT channel X_{actuator}")
    return s


def _register_motion(motion: str) -> None:
    m = motion

    @register(
        f"t_p_{m}_s",
        "actuator",
        "s",
        "motion",
        description=f"Positioning time t_p of the {m} stroke, valve to motion start [s] (3.3).",
    )
    def positioning_time(view: CycleView, act: str) -> float:
        s = _times(view, act, m)
        return s.t_start - s.t_valve

    @register(
        f"t_s_{m}_s",
        "actuator",
        "s",
        "motion",
        description=f"Stroke time t_s of the {m} stroke, motion start to arrival [s] (3.3).",
    )
    def stroke_time(view: CycleView, act: str) -> float:
        s = _times(view, act, m)
        return s.t_end - s.t_start

    @register(
        f"t_o_{m}_s",
        "actuator",
        "s",
        "motion",
        description=f"Operating time t_o = t_p + t_s of the {m} stroke [s] (3.3).",
    )
    def operating_time(view: CycleView, act: str) -> float:
        s = _times(view, act, m)
        return s.t_end - s.t_valve

    @register(
        f"v_max_{m}_m_s",
        "actuator",
        "m/s",
        "motion",
        ("X_{act}",),
        description=f"Maximum piston speed in the {m} stroke [m/s] (3.3, LVDT).",
    )
    def max_velocity(view: CycleView, act: str) -> float:
        return _lvdt(view, act, m).v_max

    @register(
        f"v_balance_{m}_m_s",
        "actuator",
        "m/s",
        "motion",
        ("X_{act}",),
        description=f"Balancing speed of the {m} stroke: median over 50-90 % travel [m/s] (3.3).",
    )
    def balancing_velocity(view: CycleView, act: str) -> float:
        v = _lvdt(view, act, m).v_balance
        if not np.isfinite(v):
            raise Unavailable(f"{act} {m}: too few samples in 50-90 % of the travel")
        return v

    ex = exhaust_line(m)

    @register(
        f"exhaust_flow_max_{m}_kg_s",
        "actuator",
        "kg/s",
        "motion",
        (f"Q_{{act}}_{ex}",),
        description=f"Maximum exhaust flow from chamber {ex} in the {m} step [kg/s] (3.3).",
    )
    def max_exhaust_flow(view: CycleView, act: str) -> float:
        return max_exhaust(view, act, m)

    for side in "AB":
        _register_balance(m, side)


def max_exhaust(view: CycleView, act: str, motion: str) -> float:
    """Peak flow out of the exhausting chamber during the ``motion`` step [kg/s]."""
    name = f"Q_{act}_{exhaust_line(motion)}"
    if view.data.flow_direction(name) == "forward":
        raise Unavailable(f"{name} measures forward flow only: the exhaust flow is not measured")
    step = view.stroke(act, motion).step
    q = view.window(name, step.start_s, step.end_s)
    return float(np.nanmax(-q))


def _register_balance(motion: str, side: str) -> None:
    @register(
        f"p_balance_{side}_{motion}_Pa",
        "actuator",
        "Pa",
        "motion",
        (f"P_{{act}}_{side}",),
        description=f"Balancing pressure in chamber {side} at the {motion} start [Pa] (3.3).",
    )
    def balancing_pressure(view: CycleView, act: str) -> float:
        s = _times(view, act, motion)
        seg = view.window(f"P_{act}_{side}", s.t_start - 0.0025, s.t_start + 0.0025)
        return float(np.nanmean(seg))


for _m in MOTIONS:
    _register_motion(_m)
