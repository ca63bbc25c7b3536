"""Cylinder friction from measured line pressures and a position (section 4.2.3).

Eq. 4.15: the stick-slip (breakaway) force ``Fsf`` is the net pneumatic force at the
instant ``t2`` the piston starts to move after the valve command. Eq. 4.16: over the
constant-velocity part of a stroke the force balance gives the Coulomb force ``Fcf``
and viscous coefficient ``Cvf``; strokes at different speeds (extend and retract,
several supply pressures) separate the two. Pressures are absolute, so the
atmosphere's push on the rod is in the balance
(:func:`pneufdd.physics.friction.piston_force`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.physics.friction import piston_force

__all__ = [
    "BreakawayFit",
    "SlidingFrictionFit",
    "StrokeSamples",
    "fit_breakaway_friction",
    "fit_sliding_friction",
]


@dataclass(frozen=True)
class StrokeSamples:
    """One measured stroke: time [s], absolute line pressures [Pa], position [m]."""

    time: FloatArray
    pressure_a: FloatArray
    pressure_b: FloatArray
    position: FloatArray

    def __post_init__(self) -> None:
        sizes = {np.asarray(a).size for a in (self.time, self.pressure_a, self.pressure_b)}
        sizes.add(np.asarray(self.position).size)
        if len(sizes) != 1 or min(sizes) < 20:
            raise InputError(
                describe(
                    "stroke arrays (time, pressures, position)", sorted(sizes), "one length >= 20"
                )
            )


@dataclass(frozen=True)
class BreakawayFit:
    """Result of :func:`fit_breakaway_friction`: Fsf [N], its spread [N], onsets [s]."""

    static_friction_n: float
    static_friction_std_n: float
    onsets_s: tuple[float, ...]


@dataclass(frozen=True)
class SlidingFrictionFit:
    """Result of :func:`fit_sliding_friction`: Fcf [N], Cvf [N s/m], standard errors,
    and the constant force F0 [N] when fitted (else 0)."""

    coulomb_friction_n: float
    coulomb_friction_std_n: float
    viscous_friction_n_s_m: float
    viscous_friction_std_n_s_m: float
    samples: int
    offset_force_n: float = 0.0


def _window(rate: float, seconds: float) -> int:
    return max(round(seconds * rate) | 1, 5)


def _derivatives(
    stroke: StrokeSamples, smooth_s: float
) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    t = np.asarray(stroke.time, dtype=np.float64)
    dt = float(np.median(np.diff(t)))
    n = min(_window(1.0 / dt, smooth_s), (t.size - 1) | 1 if t.size % 2 == 0 else t.size)
    n = n if n % 2 == 1 else n - 1
    x = np.asarray(stroke.position, dtype=np.float64)
    xs = savgol_filter(x, n, 2)
    v = savgol_filter(x, n, 2, deriv=1, delta=dt)
    a = savgol_filter(x, n, 2, deriv=2, delta=dt)
    return xs, v, a, dt


def fit_breakaway_friction(
    strokes: Sequence[StrokeSamples],
    area_a: float,
    area_b: float,
    noise_m: float = 0.0,
    travel_m: float = 2e-3,
) -> BreakawayFit:
    """Stick-slip friction Fsf at motion onset, eq. 4.15.

    .. math:: F_{sf} = (P_a A_a - P_b A_b - P_{atm} A_{rod})\\big|_{t = t_2}

    Each stroke starts at rest at an end stop (from the valve command ``t1``). The
    onset ``t2`` is found from the first ``travel_m`` of travel: from rest under a
    near-constant net force the displacement grows as ``(t - t2)^2``, so
    ``sqrt(|x - x0|)`` is a straight line in time whose root is ``t2`` (robust to
    position noise that hides the first micrometres). Fsf is the mean over strokes
    of the net force at ``t2`` (the dissertation assumes one value for both
    directions); with strokes both ways each direction weighs half, so a constant
    force (a vertical load's weight, a pressure sensor's zero error) cancels.

    Parameters
    ----------
    strokes : sequence of StrokeSamples
        Windows from the valve command to past the start of motion.
    area_a, area_b : float
        Piston area of the blind side and annular area of the rod side [m^2].
    noise_m : float
        Standard deviation of the position noise [m] (sets the detection threshold).
    travel_m : float
        Travel used to locate the onset [m].

    Returns
    -------
    BreakawayFit
    """
    if not strokes:
        raise InputError(describe("strokes", 0, "at least one"))
    forces, onsets, directions = [], [], []
    for k, s in enumerate(strokes):
        t = np.asarray(s.time, dtype=np.float64)
        x = np.asarray(s.position, dtype=np.float64)
        dt = float(np.median(np.diff(t)))
        rest = x[: max(int(0.01 / dt), 3)]
        x0 = float(np.median(rest))
        d = np.abs(x - x0)
        lo = max(4.0 * noise_m, 0.1 * travel_m)
        hi = max(travel_m, 3.0 * lo)
        beyond = np.flatnonzero(d > hi)
        if beyond.size == 0:
            raise InputError(describe(f"stroke {k}: travel", float(d.max()), f"> {hi} m"))
        end = int(beyond[0])
        start_candidates = np.flatnonzero(d[:end] < lo)
        begin = int(start_candidates[-1]) if start_candidates.size else 0
        sel = slice(begin, end + 1)
        if end + 1 - begin < 3:
            t2 = float(t[begin])
        else:
            slope, intercept = np.polyfit(t[sel], np.sqrt(d[sel]), 1)
            t2 = float(-intercept / slope) if slope > 0 else float(t[begin])
        t2 = min(max(t2, float(t[0])), float(t[end]))
        near = np.abs(t - t2) <= 1.5e-3
        pa = float(np.mean(np.asarray(s.pressure_a)[near]))
        pb = float(np.mean(np.asarray(s.pressure_b)[near]))
        force = float(piston_force(pa, pb, area_a, area_b))
        direction = np.sign(x[end] - x0)
        forces.append(force * direction)
        directions.append(direction)
        onsets.append(t2)
    values = np.asarray(forces)
    ways = np.asarray(directions)
    groups = [values[ways == d] for d in (1.0, -1.0) if np.any(ways == d)]
    if len(groups) == 2:  # each direction weighs half: a constant force cancels
        mean = 0.5 * float(np.mean(groups[0]) + np.mean(groups[1]))
        var = sum(float(np.var(g, ddof=1)) / g.size if g.size > 1 else np.nan for g in groups)
        std = 0.5 * math.sqrt(var) if np.isfinite(var) else float("nan")
    else:
        mean = float(np.mean(values))
        std = float("nan")
        if values.size > 1:
            std = float(np.std(values, ddof=1) / np.sqrt(values.size))
    return BreakawayFit(static_friction_n=mean, static_friction_std_n=std, onsets_s=tuple(onsets))


def fit_sliding_friction(
    strokes: Sequence[StrokeSamples],
    area_a: float,
    area_b: float,
    moving_mass_kg: float,
    smooth_s: float = 0.05,
    min_speed: float = 0.02,
    end_fraction: float = 0.1,
    viscous_ratio_s_m: float | None = None,
    offset: bool = False,
) -> SlidingFrictionFit:
    """Coulomb force Fcf and viscous coefficient Cvf from strokes in motion, eq. 4.16.

    .. math::

        P_a A_a - P_b A_b - P_{atm} A_{rod} - M \\ddot x
            = F_{cf}\\,\\mathrm{sign}(\\dot x) + C_{vf}\\,\\dot x

    Velocity and acceleration come from a Savitzky-Golay fit of the position
    (``smooth_s`` window, 2nd order); samples moving faster than ``min_speed`` and
    more than ``end_fraction`` of the stroke from both ends (end-stop impact and
    cushions, which the smoothing window would blend in) enter a linear
    least-squares fit. Strokes at different speeds are needed to separate Fcf and Cvf.

    Parameters
    ----------
    strokes : sequence of StrokeSamples
        Measured strokes (extend and retract, several speeds).
    area_a, area_b : float
        Piston areas [m^2].
    moving_mass_kg : float
        Piston, rod and load mass M_L + M_P [kg].
    smooth_s : float
        Differentiation window [s].
    min_speed : float
        Slowest sample used [m/s].
    end_fraction : float
        Part of the stroke excluded at each end [-].
    viscous_ratio_s_m : float, optional
        A known ratio Cvf / Fcf [s/m] (strokes all at about one speed cannot separate
        the two): then one factor is fitted, ``Fcf (sign(v) + r v)``, and Cvf is
        ``r Fcf``, with standard errors in the same ratio.
    offset : bool
        Also fit a constant force ``F0`` towards +x on the right side (the weight of
        a vertical load, a line pressure sensor's zero error: ``dP A``), from strokes
        in both directions; it is reported, not counted as friction.

    Returns
    -------
    SlidingFrictionFit
    """
    rows, rhs = [], []
    for s in strokes:
        xs, v, a, _ = _derivatives(s, smooth_s)
        x_lo, x_hi = float(np.min(xs)), float(np.max(xs))
        force = np.asarray(
            piston_force(np.asarray(s.pressure_a), np.asarray(s.pressure_b), area_a, area_b)
        )
        margin = end_fraction * (x_hi - x_lo)
        keep = (np.abs(v) > min_speed) & (xs > x_lo + margin) & (xs < x_hi - margin)
        rows.append(np.stack([np.sign(v[keep]), v[keep]], axis=1))
        rhs.append(force[keep] - moving_mass_kg * a[keep])
    design = np.concatenate(rows) if rows else np.zeros((0, 2))
    target = np.concatenate(rhs) if rhs else np.zeros(0)
    if design.shape[0] < 10:
        raise InputError(describe("moving samples", design.shape[0], ">= 10"))
    both_ways = bool(np.any(design[:, 0] > 0) and np.any(design[:, 0] < 0))
    if offset and not both_ways:
        raise InputError(
            describe("stroke directions", "one", "extend and retract (to fit a constant force)")
        )
    if viscous_ratio_s_m is None:
        speeds = np.abs(design[:, 1])
        narrow = np.ptp(speeds) < 0.5 * float(np.mean(speeds))
        if narrow and (offset or not both_ways):
            raise InputError(
                describe(
                    "spread of stroke speeds",
                    f"{np.ptp(speeds):.3g} m/s",
                    "strokes at different speeds (else Fcf and Cvf are inseparable)",
                )
            )
        columns = [design[:, 0], design[:, 1]]
    else:
        columns = [design[:, 0] + viscous_ratio_s_m * design[:, 1]]
    if offset:
        columns.append(np.ones(target.size))
    matrix = np.stack(columns, axis=1)
    coef, *_ = np.linalg.lstsq(matrix, target, rcond=None)
    res = target - matrix @ coef
    sigma2 = float(np.dot(res, res)) / max(target.size - matrix.shape[1], 1)
    cov = np.linalg.pinv(matrix.T @ matrix) * sigma2
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if viscous_ratio_s_m is None:
        cvf, cvf_std = float(coef[1]), float(std[1])
    else:
        cvf, cvf_std = viscous_ratio_s_m * float(coef[0]), viscous_ratio_s_m * float(std[0])
    return SlidingFrictionFit(
        coulomb_friction_n=float(coef[0]),
        coulomb_friction_std_n=float(std[0]),
        viscous_friction_n_s_m=cvf,
        viscous_friction_std_n_s_m=cvf_std,
        samples=int(target.size),
        offset_force_n=float(coef[-1]) if offset else 0.0,
    )
