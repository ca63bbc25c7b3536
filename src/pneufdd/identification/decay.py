"""A leak's equivalent orifice from the pressure decay of a closed volume.

A closed volume ``V`` (a chamber, or a machine's lines with the supply shut off)
loses air through a leak of effective area ``Cd A`` to the atmosphere. The leak is
the orifice of eq. 4.3 (choked while ``P_atm / P <= 0.528``, subsonic above); the
gas obeys eq. 4.7 and the energy balance of eqs. 4.8-4.10 with the volume fixed,
in one of three thermal limits:

* ``isothermal`` (heat exchange with the wall fast against the decay, eq. 4.10 with
  alpha = 1): :math:`\\dot P = -\\frac{R T_w}{V} \\dot m(P, T_w)`;
* ``adiabatic`` (no heat exchange, alpha = k): :math:`\\dot T = -(k-1) T \\dot m / m`,
  :math:`\\dot P = -\\frac{k R T}{V} \\dot m(P, T)`;
* ``thermal``: the twin's node model (``pneufdd.physics.chamber``), the adiabatic
  balance with the gas temperature relaxing to the wall with time constant
  ``thermal_time_s``: :math:`\\dot T = -(k-1) T \\dot m / m + (T_w - T) / \\tau`.

The orifice flow is proportional to ``Cd A`` and the pressure's rate to ``1 / V``, so a
decay curve alone tells the ratio ``Cd A / V`` [1/m] (:class:`DecayFit`); with the
volume known it gives the leak's area and its flow at any pressure
(:meth:`DecayFit.leak_mass_flow`). :func:`fit_pressure_decay` fits the ratio and the
initial pressure to a whole measured curve by least squares (the ODE integrated with
``scipy.integrate.solve_ivp``). ``docs/physics-validation.md`` checks the three limits
on measured decay curves of closed chambers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.physics.constants import GAMMA_AIR, P_ATM, R_AIR, T_ROOM
from pneufdd.physics.leaks import leak_mass_flow_kernel

__all__ = ["DECAY_MODELS", "DecayFit", "decay_curve", "decay_start", "fit_pressure_decay"]

DECAY_MODELS = ("isothermal", "adiabatic", "thermal")
"""The thermal limits of :func:`fit_pressure_decay`."""
MIN_DECAY_SAMPLES = 5


def _rhs(model: str, ratio: float, temperature_k: float, tau: float) -> tuple[int, object]:
    """State size and right-hand side of the decay ODE for ``Cd A / V = ratio``."""

    if model == "isothermal":

        def iso(_t: float, y: FloatArray) -> list[float]:
            flow = leak_mass_flow_kernel(float(y[0]), ratio, temperature_k)
            return [-R_AIR * temperature_k * flow]

        return 1, iso

    def with_temperature(_t: float, y: FloatArray) -> list[float]:
        p, temp = float(y[0]), max(float(y[1]), 50.0)
        # per unit volume: flow / V and m / V = P / (R T)
        flow = leak_mass_flow_kernel(p, ratio, temp)
        d_temp = -(GAMMA_AIR - 1.0) * temp * flow * R_AIR * temp / max(p, 1.0)
        if model == "thermal":
            d_temp += (temperature_k - temp) / tau
        # P = (m / V) R T: dP/dt = R (T d(m/V)/dt + (m/V) dT/dt)
        d_p = R_AIR * (-temp * flow + p / (R_AIR * temp) * d_temp)
        return [d_p, d_temp]

    return 2, with_temperature


def decay_curve(
    time_s: npt.ArrayLike,
    initial_pressure_pa: float,
    conductance_per_volume: float,
    model: str = "isothermal",
    thermal_time_s: float = math.inf,
    temperature_k: float = T_ROOM,
) -> FloatArray:
    """Absolute pressure of a leaking closed volume over time [Pa].

    Parameters
    ----------
    time_s : array_like
        Times from the start of the decay, increasing, >= 0 [s].
    initial_pressure_pa : float
        Absolute pressure at time 0 [Pa]; the gas is at ``temperature_k`` then.
    conductance_per_volume : float
        The leak's effective area over the volume, ``Cd A / V`` [1/m].
    model : {"isothermal", "adiabatic", "thermal"}
        Thermal limit (module docstring).
    thermal_time_s : float
        Heat-exchange time constant of the ``thermal`` model [s].
    temperature_k : float
        Wall (and initial gas) temperature [K].

    Returns
    -------
    ndarray
        Absolute pressure at ``time_s`` [Pa].

    Examples
    --------
    A 1 l vessel at 7 bar(g) with a leak of 60 SLPM at that pressure: after 2 s
    [bar abs], held at room temperature or cooled by the expansion:

    >>> from pneufdd.physics.leaks import leak_area
    >>> area = leak_area(60.0, "SLPM", reference_pressure=801_325.0)
    >>> [round(float(decay_curve([2.0], 801_325.0, area / 1e-3, m)[0]) / 1e5, 3)
    ...  for m in ("isothermal", "adiabatic")]
    [6.106, 5.532]
    """
    t = np.asarray(time_s, dtype=np.float64)
    if model not in DECAY_MODELS:
        raise InputError(describe("decay model", model, list(DECAY_MODELS)))
    size, rhs = _rhs(model, conductance_per_volume, temperature_k, thermal_time_s)
    y0 = [initial_pressure_pa] if size == 1 else [initial_pressure_pa, temperature_k]
    span = (0.0, float(t[-1]) if t.size else 0.0)
    if span[1] <= 0.0:
        return np.full(t.shape, float(initial_pressure_pa))
    sol = solve_ivp(
        rhs,
        span,
        y0,
        method="LSODA",
        t_eval=t,
        rtol=1e-8,
        atol=1e-3,
    )
    out: FloatArray = np.asarray(sol.y[0], dtype=np.float64)
    return out


@dataclass(frozen=True)
class DecayFit:
    """Result of :func:`fit_pressure_decay`.

    Attributes
    ----------
    model : str
        Thermal limit fitted.
    conductance_per_volume : float
        ``Cd A / V`` of the leak [1/m].
    initial_pressure_pa : float
        Fitted absolute pressure at the first sample [Pa].
    thermal_time_s : float
        Heat-exchange time constant used (``thermal``), else inf [s].
    residual_rms_pa, residual_max_pa : float
        Root mean square and largest absolute residual over the curve [Pa].
    samples : int
        Samples fitted.
    conductance_std : float
        Standard error of ``conductance_per_volume`` from the fit's Jacobian and its
        residual scatter [1/m].
    """

    model: str
    conductance_per_volume: float
    initial_pressure_pa: float
    thermal_time_s: float
    residual_rms_pa: float
    residual_max_pa: float
    samples: int
    conductance_std: float
    temperature_k: float = T_ROOM

    def effective_area(self, volume_m3: float) -> float:
        """The leak's effective area ``Cd A`` for a volume [m^2]."""
        return self.conductance_per_volume * volume_m3

    def leak_mass_flow(self, volume_m3: float, pressure_pa: float) -> float:
        """The leak's mass flow at an absolute pressure, room temperature [kg/s]."""
        return leak_mass_flow_kernel(pressure_pa, self.effective_area(volume_m3), T_ROOM)

    def predict(self, time_s: npt.ArrayLike) -> FloatArray:
        """The fitted curve at times from the first sample [Pa]."""
        return decay_curve(
            time_s,
            self.initial_pressure_pa,
            self.conductance_per_volume,
            self.model,
            self.thermal_time_s,
            self.temperature_k,
        )

    def to_dict(self) -> dict[str, float | str | int]:
        """JSON-ready fields."""
        return {
            "model": self.model,
            "conductance_per_volume_1_m": self.conductance_per_volume,
            "conductance_std_1_m": self.conductance_std,
            "initial_pressure_pa": self.initial_pressure_pa,
            "thermal_time_s": self.thermal_time_s,
            "residual_rms_pa": self.residual_rms_pa,
            "residual_max_pa": self.residual_max_pa,
            "samples": self.samples,
        }


