"""Sequential decision on per-cycle scores: a CUSUM with a known in-control run length.

The per-cycle statistic ``T`` of
:class:`~pneufdd.diagnosis.detection.statistic.CycleDistanceDetector`
is, on leak-free cycles, close to a scaled chi-square :math:`g\\chi^2_h` (Box fit of the
reference's **cross-validated** scores, so the fit describes cycles the model has not
seen). A leak raises ``T``; the test is designed for a scale change ``rho``:
:math:`H_0: T \\sim g\\chi^2_h`, :math:`H_1: T \\sim \\rho g \\chi^2_h`, with log
likelihood ratio per cycle

.. math::

    \\ell(T) = \\frac{T}{2g}\\left(1 - \\frac{1}{\\rho}\\right) - \\frac{h}{2}\\ln\\rho .

Page's CUSUM :math:`S_n = \\max(0, S_{n-1} + \\min(\\ell(T_n), c))` declares a leak when
:math:`S_n \\ge b`. The cap ``c = 0.6 b`` keeps a single odd cycle, however extreme,
from declaring: at least two cycles are needed. ``rho`` is by default the ratio of the
per-cycle threshold (the ``1 - alpha`` quantile of the fit, :attr:`threshold_`) to the
fit's mean ``g h``: the smallest leak the per-cycle test would flag.

The threshold ``b`` is set for an in-control average run length ``ARL0`` (cycles
between false alarms) with Siegmund's approximation for a CUSUM of likelihood ratios
(Siegmund 1985, eq. 2.56; the exponent root of :math:`E_0 e^{\\theta\\ell} = 1` is
:math:`\\theta = 1` for a likelihood ratio):

.. math::

    \\mathrm{ARL}_0 \\approx \\frac{e^{b'} - b' - 1}{K_0}, \\qquad b' = b + 1.166\\,\\sigma_0,

with :math:`K_0 = -E_0[\\ell]` (the Kullback-Leibler divergence) and :math:`\\sigma_0`
the standard deviation of :math:`\\ell` under :math:`H_0` (the 1.166 is the mean overshoot
correction of a normal walk). The cap only lowers increments, so the true ARL0 is at
least this. The change point is the cycle after the CUSUM last stood at zero.

After a declaration a second CUSUM with the roles swapped (increments
:math:`-\\ell`, same threshold) declares the machine back to leak-free: a repair.

References
----------
.. [1] Page, E. S. (1954). Continuous inspection schemes. Biometrika 41, 100-115.
.. [2] Siegmund, D. (1985). Sequential Analysis. Springer, section II.2 and X.2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

from scipy import optimize, stats

from pneufdd.errors import InputError, describe
from pneufdd.limits import MAX_ARL0

__all__ = ["CusumDecision", "CusumDetector", "CusumState", "check_arl0"]

OVERSHOOT = 1.166
"""Siegmund's mean-overshoot correction of a normal random walk [standard deviations]."""


@dataclass
class CusumState:
    """What the detector remembers between cycles (stored with every cycle).

    Attributes
    ----------
    up : float
        CUSUM towards a leak [-].
    down : float
        CUSUM back to leak-free (only while in alarm) [-].
    in_alarm : bool
        A leak has been declared and not yet repaired.
    change_start : float or None
        Start of the first cycle of the current excursion of ``up`` (the change
        point) [s since 1970-01-01 UTC].
    change_cycles : int
        Cycles since the change point.
    cycles : int
        Cycles seen.
    """

    up: float = 0.0
    down: float = 0.0
    in_alarm: bool = False
    change_start: float | None = None
    change_cycles: int = 0
    cycles: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CusumState:
        """Inverse of :meth:`to_dict`."""
        return cls(
            up=float(data["up"]),
            down=float(data["down"]),
            in_alarm=bool(data["in_alarm"]),
            change_start=None if data["change_start"] is None else float(data["change_start"]),
            change_cycles=int(data["change_cycles"]),
            cycles=int(data["cycles"]),
        )


@dataclass(frozen=True)
class CusumDecision:
    """The outcome of one cycle: ``"leak"`` (declared), ``"repaired"`` or None."""

    event: str | None
    increment: float
    state: CusumState


def check_arl0(arl0: float) -> None:
    """Refuse an in-control average run length outside ``(1, MAX_ARL0]`` (nan, inf too).

    Called by :class:`CusumDetector` and, before anything is opened or written, by
    ``pneufdd monitor``.

    Examples
    --------
    >>> check_arl0(1.0e6)
    >>> try:
    ...     check_arl0(float("inf"))
    ... except InputError as exc:
    ...     print(str(exc).split("; ")[1])
    allowed: > 1 and <= 1e+09 (docs/limits.md)
    """
    if not 1 < arl0 <= MAX_ARL0:  # also refuses nan and inf
        raise InputError(
            describe(
                "in-control average run length (--arl0) [cycles]",
                arl0,
                f"> 1 and <= {MAX_ARL0:g} (docs/limits.md)",
            )
        )


