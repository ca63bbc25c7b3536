"""Valve flow capacity: Cv and xT of the ISA gas equation from (P1, P2, flow) points.

Section 4.2.1: the measured valve flow shows a pressure drop between the upstream and
downstream lines even at zero flow (Fig. 4.7), which no flow standard has. The
dissertation measures that zero-flow drop at several supply pressures, subtracts it
from the upstream pressure (Fig. 4.8) and then fits Cv and xT of eq. 4.6 by
least squares over the remaining points (Fig. 4.9: Cv = 0.3988, xT = 1.0; the
catalogue's 410 l/min at 6 -> 5 bar(g) checks it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.physics.constants import ISA_STANDARD, T_ROOM
from pneufdd.physics.flow import isa_mass_flow
from pneufdd.physics.units import bar_gauge_to_pa

__all__ = ["ValveFit", "fit_valve", "nominal_flow_l_min", "zero_flow_drop"]


@dataclass(frozen=True)
class ValveFit:
    """Result of :func:`fit_valve`.

    Attributes
    ----------
    cv, cv_std : float
        Flow coefficient and its standard error [US gal/(min psi^0.5)].
    xt, xt_std : float
        Pressure differential ratio factor at choking and its standard error [-].
    rms : float
        Root-mean-square flow residual [kg/s].
    points : int
        Points used.
    """

    cv: float
    cv_std: float
    xt: float
    xt_std: float
    rms: float
    points: int

    @property
    def nominal_flow_l_min(self) -> float:
        """Catalogue nominal flow at 6 -> 5 bar(g), 20 degC [l/min at the ISA basis]."""
        return nominal_flow_l_min(self.cv, self.xt)


def _arrays(**named: npt.ArrayLike) -> list[FloatArray]:
    out = [np.asarray(v, dtype=np.float64).ravel() for v in named.values()]
    sizes = {a.size for a in out}
    if len(sizes) != 1:
        raise InputError(
            describe("lengths of " + ", ".join(named), [a.size for a in out], "equal lengths")
        )
    for name, a in zip(named, out, strict=True):
        if not np.all(np.isfinite(a)):
            raise InputError(describe(name, "non-finite values", "finite numbers"))
    return out


def zero_flow_drop(
    upstream_pressure: npt.ArrayLike, downstream_pressure: npt.ArrayLike
) -> tuple[float, float]:
    """The no-flow pressure drop as a straight line in the upstream pressure (Fig. 4.8).

    .. math:: \\Delta P_0(P_1) = a + b\\,P_1

    fitted to points measured with the flow control valve closed (zero flow) at
    several supply pressures; one point gives a constant drop.

    Parameters
    ----------
    upstream_pressure, downstream_pressure : array_like
        Absolute pressures at zero flow [Pa].

    Returns
    -------
    (float, float)
        Intercept ``a`` [Pa] and slope ``b`` [-] of the drop.

    Examples
    --------
    >>> zero_flow_drop([5e5, 7e5], [4.9e5, 6.88e5])
    (5000.0, 0.01)
    """
    p1, p2 = _arrays(upstream_pressure=upstream_pressure, downstream_pressure=downstream_pressure)
    drop = p1 - p2
    if p1.size == 1 or np.ptp(p1) == 0.0:
        return float(np.mean(drop)), 0.0
    slope, intercept = np.polyfit(p1, drop, 1)
    return float(round(intercept, 9)), float(round(slope, 12))


def fit_valve(
    upstream_pressure: npt.ArrayLike,
    downstream_pressure: npt.ArrayLike,
    mass_flow: npt.ArrayLike,
    zero_drop: tuple[float, float] = (0.0, 0.0),
    temperature: float = T_ROOM,
    fit_xt: bool = True,
    xt: float = 1.0,
) -> ValveFit:
    """Fit Cv and xT of the ISA gas equation (eq. 4.6) to measured flow points.

    The zero-flow drop ``a + b P1`` (:func:`zero_flow_drop`) is subtracted from the
    upstream pressure first (Fig. 4.8); then the RMS flow error is minimised (Fig. 4.9,
    ``scipy.optimize.least_squares``, xT bounded to [0.01, 1]).

    Parameters
    ----------
    upstream_pressure, downstream_pressure : array_like
        Absolute pressures [Pa].
    mass_flow : array_like
        Measured mass flow from port 1 to port 2 [kg/s].
    zero_drop : (float, float)
        Intercept [Pa] and slope [-] of the zero-flow drop.
    temperature : float
        Upstream air temperature [K].
    fit_xt : bool
        Fit xT too (else ``xt``).
    xt : float
        xT when it is not fitted [-] (a catalogue or assumed value).

    Returns
    -------
    ValveFit

    Examples
    --------
    Points of the CPE14 valve of section 4.2.1 (Cv = 0.3971, xT = 1) are recovered:

    >>> import numpy as np
    >>> p1 = np.full(20, 6.5e5); p2 = np.linspace(2e5, 6.4e5, 20)
    >>> from pneufdd.physics.flow import isa_mass_flow
    >>> fit = fit_valve(p1, p2, isa_mass_flow(p1, p2, 0.3971, 1.0))
    >>> round(fit.cv, 4), round(fit.xt, 3), round(fit.nominal_flow_l_min)
    (0.3971, 1.0, 406)
    """
    p1, p2, flow = _arrays(
        upstream_pressure=upstream_pressure, downstream_pressure=downstream_pressure,
        mass_flow=mass_flow,
    )  # fmt: skip
    if p1.size < 3:
        raise InputError(describe("flow points", p1.size, ">= 3"))
    corrected = p1 - (zero_drop[0] + zero_drop[1] * p1)
    if np.any(corrected <= 0.0):
        raise InputError(describe("corrected upstream pressure", "<= 0 Pa", "> 0 Pa"))
    scale = max(float(np.max(np.abs(flow))), 1e-12)
    # first guess from the subsonic law at xT = 1 (flow is proportional to Cv)
    unit = np.asarray(isa_mass_flow(corrected, p2, 1.0, 1.0 if fit_xt else xt, temperature))
    cv0 = max(float(np.dot(unit, flow) / max(np.dot(unit, unit), 1e-30)), 1e-3)

    def residual(theta: FloatArray) -> FloatArray:
        cv, x = float(theta[0]), float(theta[1]) if fit_xt else xt
        model = np.asarray(isa_mass_flow(corrected, p2, cv, x, temperature))
        out: FloatArray = (model - flow) / scale
        return out

    if fit_xt:
        starts = [np.array([cv0, x]) for x in (0.3, 0.6, 0.99)]
        fits = [
            least_squares(residual, s, bounds=([1e-6, 0.01], [50.0, 1.0]), x_scale=[cv0, 0.3])
            for s in starts
        ]
        sol = min(fits, key=lambda f: float(f.cost))
    else:
        sol = least_squares(residual, np.array([cv0]), bounds=([1e-6], [50.0]))
    res = residual(sol.x)
    dof = max(p1.size - sol.x.size, 1)
    sigma2 = float(np.dot(res, res)) / dof
    jac = np.asarray(sol.jac)
    try:
        cov = np.linalg.pinv(jac.T @ jac) * sigma2
    except np.linalg.LinAlgError:  # pragma: no cover - pinv converges for finite input
        cov = np.full((sol.x.size, sol.x.size), np.nan)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return ValveFit(
        cv=float(sol.x[0]),
        cv_std=float(std[0]),
        xt=float(sol.x[1]) if fit_xt else xt,
        xt_std=float(std[1]) if fit_xt else 0.0,
        rms=float(np.sqrt(np.mean(res**2)) * scale),
        points=int(p1.size),
    )


def nominal_flow_l_min(cv: float, xt: float = 1.0) -> float:
    """Catalogue nominal flow: 6 -> 5 bar(g) at 20 degC, eq. 4.6 [l/min, ISA basis].

    Section 4.2.1 checks its fit with this number (catalogue 410 l/min, computed
    413.6 l/min; the volume basis is discussed in :func:`pneufdd.physics.flow.isa_mass_flow`).

    Examples
    --------
    >>> round(nominal_flow_l_min(0.3988), 1)
    407.7
    """
    mass = float(isa_mass_flow(bar_gauge_to_pa(6.0), bar_gauge_to_pa(5.0), cv, xt, T_ROOM))
    return mass / ISA_STANDARD.density * 60e3