def _checked(time_s: npt.ArrayLike, pressure_pa: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    t = np.asarray(time_s, dtype=np.float64).ravel()
    p = np.asarray(pressure_pa, dtype=np.float64).ravel()
    if t.size != p.size or t.size < MIN_DECAY_SAMPLES:
        raise InputError(
            describe(
                "decay curve (time, pressure)",
                f"{t.size} times and {p.size} pressures",
                f"as many of each, at least {MIN_DECAY_SAMPLES}",
            )
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise InputError(describe("decay curve samples", "NaN or infinite values", "finite"))
    if np.any(np.diff(t) <= 0.0):
        raise InputError(describe("decay curve times", "not increasing", "increasing times"))
    if p[0] <= P_ATM * 1.01:
        raise InputError(
            describe("decay curve's first pressure", p[0], "an absolute pressure above 1.02 bar")
        )
    return t - t[0], p


def fit_pressure_decay(
    time_s: npt.ArrayLike,
    pressure_pa: npt.ArrayLike,
    model: str = "isothermal",
    thermal_time_s: float = math.inf,
    temperature_k: float = T_ROOM,
) -> DecayFit:
    """Fit a leak's ``Cd A / V`` and the initial pressure to a whole decay curve.

    Least squares (``scipy.optimize.least_squares``) over ``ln(Cd A / V)`` and the
    initial pressure; the curve is :func:`decay_curve` of the chosen thermal limit.

    Parameters
    ----------
    time_s : array_like
        Sample times, increasing [s].
    pressure_pa : array_like
        Absolute pressure of the closed volume, starting above 1.02 bar [Pa].
    model : {"isothermal", "adiabatic", "thermal"}
        Thermal limit (module docstring).
    thermal_time_s : float
        Heat-exchange time constant for ``thermal`` [s].
    temperature_k : float
        Wall temperature [K].

    Returns
    -------
    DecayFit

    Raises
    ------
    InputError
        For an unknown model, fewer than 5 samples, non-finite or unordered samples,
        or a curve that starts at the atmosphere.

    Examples
    --------
    A simulated isothermal curve is recovered:

    >>> t = np.linspace(0.0, 3.0, 31)
    >>> p = decay_curve(t, 700_000.0, 1e-6 / 1e-3)
    >>> fit = fit_pressure_decay(t, p)
    >>> round(fit.conductance_per_volume, 6), round(fit.residual_rms_pa, 3)
    (0.001, 0.0)
    """
    if model not in DECAY_MODELS:
        raise InputError(describe("decay model", model, list(DECAY_MODELS)))
    if model == "thermal" and not (math.isfinite(thermal_time_s) and thermal_time_s > 0.0):
        raise InputError(describe("thermal_time_s of the thermal model", thermal_time_s, "> 0 s"))
    t, p = _checked(time_s, pressure_pa)
    p0 = float(np.median(p[: min(3, p.size)]))
    # start: the isothermal choked decay's initial slope, dP/dt = -R T P * c * ratio
    slope = (p[-1] - p0) / max(t[-1], 1e-9)
    per_ratio = R_AIR * temperature_k * leak_mass_flow_kernel(p0, 1.0, temperature_k)
    # bounds: from no leak to one that empties the volume's first e-fold within the
    # first sample interval (beyond, the curve says nothing and the ODE turns stiff)
    low = 1e-14
    high = max(p0 / (per_ratio * max(float(np.min(np.diff(t))), 1e-6)), 1e3 * low)
    start_ratio = float(np.clip(-slope / per_ratio, 10.0 * low, 0.1 * high))
    scale = max(float(np.ptp(p)), 1.0)

    def residuals(theta: FloatArray) -> FloatArray:
        curve = decay_curve(
            t, theta[1] * scale, math.exp(theta[0]), model, thermal_time_s, temperature_k
        )
        out: FloatArray = (curve - p) / scale
        return out

    sol = least_squares(
        residuals,
        np.array([math.log(start_ratio), p0 / scale]),
        method="trf",
        x_scale=1.0,
        bounds=([math.log(low), -np.inf], [math.log(high), np.inf]),
    )
    r = np.asarray(sol.fun) * scale
    jac = np.asarray(sol.jac)
    dof = max(r.size - 2, 1)
    cov = np.linalg.pinv(jac.T @ jac) * float(np.sum(np.asarray(sol.fun) ** 2)) / dof
    ratio = math.exp(float(sol.x[0]))
    return DecayFit(
        model=model,
        conductance_per_volume=ratio,
        initial_pressure_pa=float(sol.x[1]) * scale,
        thermal_time_s=thermal_time_s if model == "thermal" else math.inf,
        residual_rms_pa=float(np.sqrt(np.mean(r**2))),
        residual_max_pa=float(np.max(np.abs(r))),
        samples=int(t.size),
        conductance_std=ratio * math.sqrt(max(float(cov[0, 0]), 0.0)),
        temperature_k=temperature_k,
    )


def decay_start(time_s: npt.ArrayLike, pressure_pa: npt.ArrayLike, window_s: float = 1.0) -> int:
    """Index of the last sample before a recorded decay starts (0 if it starts at once).

    A recording often holds the filled volume for a while before the valve closes or
    the supply is shut. The noise ``sigma`` is the scatter of the first 20 samples'
    differences (median absolute deviation); the decay has started at the first
    sample from which the pressure falls by more than ``20 sigma`` within the next
    ``window_s``, and the start is the last sample, from there on, still within
    ``3 sigma`` of the level held until then. A curve that never falls that fast (a
    slow leak) starts at its first sample.

    Parameters
    ----------
    time_s, pressure_pa : array_like
        Samples, times increasing [s], absolute pressure [Pa].
    window_s : float
        Window of the fall that marks the start [s].

    Returns
    -------
    int
        Index into the samples.

    Examples
    --------
    >>> t = np.arange(0.0, 10.0, 0.1)
    >>> p = np.where(t < 3.0, 7e5, 7e5 - 1e5 * (t - 3.0)) + 300.0 * np.sin(7.0 * t)
    >>> int(decay_start(t, p))
    30
    """
    t, p = _checked(time_s, pressure_pa)
    head = np.diff(p[: min(21, p.size)])
    sigma = max(1.4826 * float(np.median(np.abs(head - np.median(head)))), 1.0)
    ahead = np.searchsorted(t, t + window_s)
    fall = p - p[np.clip(ahead, 0, p.size - 1)]
    fast = np.nonzero(fall > 20.0 * sigma)[0]
    if fast.size == 0 or fast[0] == 0:
        return 0
    first = int(fast[0])
    level = float(np.median(p[: first + 1]))
    # the fall was seen a window ahead: the start lies between first and there
    end = int(min(ahead[first], p.size - 1))
    held = np.nonzero(p[first : end + 1] < level - 3.0 * sigma)[0]
    return first + int(held[0]) - 1 if held.size and held[0] > 0 else first
