"""An order code -> the values a machine description takes from it, each with its source.

:func:`actuator_from_code` gives a cylinder's, drive's or gripper's geometry as the
twin's equivalent linear piston (eq. 4.11), and the values the code does not state
but the family's documented rules give (dead volumes, the tube its port takes, seal
friction by piston area). :func:`valve_from_code` gives a valve's kind and its Cv and
xT (:mod:`pneufdd.physics.valve_rating`). Every value comes with a note saying where
it came from (:meth:`CatalogueActuator.values`), which ``machine draft`` writes into
the TOML beside it.

Equivalent piston: a twin-piston drive (DRQD, SLT) of ``n`` pistons has the bore and
rod of one times ``sqrt(n)``; a through piston rod (``S2``, ``W``) has the annulus on
both sides, so the equivalent bore is ``sqrt(bore^2 - rod^2)`` and the rod 0; a
semi-rotary drive's stroke is its angle times its pinion radius (``angle_deg``,
``lever_mm``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

from pneufdd.catalogue.codes import ParsedCode, parse_actuator_code, parse_valve_code
from pneufdd.catalogue.tables import (
    Family,
    SizeRow,
    ValveRow,
    families,
    ports,
    sizes,
    source,
    valve_rows,
)
from pneufdd.errors import InputError, describe

__all__ = [
    "CatalogueActuator",
    "CatalogueValve",
    "actuator_from_code",
    "description_values",
    "valve_from_code",
    "valve_kind_from_code",
]


@dataclass(frozen=True)
class CatalogueActuator:
    """What an actuator's order code gives the description (see :meth:`values`)."""

    parsed: ParsedCode
    family: Family
    row: SizeRow
    bore_mm: float
    rod_mm: float
    stroke_mm: float
    angle_deg: float | None
    lever_mm: float | None
    dead_volume_cm3: float
    tube: str
    tube_inner_diameter_mm: float
    static_friction_n: float
    coulomb_friction_n: float
    viscous_friction_n_s_m: float

    @property
    def code(self) -> str:
        """The order code."""
        return self.parsed.code

    @property
    def kind(self) -> str:
        """The description's ``kind`` (``linear``, ``rotary``, ...)."""
        return self.family.kind

    @property
    def piston_area_mm2(self) -> float:
        """Area of the equivalent piston's blind side [mm^2]."""
        return math.pi / 4.0 * self.bore_mm**2

    def geometry_note(self) -> str:
        """Where the geometry came from: the code, and the row's source id and status
        (``docs/catalogue.md`` lists the sources)."""
        source(self.row.source)  # a row citing an unknown source is refused
        return f"from catalogue {self.code} [{self.row.source}: {_word(self.row.status)}]"

    def values(self) -> list[tuple[str, float | str, str]]:
        """``(key, value, note)`` of every description key the code sets (a new list).

        Geometry (kind, bore, rod, stroke or angle and lever) is the code's; dead
        volumes, tube bore and friction are the family's documented rules, marked
        ``assumed``.
        """
        geometry = self.geometry_note()
        rule = f"assumed by the {self.family.family} rule of {self.family.rules_source}"
        out: list[tuple[str, float | str, str]] = [
            ("kind", self.kind, f"from catalogue {self.code} ({self.family.standard})"),
            ("bore_mm", round(self.bore_mm, 3), geometry),
            ("rod_mm", round(self.rod_mm, 3), geometry),
        ]
        if self.angle_deg is not None and self.lever_mm is not None:
            out.append(("angle_deg", self.angle_deg, f"from catalogue {self.code}"))
            out.append(("lever_mm", self.lever_mm, geometry))
        else:
            stroke_note = (
                f"from catalogue {self.code}" if self.parsed.stroke_mm is not None else geometry
            )
            out.append(("stroke_mm", self.stroke_mm, stroke_note))
        dead = round(self.dead_volume_cm3, 3)
        dead_note = f"{rule}: {self.family.dead_length_mm:g} mm of bore"
        out += [("dead_volume_a_cm3", dead, dead_note), ("dead_volume_b_cm3", dead, dead_note)]
        port = ports()[self.row.port]
        out.append(
            (
                "tube_inner_diameter_mm",
                self.tube_inner_diameter_mm,
                f"assumed: {port.tube} for the {self.row.port} port of {self.code}",
            )
        )
        friction = f"{rule}: {self.family.friction_n_per_mm2:g} N/mm^2 of piston area"
        out += [
            ("static_friction_n", round(self.static_friction_n, 2), friction),
            ("coulomb_friction_n", round(self.coulomb_friction_n, 2), friction),
            ("viscous_friction_n_s_m", round(self.viscous_friction_n_s_m, 2), friction),
        ]
        return out


