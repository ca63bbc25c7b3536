"""The supply path: regulator set point, droop and the supply-line restriction R1.

Fig. 4.13 draws the supply as a source ``V`` behind a resistance ``R1`` (tubing,
flow meter) to the measuring point ``V_m``; eq. 4.20: ``V_m = V - R1 i``. In
pneumatic terms ``P_In = P_set - R1 Q_In`` (eq. 4.19-4.21 explain why a leak lowers
``P_In`` and raises ``Q_In``). :func:`fit_supply_path` fits that line to (P_In,
Q_In) samples (its intercept is the set point at zero flow, its slope the droop
``R1``) and, for the twin, the ISA flow coefficient of the whole path from the set
point to ``P_In`` (eq. 4.6 with the set point upstream).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from pneufdd.errors import InputError, describe
from pneufdd.identification.valve import fit_valve
from pneufdd.physics.flow import isa_mass_flow

__all__ = ["SupplyPathFit", "fit_supply_path"]


@dataclass(frozen=True)
class SupplyPathFit:
    """Result of :func:`fit_supply_path`.

    Attributes
    ----------
    set_point_pa, set_point_std_pa : float
        Pressure at zero flow (regulator set point seen at ``P_In``) [Pa absolute].
    resistance_pa_s_kg, resistance_std_pa_s_kg : float
        Droop R1 of eq. 4.20: pressure lost per mass flow [Pa s/kg].
    path_cv : float
        ISA flow coefficient of the path from the set point to ``P_In`` (xT = 1) [-].
    path_set_point_pa : float
        Upstream pressure of that ISA fit (fitted with it) [Pa absolute].
    """

    set_point_pa: float
    set_point_std_pa: float
    resistance_pa_s_kg: float
    resistance_std_pa_s_kg: float
    path_cv: float
    path_set_point_pa: float


def fit_supply_path(
    supply_pressure: npt.ArrayLike, supply_flow: npt.ArrayLike, min_flow: float = 0.0
) -> SupplyPathFit:
    """Fit eq. 4.20, ``P_In = P_set - R1 Q_In``, to quasi-steady supply samples.

    Parameters
    ----------
    supply_pressure : array_like
        ``P_In`` [Pa absolute].
    supply_flow : array_like
        ``Q_In`` [kg/s].
    min_flow : float
        Samples at lower flow are ignored for the path Cv [kg/s].

    Returns
    -------
    SupplyPathFit

    Examples
    --------
    >>> import numpy as np
    >>> q = np.linspace(0.0, 4e-3, 50)
    >>> fit = fit_supply_path(5.9e5 - 2.0e7 * q, q)
    >>> round(fit.set_point_pa), round(fit.resistance_pa_s_kg)
    (590000, 20000000)
    """
    p = np.asarray(supply_pressure, dtype=np.float64).ravel()
    q = np.asarray(supply_flow, dtype=np.float64).ravel()
    if p.size != q.size or p.size < 3:
        raise InputError(describe("P_In and Q_In samples", (p.size, q.size), "equal, >= 3"))
    ok = np.isfinite(p) & np.isfinite(q)
    p, q = p[ok], q[ok]
    if p.size < 3:
        raise InputError(describe("finite P_In and Q_In sample pairs", p.size, ">= 3"))
    if np.ptp(q) <= 0.0:
        raise InputError(
            describe("spread of supply flow", 0.0, "> 0 kg/s (samples at several flows)")
        )
    design = np.stack([np.ones_like(q), -q], axis=1)
    coef, *_ = np.linalg.lstsq(design, p, rcond=None)
    res = p - design @ coef
    sigma2 = float(np.dot(res, res)) / max(p.size - 2, 1)
    std = np.sqrt(np.clip(np.diag(np.linalg.pinv(design.T @ design) * sigma2), 0.0, None))
    flowing = q > max(min_flow, 0.05 * float(np.max(q)))
    path_cv, path_set = float("nan"), float("nan")
    if np.count_nonzero(flowing) >= 3:
        pf, qf = p[flowing], q[flowing]
        top = float(np.max(p))
        scale = float(np.max(qf))

        def residual(theta: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
            upstream = top + float(theta[0])
            model = np.asarray(isa_mass_flow(upstream, pf, float(theta[1])))
            out: npt.NDArray[np.float64] = (model - qf) / scale
            return out

        guess = fit_valve(np.full(pf.size, top + 1e3), pf, qf, fit_xt=False).cv
        sol = least_squares(
            residual, np.array([1e3, guess]), bounds=([1.0, 1e-6], [2e5, 50.0]),
            x_scale=[1e3, guess],
        )  # fmt: skip
        path_set, path_cv = top + float(sol.x[0]), float(sol.x[1])
    return SupplyPathFit(
        set_point_pa=float(coef[0]),
        set_point_std_pa=float(std[0]),
        resistance_pa_s_kg=float(coef[1]),
        resistance_std_pa_s_kg=float(std[1]),
        path_cv=path_cv,
        path_set_point_pa=path_set,
    )
