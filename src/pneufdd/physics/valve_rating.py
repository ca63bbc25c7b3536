"""A catalogue's valve flow rating converted to the twin's Cv and xT (eq. 4.5 -> eq. 4.6).

Catalogues rate a directional valve in one of two ways:

* **standard nominal flow** ``qnN`` (Festo): the flow at 6 bar(g) upstream and 5 bar(g)
  downstream, 20 degC, in l/min (ANR, ISO 8778);
* **sonic conductance** ``C`` and **critical pressure ratio** ``b`` of ISO 6358 (SMC,
  eq. 4.5), with ``C`` in dm^3/(s bar) (ANR).

The twin's valve is the ISA law of eq. 4.6 with ``Cv`` and ``xT``. One convention
converts both ratings: **the twin's valve passes the catalogue's flow at the nominal
point 6 -> 5 bar(g), 20 degC**. For ``qnN`` that is the rating itself, with the
description's ``xT`` (0.9 for Festo's spool valves, as festo-dsd's CPE valves and
``docs/machines.md``); for ``C`` and ``b`` the nominal flow is computed with ISO 6358
(:func:`pneufdd.physics.flow.iso6358_mass_flow`) and ``xT = 1 - b`` (both laws choke at
the same pressure ratio). Matched at the nominal point, the ISA valve's choked flow is
about 4 % below ISO 6358's for ``b`` 0.28-0.37 (the two laws' subsonic curves differ:
the ISA expansion factor against the ISO ellipse); matched at choking instead, its
nominal flow would be 4 % above the catalogue's.
"""

from __future__ import annotations

from pneufdd.errors import InputError, describe
from pneufdd.physics.constants import T_ROOM
from pneufdd.physics.flow import isa_mass_flow, iso6358_mass_flow, sonic_conductance_from_catalogue
from pneufdd.physics.units import bar_gauge_to_pa, l_min_anr_to_kg_s

__all__ = [
    "FESTO_SPOOL_XT",
    "cv_from_nominal_flow",
    "isa_from_sonic_conductance",
    "nominal_flow_from_sonic_conductance",
]

FESTO_SPOOL_XT = 0.9
"""Pressure-drop ratio factor taken for a spool valve rated by ``qnN`` alone [-]
(festo-dsd's CPE valves, ``docs/machines.md``)."""
_UPSTREAM = 6.0
_DOWNSTREAM = 5.0


def _nominal_isa(cv: float, xt: float) -> float:
    """Mass flow of the ISA valve at the nominal point [kg/s]."""
    return float(
        isa_mass_flow(bar_gauge_to_pa(_UPSTREAM), bar_gauge_to_pa(_DOWNSTREAM), cv, xt, T_ROOM)
    )


def cv_from_nominal_flow(nominal_flow_l_min_anr: float, xt: float = FESTO_SPOOL_XT) -> float:
    """Cv of the ISA valve (eq. 4.6) that passes a standard nominal flow ``qnN``.

    .. math:: C_v = \\frac{q_{nN}\\,\\rho_{ANR}}{\\dot m_{ISA}(7.013, 6.013\\ \\mathrm{bar},
              C_v = 1, x_T, 20\\,^{\\circ}\\mathrm{C})}

    Parameters
    ----------
    nominal_flow_l_min_anr : float
        Standard nominal flow, 6 -> 5 bar(g), 20 degC [l/min (ANR)], > 0.
    xt : float
        Pressure-drop ratio factor of the valve, 0.05-1 [-].

    Returns
    -------
    float
        Flow coefficient Cv [-].

    Examples
    --------
    A VUVG-L14 5/2 valve rated 560 l/min (``docs/machines.md``: 1050 l/min per Cv):

    >>> round(cv_from_nominal_flow(560.0), 4)
    0.5327
    """
    if not nominal_flow_l_min_anr > 0.0:
        raise InputError(describe("standard nominal flow", nominal_flow_l_min_anr, "> 0 l/min"))
    if not 0.05 <= xt <= 1.0:
        raise InputError(describe("xT", xt, "0.05 to 1"))
    return float(l_min_anr_to_kg_s(nominal_flow_l_min_anr)) / _nominal_isa(1.0, xt)


def nominal_flow_from_sonic_conductance(c_dm3_s_bar: float, b: float) -> float:
    """Standard nominal flow (6 -> 5 bar(g), 20 degC) of an ISO 6358 valve [l/min (ANR)].

    Parameters
    ----------
    c_dm3_s_bar : float
        Sonic conductance C as catalogues print it [dm^3/(s bar)], > 0.
    b : float
        Critical pressure ratio, 0-0.95 [-].

    Returns
    -------
    float
        Flow at the nominal point [l/min (ANR)].

    Examples
    --------
    SMC's SY3000 (C 1.1, b 0.28; CAT.EUS11-83B states Q = 276 l/min (ANR)):

    >>> round(nominal_flow_from_sonic_conductance(1.1, 0.28), 1)
    276.5
    """
    if not c_dm3_s_bar > 0.0:
        raise InputError(describe("sonic conductance C", c_dm3_s_bar, "> 0 dm^3/(s bar)"))
    if not 0.0 <= b <= 0.95:
        raise InputError(describe("critical pressure ratio b", b, "0 to 0.95"))
    mass = float(
        iso6358_mass_flow(
            bar_gauge_to_pa(_UPSTREAM),
            bar_gauge_to_pa(_DOWNSTREAM),
            sonic_conductance_from_catalogue(c_dm3_s_bar),
            b,
            T_ROOM,
        )
    )
    return mass / float(l_min_anr_to_kg_s(1.0))


def isa_from_sonic_conductance(c_dm3_s_bar: float, b: float) -> tuple[float, float]:
    """Cv and xT of the ISA valve equivalent to an ISO 6358 rating (module docstring).

    .. math:: x_T = 1 - b, \\qquad
              \\dot m_{ISA}(6 \\to 5\\ \\mathrm{bar(g)}; C_v, x_T)
              = \\dot m_{ISO\\,6358}(6 \\to 5\\ \\mathrm{bar(g)}; C, b)

    Parameters
    ----------
    c_dm3_s_bar : float
        Sonic conductance C [dm^3/(s bar)], > 0.
    b : float
        Critical pressure ratio, 0-0.95 [-].

    Returns
    -------
    (float, float)
        Cv [-] and xT [-].

    Examples
    --------
    >>> cv, xt = isa_from_sonic_conductance(1.1, 0.28)
    >>> round(cv, 4), xt
    (0.2667, 0.72)
    """
    xt = round(max(0.05, min(1.0, 1.0 - b)), 6)
    qn = nominal_flow_from_sonic_conductance(c_dm3_s_bar, b)
    return cv_from_nominal_flow(qn, xt), xt
