"""Restrictions in series: the twin's valve, tube, throttle and cushion as one path.

Pure arithmetic, without numba: :mod:`pneufdd.sim.compile` builds every plant with it,
and a leak-free simulation on the prebuilt twin must not load numba
(:mod:`pneufdd.sim.prebuilt`).
"""

from __future__ import annotations

import math

__all__ = ["series_cv"]


def series_cv(*cvs: float) -> float:
    """Flow coefficient of restrictions in series, the incompressible series rule.

    .. math:: \\frac{1}{C_v^2} = \\sum_i \\frac{1}{C_{v,i}^2}

    Each restriction passes ``Q = Cv sqrt(dp_i)`` for the same flow ``Q``; the pressure
    drops add up, so ``dp = Q^2 sum 1/Cv_i^2``. The twin lumps a valve, its tube and
    (on the exhaust) the meter-out throttle and the end-position cushion into one path
    this way (``docs/twin.md``, series restrictions; Crane TP-410).

    Parameters
    ----------
    *cvs : float
        Flow coefficients of the restrictions, each > 0 [US gal/(min psi^0.5)].

    Returns
    -------
    float
        Flow coefficient of the path [US gal/(min psi^0.5)].

    Examples
    --------
    >>> round(series_cv(0.4, 0.3), 3)
    0.24
    """
    return 1.0 / math.sqrt(sum(1.0 / c**2 for c in cvs))