class CusumDetector:
    """CUSUM of scaled-chi-square likelihood ratios on per-cycle scores.

    Parameters
    ----------
    chi2_scale, chi2_dof : float
        Box fit ``g``, ``h`` of the leak-free cross-validated scores [-].
    threshold : float
        Per-cycle threshold of the statistic (sets the default ``rho``) [-].
    arl0 : float
        In-control average run length: cycles between false alarms [-].
    rho : float, optional
        Designed scale change of the statistic under a leak [-].
    cap_fraction : float
        Largest increment as a fraction of the decision threshold [-].

    Examples
    --------
    >>> det = CusumDetector(chi2_scale=0.01, chi2_dof=100.0, threshold=1.4, arl0=10_000)
    >>> round(det.rho, 2), round(det.decision_threshold, 2)
    (1.4, 7.79)
    >>> state = CusumState()
    >>> [det.update(state, t, start=float(i)).event for i, t in enumerate([1.0, 9.0, 1.0, 1.0])]
    [None, None, None, None]
    >>> [det.update(state, t, start=float(i)).event for i, t in enumerate([2.0, 2.0])]
    [None, 'leak']
    """

    def __init__(
        self,
        chi2_scale: float,
        chi2_dof: float,
        threshold: float,
        arl0: float = 1.0e6,
        rho: float | None = None,
        cap_fraction: float = 0.6,
    ) -> None:
        if not (chi2_scale > 0 and chi2_dof > 0 and threshold > 0):
            raise InputError(
                describe("leak-free score fit (g, h, threshold)", (chi2_scale, chi2_dof), "> 0")
            )
        check_arl0(arl0)
        if not 0.5 <= cap_fraction < 1.0:
            raise InputError(describe("cap_fraction", cap_fraction, "[0.5, 1)"))
        self.chi2_scale = float(chi2_scale)
        self.chi2_dof = float(chi2_dof)
        self.arl0 = float(arl0)
        mean = self.chi2_scale * self.chi2_dof
        self.rho = float(rho) if rho is not None else max(threshold / mean, 1.05)
        if not self.rho > 1:
            raise InputError(describe("designed scale change rho", self.rho, "> 1"))
        slope = (1.0 - 1.0 / self.rho) / (2.0 * self.chi2_scale)
        self._slope = slope
        self._offset = 0.5 * self.chi2_dof * math.log(self.rho)
        self.kl0 = -(slope * mean - self._offset)  # -E0[l] > 0
        self.sigma0 = slope * self.chi2_scale * math.sqrt(2.0 * self.chi2_dof)
        self.decision_threshold = self._solve_threshold()
        self.cap = cap_fraction * self.decision_threshold

    def _solve_threshold(self) -> float:
        def arl(b: float) -> float:
            bb = b + OVERSHOOT * self.sigma0
            return (math.expm1(bb) - bb) / self.kl0

        target = self.arl0
        return float(optimize.brentq(lambda b: math.log(arl(b)) - math.log(target), 1e-6, 700.0))

    @classmethod
    def from_reference(
        cls, detector: Any, arl0: float = 1.0e6, rho: float | None = None
    ) -> CusumDetector:
        """From a fitted :class:`~pneufdd.diagnosis.detection.statistic.CycleDistanceDetector`."""
        return cls(
            detector.chi2_scale_, detector.chi2_dof_, detector.threshold_, arl0=arl0, rho=rho
        )

    def llr(self, score: float) -> float:
        """Log likelihood ratio of one cycle's score, eq. above [-]."""
        return float(self._slope * score - self._offset)

    def update(self, state: CusumState, score: float, start: float) -> CusumDecision:
        """Take one cycle's score (cycle start ``start``); update ``state`` in place."""
        step = self.llr(score) if math.isfinite(score) else self.cap
        inc = min(step, self.cap)
        state.cycles += 1
        event = None
        if state.up <= 0.0:
            state.change_start, state.change_cycles = start, 0
        state.up = max(0.0, state.up + inc)
        if state.up > 0.0:
            state.change_cycles += 1
        else:
            state.change_start, state.change_cycles = None, 0
        if state.in_alarm:
            state.down = max(0.0, state.down + min(-step, self.cap))
            if state.down >= self.decision_threshold:
                event = "repaired"
                state.in_alarm, state.down, state.up = False, 0.0, 0.0
                state.change_start, state.change_cycles = None, 0
        elif state.up >= self.decision_threshold:
            event = "leak"
            state.in_alarm, state.down = True, 0.0
        return CusumDecision(event, inc, state)

    def leak_free_quantile(self, q: float) -> float:
        """Quantile ``q`` of the leak-free score distribution [-]."""
        return float(self.chi2_scale * stats.chi2.ppf(q, self.chi2_dof))
