"""Seal friction against chamber pressure, from a piston driven at constant pressure.

A test bench holds one chamber of a piston at a (nearly) constant pressure and moves
the piston back and forth with an external drive through a force sensor. The force
balance of eq. 4.13 at constant speed (no acceleration term) with the friction of
eqs. 4.14 and 4.16 is

.. math:: F = A\\,(P - P_{atm}) + F_0 + \\operatorname{sign}(v)\\,F_{cf}(P) + C_{vf}\\,v

with the piston area ``A`` and the sensor's zero ``F0`` common to every run. The
twin's friction (eq. 4.14, :mod:`pneufdd.physics.friction`) has a Coulomb force that
does not depend on pressure; an O-ring is pressed harder against the bore the higher
the pressure, so :func:`fit_seal_friction` fits both forms and reports their
residuals: ``pressure_dependent=False`` is the twin's, ``True`` adds
:math:`F_{cf}(P) = F_{c0} + k_p (P - P_{atm})`. The breakaway force of eq. 4.15 is the
peak of the friction force right after each reversal (:func:`breakaway_forces`).
``docs/physics-validation.md`` applies both to measured O-ring friction at 1-7 bar.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear
from scipy.signal import savgol_filter

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.physics.constants import P_ATM

__all__ = ["SealFrictionFit", "SealFrictionRun", "breakaway_forces", "fit_seal_friction"]

RESAMPLE_DT = 0.01
"""Uniform sample interval the runs are interpolated onto [s]."""
SMOOTH_S = 0.15
"""Savitzky-Golay window of the velocity [s]."""
SETTLE_S = 0.3
"""Time after a reversal left out of the sliding fit (the breakaway transient) [s]."""


@dataclass(frozen=True)
class SealFrictionRun:
    """One run: time [s], position [m], chamber absolute pressure [Pa], force [N]."""

    time: FloatArray
    position: FloatArray
    pressure: FloatArray
    force: FloatArray

    def __post_init__(self) -> None:
        arrays = (self.time, self.position, self.pressure, self.force)
        sizes = {np.asarray(a).size for a in arrays}
        if len(sizes) != 1 or min(sizes) < 50:
            raise InputError(
                describe(
                    "seal friction run arrays (time, position, pressure, force)",
                    sorted(sizes),
                    "one length >= 50",
                )
            )
        if not all(np.all(np.isfinite(np.asarray(a, dtype=np.float64))) for a in arrays):
            raise InputError(describe("seal friction run samples", "NaN or inf", "finite values"))
        if np.any(np.diff(np.asarray(self.time, dtype=np.float64)) <= 0.0):
            raise InputError(describe("seal friction run times", "not increasing", "increasing"))


@dataclass(frozen=True)
class SealFrictionFit:
    """Result of :func:`fit_seal_friction`.

    Attributes
    ----------
    area_m2 : float
        Piston area [m^2].
    offset_n : float
        Force sensor zero F0 [N].
    coulomb_n : float
        Coulomb friction Fcf at the atmosphere (pressure-dependent fit) or at every
        pressure (the twin's form) [N].
    coulomb_per_bar_n : float
        Rise of the Coulomb friction per bar of chamber pressure (0 for the twin's
        form) [N/bar].
    viscous_n_s_m : float
        Viscous coefficient Cvf [N s/m].
    residual_rms_n, residual_max_n : float
        Root mean square and largest absolute residual over the samples fitted [N].
    samples : int
        Samples fitted (moving, away from reversals).
    pressure_dependent : bool
        Which form was fitted.
    """

    area_m2: float
    offset_n: float
    coulomb_n: float
    coulomb_per_bar_n: float
    viscous_n_s_m: float
    residual_rms_n: float
    residual_max_n: float
    samples: int
    pressure_dependent: bool

    def coulomb_at(self, pressure_pa: float) -> float:
        """Coulomb friction at an absolute chamber pressure [N]."""
        return self.coulomb_n + self.coulomb_per_bar_n * (pressure_pa - P_ATM) / 1e5

    def to_dict(self) -> dict[str, float | int | bool]:
        """JSON-ready fields."""
        return dict(self.__dict__)


def _uniform(run: SealFrictionRun) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The run on a uniform grid: time, position, pressure, force, velocity [SI]."""
    t = np.asarray(run.time, dtype=np.float64)
    grid = np.arange(t[0], t[-1], RESAMPLE_DT)
    x = np.interp(grid, t, np.asarray(run.position, dtype=np.float64))
    p = np.interp(grid, t, np.asarray(run.pressure, dtype=np.float64))
    f = np.interp(grid, t, np.asarray(run.force, dtype=np.float64))
    n = max(round(SMOOTH_S / RESAMPLE_DT) | 1, 5)
    v = savgol_filter(x, n, 2, deriv=1, delta=RESAMPLE_DT)
    return p, f, v, grid


def _sliding_samples(
    run: SealFrictionRun, min_speed: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pressure, force and velocity of the samples moving steadily in one direction."""
    p, f, v, _grid = _uniform(run)
    moving = np.abs(v) > min_speed
    direction = np.sign(v) * moving
    keep = moving.copy()
    # leave out SETTLE_S after every start of motion (reversal or start from rest)
    starts = np.nonzero(np.diff(direction) != 0)[0] + 1
    for k in starts:
        keep[k : k + round(SETTLE_S / RESAMPLE_DT)] = False
    return p[keep], f[keep], v[keep]


def fit_seal_friction(
    runs: Sequence[SealFrictionRun],
    pressure_dependent: bool = True,
    min_speed_m_s: float = 2e-3,
    area_m2: float | None = None,
    offset_n: float | None = None,
) -> SealFrictionFit:
    """Fit area, sensor zero, Coulomb and viscous friction to driven-piston runs.

    Linear least squares over every moving sample of every run (the model in the
    module docstring; ``scipy.optimize.lsq_linear`` with ``Cvf >= 0`` and ``A > 0``);
    ``pressure_dependent=False`` is the twin's friction (eq. 4.14, Coulomb force
    independent of pressure). Samples within 0.3 s of a start of motion are left out
    (the breakaway transient of eq. 4.15). Area and sensor zero can be given (a fit
    per pressure level with those of a fit over all levels).

    Parameters
    ----------
    runs : sequence of SealFrictionRun
        Runs at one or more pressures (at least two pressures for the dependence).
    pressure_dependent : bool
        Fit ``Fcf`` linear in the chamber pressure.
    min_speed_m_s : float
        Speed below which a sample counts as at rest [m/s].
    area_m2, offset_n : float, optional
        Piston area [m^2] and sensor zero [N] to hold instead of fitting.

    Returns
    -------
    SealFrictionFit

    Raises
    ------
    InputError
        Without runs, or with too few moving samples.

    Examples
    --------
    A 26 mm piston with 3 N + 0.8 N/bar of Coulomb friction, driven at 10 mm/s:

    >>> t = np.arange(0.0, 8.0, 0.01)
    >>> x = 0.02 * (1 - np.cos(2 * np.pi * t / 4.0)) / 2
    >>> v = np.gradient(x, t)
    >>> runs = []
    >>> for bar in (1.0, 4.0, 7.0):
    ...     p = np.full(t.size, P_ATM + bar * 1e5)
    ...     f = 5.3e-4 * bar * 1e5 + 1.0 + np.sign(v) * (3.0 + 0.8 * bar) + 50.0 * v
    ...     runs.append(SealFrictionRun(t, x, p, f))
    >>> fit = fit_seal_friction(runs)
    >>> round(fit.area_m2 * 1e4, 3), round(fit.coulomb_n, 2), round(fit.coulomb_per_bar_n, 2)
    (5.3, 3.0, 0.8)
    """
    if not runs:
        raise InputError(describe("seal friction runs", 0, "at least one"))
    rows: list[FloatArray] = []
    forces: list[FloatArray] = []
    for run in runs:
        p, f, v = _sliding_samples(run, min_speed_m_s)
        gauge = p - P_ATM
        s = np.sign(v)
        known = (area_m2 or 0.0) * gauge + (offset_n or 0.0)
        columns = [gauge, np.ones_like(gauge), s, s * gauge / 1e5, v]
        rows.append(np.column_stack(columns))
        forces.append(f - known)
    a = np.vstack(rows)
    y = np.concatenate(forces)
    # columns: area, offset, Fc0, Fc per bar, Cvf; those held or not fitted drop out
    fitted = [area_m2 is None, offset_n is None, True, pressure_dependent, True]
    if y.size < 2 * sum(fitted):
        raise InputError(
            describe("moving samples of the seal friction runs", y.size, f">= {2 * sum(fitted)}")
        )
    low = np.array([1e-9, -np.inf, -np.inf, -np.inf, 0.0])[fitted]
    sol = lsq_linear(a[:, fitted], y, bounds=(low, np.full(low.size, np.inf)))
    coef = np.zeros(5)
    coef[fitted] = sol.x
    r = y - a @ coef
    return SealFrictionFit(
        area_m2=float(coef[0]) if area_m2 is None else area_m2,
        offset_n=float(coef[1]) if offset_n is None else offset_n,
        coulomb_n=float(coef[2]),
        coulomb_per_bar_n=float(coef[3]),
        viscous_n_s_m=float(coef[4]),
        residual_rms_n=float(np.sqrt(np.mean(r**2))),
        residual_max_n=float(np.max(np.abs(r))),
        samples=int(y.size),
        pressure_dependent=pressure_dependent,
    )


def breakaway_forces(
    run: SealFrictionRun, area_m2: float, offset_n: float, min_speed_m_s: float = 2e-3
) -> FloatArray:
    """Breakaway (stick-slip) friction at every start of motion of a run, eq. 4.15 [N].

    The friction force is the measured force less the pressure force and the sensor
    zero, signed along the motion; its peak within 0.3 s after a start of motion
    (reversal or start from rest) is the breakaway force ``Fsf`` of that start.

    Parameters
    ----------
    run : SealFrictionRun
        One run.
    area_m2, offset_n : float
        Piston area [m^2] and sensor zero [N] (from :func:`fit_seal_friction`).
    min_speed_m_s : float
        Speed below which a sample counts as at rest [m/s].

    Returns
    -------
    ndarray
        One breakaway force per start of motion [N].
    """
    p, f, v, _ = _uniform(run)
    friction = f - area_m2 * (p - P_ATM) - offset_n
    moving = np.abs(v) > min_speed_m_s
    direction = np.sign(v) * moving
    starts = np.nonzero((np.diff(direction) != 0) & (direction[1:] != 0))[0] + 1
    span = round(SETTLE_S / RESAMPLE_DT)
    out = [
        float(np.max(direction[k] * friction[k : k + span]))
        for k in starts
        if k + span <= friction.size
    ]
    return np.asarray(out, dtype=np.float64)
