"""The catalogue tables shipped in the package (``pneufdd/catalogue/data/*.csv``).

Every row names its source (an id of ``sources.csv``: document, edition, where in it,
address, whether it was read) and its status (``verified``, ``standard value``,
``unverified``, ``assumption`` or ``not found``). ``docs/catalogue.md`` prints the
tables and explains the columns. Read once per process.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from functools import cache
from importlib import resources

from pneufdd.errors import InputError, describe

__all__ = [
    "Family",
    "PortRow",
    "SizeRow",
    "Source",
    "ValveRow",
    "families",
    "ports",
    "sizes",
    "sources",
    "valve_rows",
]


@dataclass(frozen=True)
class Source:
    """One document a row cites."""

    id: str
    document: str
    edition: str
    where: str
    url: str
    consulted: str

    def short(self) -> str:
        """The document and where in it, in one line."""
        edition = f", {self.edition}" if self.edition else ""
        return f"{self.document}{edition}: {self.where}"


@dataclass(frozen=True)
class Family:
    """An actuator family: its kind, standard, code form and the assumed rules."""

    family: str
    maker: str
    kind: str
    standard: str
    form: str
    friction_n_per_mm2: float
    coulomb_ratio: float
    viscous_n_s_m_per_mm2: float
    dead_length_mm: float
    rules_source: str


@dataclass(frozen=True)
class SizeRow:
    """One size of an actuator family."""

    family: str
    size: str
    bore_mm: float
    rod_mm: float
    pistons: int
    stroke_mm: float | None
    lever_mm: float | None
    port: str
    source: str
    status: str


@dataclass(frozen=True)
class ValveRow:
    """One valve (family, size, function) and its flow rating."""

    family: str
    size: str
    function: str
    kind: str
    nominal_flow_l_min_anr: float | None
    sonic_conductance_dm3_s_bar: float | None
    critical_ratio_b: float | None
    xt: float | None
    port: str
    source: str
    status: str


@dataclass(frozen=True)
class PortRow:
    """The tube a port thread takes."""

    port: str
    tube: str
    tube_inner_diameter_mm: float
    source: str
    status: str


def _rows(name: str) -> list[dict[str, str]]:
    text = resources.files("pneufdd.catalogue").joinpath("data", name).read_text("utf-8")
    return list(csv.DictReader(io.StringIO(text)))


def _opt(text: str) -> float | None:
    return float(text) if text.strip() else None


@cache
def sources() -> dict[str, Source]:
    """Every source by its id."""
    return {r["id"]: Source(**r) for r in _rows("sources.csv")}


@cache
def families() -> dict[str, Family]:
    """Every actuator family by its name."""
    out = {}
    for r in _rows("families.csv"):
        out[r["family"]] = Family(
            family=r["family"],
            maker=r["maker"],
            kind=r["kind"],
            standard=r["standard"],
            form=r["form"],
            friction_n_per_mm2=float(r["friction_n_per_mm2"]),
            coulomb_ratio=float(r["coulomb_ratio"]),
            viscous_n_s_m_per_mm2=float(r["viscous_n_s_m_per_mm2"]),
            dead_length_mm=float(r["dead_length_mm"]),
            rules_source=r["rules_source"],
        )
    return out


@cache
def sizes() -> dict[tuple[str, str], SizeRow]:
    """Every actuator size by (family, size)."""
    out = {}
    for r in _rows("actuator_sizes.csv"):
        row = SizeRow(
            family=r["family"],
            size=r["size"],
            bore_mm=float(r["bore_mm"]),
            rod_mm=float(r["rod_mm"]),
            pistons=int(r["pistons"]),
            stroke_mm=_opt(r["stroke_mm"]),
            lever_mm=_opt(r["lever_mm"]),
            port=r["port"],
            source=r["source"],
            status=r["status"],
        )
        out[row.family, row.size] = row
    return out


@cache
def valve_rows() -> dict[tuple[str, str, str], ValveRow]:
    """Every valve by (family, size, function)."""
    out = {}
    for r in _rows("valves.csv"):
        row = ValveRow(
            family=r["family"],
            size=r["size"],
            function=r["function"],
            kind=r["kind"],
            nominal_flow_l_min_anr=_opt(r["nominal_flow_l_min_anr"]),
            sonic_conductance_dm3_s_bar=_opt(r["sonic_conductance_dm3_s_bar"]),
            critical_ratio_b=_opt(r["critical_ratio_b"]),
            xt=_opt(r["xt"]),
            port=r["port"],
            source=r["source"],
            status=r["status"],
        )
        out[row.family, row.size, row.function] = row
    return out


@cache
def ports() -> dict[str, PortRow]:
    """The tube of every port thread."""
    return {
        r["port"]: PortRow(
            r["port"], r["tube"], float(r["tube_inner_diameter_mm"]), r["source"], r["status"]
        )
        for r in _rows("ports.csv")
    }


def source(ident: str) -> Source:
    """The source ``ident`` (an error names the ids known: a table cites a missing one)."""
    known = sources()
    if ident not in known:  # pragma: no cover - tests/test_catalogue.py checks every row
        raise InputError(describe("catalogue source id", ident, sorted(known)))
    return known[ident]