def _word(status: str) -> str:
    """A row's status in a word or two: the text before its explanation."""
    return status.split(" (")[0].split(":")[0]


def _row(parsed: ParsedCode) -> tuple[Family, SizeRow]:
    family = families()[parsed.family]
    table = sizes()
    if (parsed.family, parsed.size) not in table:
        known = sorted((s for f, s in table if f == parsed.family), key=float)
        raise InputError(
            describe(f"size of order code {parsed.code!r} ({parsed.family})", parsed.size, known)
        )
    return family, table[parsed.family, parsed.size]


@lru_cache(maxsize=256)
def actuator_from_code(code: str) -> CatalogueActuator:
    """The geometry and assumed values of an actuator from its order code.

    Parameters
    ----------
    code : str
        An order code of :data:`pneufdd.catalogue.codes.ACTUATOR_FORMS`.

    Returns
    -------
    CatalogueActuator

    Raises
    ------
    InputError
        For a code that does not parse, a size the family has not, or a gripper or
        drive whose table row lacks its stroke or pinion radius.

    Examples
    --------
    >>> a = actuator_from_code("DSBC-63-100-PPVA-N3")
    >>> a.bore_mm, a.rod_mm, a.stroke_mm, a.tube_inner_diameter_mm
    (63.0, 20.0, 100.0, 7.0)
    >>> round(a.dead_volume_cm3, 2), round(a.static_friction_n, 1)
    (12.47, 124.7)
    >>> d = actuator_from_code("DRQD-16-90")
    >>> round(d.bore_mm, 2), d.angle_deg, d.lever_mm
    (22.63, 90.0, 10.0)
    """
    parsed = parse_actuator_code(code)
    family, row = _row(parsed)
    bore = row.bore_mm * math.sqrt(row.pistons)
    rod = row.rod_mm * math.sqrt(row.pistons)
    if parsed.through_rod:  # the annulus on both sides
        bore, rod = math.sqrt(bore**2 - rod**2), 0.0
    angle = lever = None
    if parsed.angle_deg is not None:
        if row.lever_mm is None:  # pragma: no cover - every DRQD row has one
            raise InputError(describe(f"pinion radius of {parsed.code!r}", None, "a table value"))
        angle, lever = parsed.angle_deg, row.lever_mm
        stroke = math.radians(angle) * lever
    elif parsed.stroke_mm is not None:
        stroke = parsed.stroke_mm
    elif row.stroke_mm is not None:
        stroke = row.stroke_mm
    else:  # pragma: no cover - every gripper row has one
        raise InputError(describe(f"stroke of {parsed.code!r}", None, "a table value"))
    area = math.pi / 4.0 * bore**2
    static = family.friction_n_per_mm2 * area
    return CatalogueActuator(
        parsed=parsed,
        family=family,
        row=row,
        bore_mm=bore,
        rod_mm=rod,
        stroke_mm=stroke,
        angle_deg=angle,
        lever_mm=lever,
        dead_volume_cm3=area * family.dead_length_mm / 1e3,
        tube=ports()[row.port].tube,
        tube_inner_diameter_mm=ports()[row.port].tube_inner_diameter_mm,
        static_friction_n=static,
        coulomb_friction_n=family.coulomb_ratio * static,
        viscous_friction_n_s_m=family.viscous_n_s_m_per_mm2 * area,
    )


