"""Unit conversions at the edges of pneufdd, and the registry of channel units.

Inside pneufdd every quantity is SI: absolute pressure in Pa, mass flow in kg/s,
length in m, time in s, temperature in K. Users speak psig, bar gauge, SLPM and
scfm; these functions convert at the edge. Every volumetric flow names its basis
(see :mod:`pneufdd.physics.constants`): ``SLPM`` is always the dissertation's
standard (0 degC, 1013 mbar, 1.294 kg/m^3), ``scfm`` the CAGI/DOE standard air
(68 degF, 14.7 psia, 0.075 lb/ft^3), ``l/min (ANR)`` the ISO 8778 atmosphere.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.errors import UnitError, describe
from pneufdd.physics.constants import (
    ANR,
    CAGI_SCFM,
    DISSERTATION_STANDARD,
    KELVIN_OFFSET,
    P_ATM,
    PSI,
    FlowBasis,
)

__all__ = [
    "UNITS",
    "UnitSpec",
    "bar_gauge_to_pa",
    "flow_to_kg_s",
    "kg_s_to_flow",
    "kg_s_to_l_min_anr",
    "kg_s_to_scfm",
    "kg_s_to_slpm",
    "l_min_anr_to_kg_s",
    "pa_to_bar_gauge",
    "pa_to_psig",
    "psig_to_pa",
    "scfm_to_kg_s",
    "si_unit_of",
    "slpm_to_kg_s",
    "to_si",
]

Num = TypeVar("Num", float, npt.NDArray[np.float64])


def psig_to_pa(psig: Num) -> Num:
    """Convert gauge pressure in psi to absolute pressure.

    Parameters
    ----------
    psig : float or ndarray
        Gauge pressure [psig].

    Returns
    -------
    float or ndarray
        Absolute pressure [Pa], referred to the standard atmosphere 101325 Pa.

    Examples
    --------
    >>> round(psig_to_pa(90.0))
    721853
    """
    return psig * PSI + P_ATM


def pa_to_psig(pressure: Num) -> Num:
    """Convert absolute pressure to gauge pressure in psi.

    Parameters
    ----------
    pressure : float or ndarray
        Absolute pressure [Pa].

    Returns
    -------
    float or ndarray
        Gauge pressure [psig].

    Examples
    --------
    >>> round(pa_to_psig(psig_to_pa(62.48)), 6)
    62.48
    """
    return (pressure - P_ATM) / PSI


def bar_gauge_to_pa(bar_g: Num) -> Num:
    """Convert gauge pressure in bar to absolute pressure.

    Parameters
    ----------
    bar_g : float or ndarray
        Gauge pressure [bar(g)].

    Returns
    -------
    float or ndarray
        Absolute pressure [Pa].

    Examples
    --------
    >>> bar_gauge_to_pa(6.0)
    701325.0
    """
    return bar_g * 1e5 + P_ATM


def pa_to_bar_gauge(pressure: Num) -> Num:
    """Convert absolute pressure to gauge pressure in bar.

    Parameters
    ----------
    pressure : float or ndarray
        Absolute pressure [Pa].

    Returns
    -------
    float or ndarray
        Gauge pressure [bar(g)].

    Examples
    --------
    >>> pa_to_bar_gauge(701325.0)
    6.0
    """
    return (pressure - P_ATM) / 1e5


def flow_to_kg_s(flow: Num, basis: FlowBasis, litres_per: float = 1e-3 / 60.0) -> Num:
    """Convert a volumetric flow at standard conditions to mass flow.

    Parameters
    ----------
    flow : float or ndarray
        Volumetric flow at the reference state of ``basis``, in units whose size
        in m^3/s is ``litres_per`` [unit of flow].
    basis : FlowBasis
        Reference state; its density is used [kg/m^3].
    litres_per : float
        Size of one unit of ``flow`` [m^3/s]; the default is one litre per minute.

    Returns
    -------
    float or ndarray
        Mass flow [kg/s].

    Examples
    --------
    >>> from pneufdd.physics.constants import DISSERTATION_STANDARD
    >>> round(flow_to_kg_s(60.0, DISSERTATION_STANDARD), 6)
    0.001294
    """
    return flow * litres_per * basis.density


def kg_s_to_flow(mass_flow: Num, basis: FlowBasis, litres_per: float = 1e-3 / 60.0) -> Num:
    """Convert mass flow to a volumetric flow at the reference state of ``basis``.

    Parameters
    ----------
    mass_flow : float or ndarray
        Mass flow [kg/s].
    basis : FlowBasis
        Reference state; its density is used [kg/m^3].
    litres_per : float
        Size of one unit of the result [m^3/s]; the default is one litre per minute.

    Returns
    -------
    float or ndarray
        Volumetric flow at the reference state [unit of flow].

    Examples
    --------
    >>> from pneufdd.physics.constants import DISSERTATION_STANDARD
    >>> round(kg_s_to_flow(0.001294, DISSERTATION_STANDARD), 9)
    60.0
    """
    return mass_flow / (litres_per * basis.density)


def slpm_to_kg_s(slpm: Num) -> Num:
    """Convert standard litres per minute (0 degC, 1013 mbar, 1.294 kg/m^3) to mass flow.

    Parameters
    ----------
    slpm : float or ndarray
        Volumetric flow at the dissertation's standard conditions [SLPM].

    Returns
    -------
    float or ndarray
        Mass flow [kg/s].

    Examples
    --------
    >>> slpm_to_kg_s(200.0)
    0.004313333333333334
    """
    return flow_to_kg_s(slpm, DISSERTATION_STANDARD)


def kg_s_to_slpm(mass_flow: Num) -> Num:
    """Convert mass flow to standard litres per minute (0 degC, 1013 mbar, 1.294 kg/m^3).

    Parameters
    ----------
    mass_flow : float or ndarray
        Mass flow [kg/s].

    Returns
    -------
    float or ndarray
        Volumetric flow at the dissertation's standard conditions [SLPM].

    Examples
    --------
    >>> round(kg_s_to_slpm(slpm_to_kg_s(28.0)), 9)
    28.0
    """
    return kg_s_to_flow(mass_flow, DISSERTATION_STANDARD)


def l_min_anr_to_kg_s(l_min: Num) -> Num:
    """Convert litres per minute ANR (20 degC, 100 kPa, 1.185 kg/m^3) to mass flow.

    Parameters
    ----------
    l_min : float or ndarray
        Volumetric flow at the ISO 8778 reference atmosphere [l/min (ANR)].

    Returns
    -------
    float or ndarray
        Mass flow [kg/s].

    Examples
    --------
    >>> round(l_min_anr_to_kg_s(410.0), 6)
    0.008098
    """
    return flow_to_kg_s(l_min, ANR)


def kg_s_to_l_min_anr(mass_flow: Num) -> Num:
    """Convert mass flow to litres per minute ANR (20 degC, 100 kPa, 1.185 kg/m^3).

    Parameters
    ----------
    mass_flow : float or ndarray
        Mass flow [kg/s].

    Returns
    -------
    float or ndarray
        Volumetric flow at the ISO 8778 reference atmosphere [l/min (ANR)].

    Examples
    --------
    >>> round(kg_s_to_l_min_anr(l_min_anr_to_kg_s(410.0)), 9)
    410.0
    """
    return kg_s_to_flow(mass_flow, ANR)


_CFM = 0.028316846592 / 60.0  # one cubic foot per minute [m^3/s]


def scfm_to_kg_s(scfm: Num) -> Num:
    """Convert standard cubic feet per minute (68 degF, 14.7 psia, 0.075 lb/ft^3) to mass flow.

    Parameters
    ----------
    scfm : float or ndarray
        Volumetric flow of CAGI/DOE standard air [scfm].

    Returns
    -------
    float or ndarray
        Mass flow [kg/s].

    Examples
    --------
    >>> round(scfm_to_kg_s(100.0), 5)
    0.0567
    """
    return flow_to_kg_s(scfm, CAGI_SCFM, litres_per=_CFM)


def kg_s_to_scfm(mass_flow: Num) -> Num:
    """Convert mass flow to standard cubic feet per minute (68 degF, 14.7 psia).

    Parameters
    ----------
    mass_flow : float or ndarray
        Mass flow [kg/s].

    Returns
    -------
    float or ndarray
        Volumetric flow of CAGI/DOE standard air [scfm].

    Examples
    --------
    >>> round(kg_s_to_scfm(scfm_to_kg_s(5.72)), 9)
    5.72
    """
    return kg_s_to_flow(mass_flow, CAGI_SCFM, litres_per=_CFM)


# ---------------------------------------------------------------------------
# Channel unit registry: what a Recording or a reader accepts.
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class UnitSpec:
    """One accepted channel unit and how to bring it to SI.

    Attributes
    ----------
    quantity : str
        Physical quantity, e.g. ``"pressure"``.
    si_unit : str
        The SI unit pneufdd stores this quantity in.
    to_si : Callable
        Converts an array in this unit to ``si_unit``.
    note : str
        Basis or reference the unit implies.
    """

    quantity: str
    si_unit: str
    to_si: Callable[[FloatArray], FloatArray]
    note: str = ""


def _scale(factor: float, offset: float = 0.0) -> Callable[[FloatArray], FloatArray]:
    def convert(values: FloatArray) -> FloatArray:
        return values * factor + offset

    return convert


UNITS: dict[str, UnitSpec] = {
    # pressure, stored absolute
    "Pa": UnitSpec("pressure", "Pa", _scale(1.0), "absolute"),
    "kPa": UnitSpec("pressure", "Pa", _scale(1e3), "absolute"),
    "MPa": UnitSpec("pressure", "Pa", _scale(1e6), "absolute"),
    "bar": UnitSpec("pressure", "Pa", _scale(1e5), "absolute"),
    "bar(g)": UnitSpec("pressure", "Pa", _scale(1e5, P_ATM), "gauge, over 101325 Pa"),
    "psia": UnitSpec("pressure", "Pa", _scale(PSI), "absolute"),
    "psig": UnitSpec("pressure", "Pa", _scale(PSI, P_ATM), "gauge, over 101325 Pa"),
    # mass flow, stored in kg/s
    "kg/s": UnitSpec("mass flow", "kg/s", _scale(1.0)),
    "SLPM": UnitSpec(
        "mass flow",
        "kg/s",
        _scale(DISSERTATION_STANDARD.density * 1e-3 / 60.0),
        "0 degC, 1013 mbar",
    ),
    "l/min (ANR)": UnitSpec(
        "mass flow", "kg/s", _scale(ANR.density * 1e-3 / 60.0), "20 degC, 100 kPa, 65 % RH"
    ),
    "scfm": UnitSpec(
        "mass flow", "kg/s", _scale(CAGI_SCFM.density * _CFM), "68 degF, 14.7 psia, 36 % RH"
    ),
    # standard volume (accumulated flow), stored as mass
    "kg": UnitSpec("mass", "kg", _scale(1.0)),
    "SL": UnitSpec("mass", "kg", _scale(DISSERTATION_STANDARD.density * 1e-3), "0 degC, 1013 mbar"),
    # geometry and motion
    "m": UnitSpec("length", "m", _scale(1.0)),
    "mm": UnitSpec("length", "m", _scale(1e-3)),
    "m/s": UnitSpec("velocity", "m/s", _scale(1.0)),
    "rad": UnitSpec("angle", "rad", _scale(1.0)),
    "deg": UnitSpec("angle", "rad", _scale(np.pi / 180.0)),
    # others
    "K": UnitSpec("temperature", "K", _scale(1.0)),
    "degC": UnitSpec("temperature", "K", _scale(1.0, KELVIN_OFFSET)),
    "s": UnitSpec("time", "s", _scale(1.0)),
    "V": UnitSpec("voltage", "V", _scale(1.0)),
    "1": UnitSpec("dimensionless", "1", _scale(1.0), "digital 0/1 or ratio"),
}
"""Every unit a channel may be given in, keyed by its exact spelling."""

_AMBIGUOUS = {
    "psi": "say 'psia' (absolute) or 'psig' (gauge)",
    "lpm": "say 'SLPM' (0 degC, 1013 mbar) or 'l/min (ANR)' (20 degC, 100 kPa)",
    "l/min": "say 'SLPM' (0 degC, 1013 mbar) or 'l/min (ANR)' (20 degC, 100 kPa)",
    "cfm": "say 'scfm' (68 degF, 14.7 psia)",
    "barg": "spell it 'bar(g)'",
}


def _spec(unit: str, where: str) -> UnitSpec:
    if unit in UNITS:
        return UNITS[unit]
    hint = _AMBIGUOUS.get(unit)
    if hint is not None:
        raise UnitError(describe(f"ambiguous unit {where} ({hint})", unit, UNITS))
    raise UnitError(describe(f"unknown unit {where}", unit, UNITS))


def si_unit_of(unit: str, where: str = "") -> str:
    """Return the SI unit pneufdd stores a quantity given in ``unit`` in.

    Parameters
    ----------
    unit : str
        A key of :data:`UNITS`.
    where : str
        Context for the error message, e.g. ``"of channel 'P_In'"``.

    Returns
    -------
    str
        SI unit, e.g. ``"Pa"`` for ``"psig"``.

    Raises
    ------
    UnitError
        If ``unit`` is unknown or ambiguous; the message lists the accepted units.

    Examples
    --------
    >>> si_unit_of("SLPM")
    'kg/s'
    """
    return _spec(unit, where).si_unit


def to_si(values: npt.ArrayLike, unit: str, where: str = "") -> tuple[FloatArray, str]:
    """Convert values given in ``unit`` to the SI unit pneufdd stores.

    Parameters
    ----------
    values : array_like
        Values in ``unit``.
    unit : str
        A key of :data:`UNITS`.
    where : str
        Context for the error message, e.g. ``"of channel 'Q_In' in run.csv"``.

    Returns
    -------
    values_si : ndarray
        Values in SI [si_unit].
    si_unit : str
        The SI unit of ``values_si``.

    Examples
    --------
    >>> v, u = to_si([0.0, 90.0], "psig")
    >>> u, [round(x) for x in v]
    ('Pa', [101325, 721853])
    """
    spec = _spec(unit, where)
    return spec.to_si(np.asarray(values, dtype=np.float64)), spec.si_unit