@dataclass(frozen=True)
class CatalogueValve:
    """What a valve's order code gives the description (see :meth:`values`)."""

    parsed: ParsedCode
    kind: str
    cv: float | None
    xt: float | None
    nominal_flow_l_min_anr: float | None
    port: str
    source_id: str
    status: str

    @property
    def code(self) -> str:
        """The order code."""
        return self.parsed.code

    def values(self) -> list[tuple[str, float | str, str]]:
        """``(key, value, note)`` of the valve keys the code sets: its kind, and Cv and
        xT where the table has its flow."""
        source(self.source_id)  # a row citing an unknown source is refused
        note = f"from catalogue {self.code} [{self.source_id}: {_word(self.status)}]"
        out: list[tuple[str, float | str, str]] = [
            ("kind", self.kind, f"from catalogue {self.code}")
        ]
        if self.cv is not None and self.xt is not None:
            flow = f"{self.nominal_flow_l_min_anr:.0f} l/min (ANR) at 6 -> 5 bar(g)"
            out.append(("cv", round(self.cv, 4), f"{note}, {flow}"))
            out.append(("xt", self.xt, note))
        return out


@lru_cache(maxsize=256)
def valve_from_code(code: str) -> CatalogueValve:
    """A directional valve's kind, Cv and xT from its order code.

    Parameters
    ----------
    code : str
        An order code of :data:`pneufdd.catalogue.codes.VALVE_FORMS`.

    Returns
    -------
    CatalogueValve
        ``cv`` and ``xt`` None where the table has no flow data for the valve.

    Raises
    ------
    InputError
        For a code that does not parse, or a size or function the table has not
        (a function the twin has no valve kind for: 5/3 exhausted or pressurised
        centre, 3/2 valves).

    Examples
    --------
    >>> v = valve_from_code("VUVG-L14-M52-MT-G18")
    >>> v.kind, round(v.cv, 3), v.xt
    ('5/2-monostable', 0.533, 0.9)
    >>> v = valve_from_code("SY5120-5LZD-01")
    >>> v.kind, round(v.cv, 3), v.xt
    ('5/2-monostable', 0.727, 0.63)
    """
    # the ratings need the flow laws (and so numba): imported only for a valve's Cv
    from pneufdd.physics.valve_rating import (
        cv_from_nominal_flow,
        isa_from_sonic_conductance,
        nominal_flow_from_sonic_conductance,
    )

    parsed, row = _valve_row(code)
    cv = xt = flow = None
    if row.nominal_flow_l_min_anr is not None:
        xt = row.xt if row.xt is not None else 0.9
        flow = row.nominal_flow_l_min_anr
        cv = cv_from_nominal_flow(flow, xt)
    elif row.sonic_conductance_dm3_s_bar is not None and row.critical_ratio_b is not None:
        cv, xt = isa_from_sonic_conductance(row.sonic_conductance_dm3_s_bar, row.critical_ratio_b)
        flow = nominal_flow_from_sonic_conductance(
            row.sonic_conductance_dm3_s_bar, row.critical_ratio_b
        )
    return CatalogueValve(parsed, row.kind, cv, xt, flow, row.port, row.source, row.status)


def _valve_row(code: str) -> tuple[ParsedCode, ValveRow]:
    """The parsed code and the table row of a valve's order code."""
    parsed = parse_valve_code(code)
    table = valve_rows()
    key = (parsed.family, parsed.size, parsed.function)
    if key not in table:
        same = sorted({f"{s}-{fn}" for f, s, fn in table if f == parsed.family})
        raise InputError(
            describe(
                f"size and function of valve order code {parsed.code!r}",
                f"{parsed.size}-{parsed.function}",
                same,
            )
            + "; the twin's valves are 5/2 monostable, 5/2 bistable and 5/3 closed centre"
        )
    return parsed, table[key]


def valve_kind_from_code(code: str) -> str:
    """A directional valve's kind from its order code, without its flow rating.

    Examples
    --------
    >>> valve_kind_from_code("VUVG-L14-B52-T-G18")
    '5/2-bistable'
    """
    return _valve_row(code)[1].kind


@lru_cache(maxsize=512)
def description_values(code: str, part: str) -> tuple[tuple[str, float | str], ...]:
    """The description keys an order code sets and their values (notes left out).

    ``part`` is ``"actuator"`` or ``"valve"``. Cached: a machine description with
    codes is parsed for every twin run of a calibration or a diagnosis's check.

    Examples
    --------
    >>> dict(description_values("VUVG-L10-M52-T-M5", "valve"))["kind"]
    '5/2-monostable'
    """
    found = actuator_from_code(code) if part == "actuator" else valve_from_code(code)
    return tuple((key, value) for key, value, _ in found.values())
