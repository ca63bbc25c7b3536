"""The catalogue tables shipped in the package (``pneufdd/catalogue/data/*.csv``).

Every row names its source (an id of ``sources.csv``: document, edition, where in it,
address, whether it was read) and its status (``verified``, ``standard value``,
``unverified``, ``assumption`` or ``not found``). ``docs/catalogue.md`` prints the
tables and explains the columns. Read once per process.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from dataclasses import dataclass, fields
from functools import cache
from importlib import resources
from typing import Any, TypeVar

from pneufdd.errors import InputError, describe

T = TypeVar("T")

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


_CONVERT: dict[str, Callable[[str], Any]] = {
    "str": str,
    "int": int,
    "float": float,
    "float | None": lambda text: float(text) if text.strip() else None,
}
"""How a CSV cell becomes a field of its annotated type (empty: None where allowed)."""


def _load(cls: type[T], name: str) -> list[T]:
    """Every row of the table ``name`` as a ``cls``, each cell by its field's type."""
    kinds = {f.name: _CONVERT[str(f.type)] for f in fields(cls)}  # type: ignore[arg-type]
    return [cls(**{k: kinds[k](v) for k, v in r.items()}) for r in _rows(name)]


@cache
def sources() -> dict[str, Source]:
    """Every source by its id."""
    return {row.id: row for row in _load(Source, "sources.csv")}


@cache
def families() -> dict[str, Family]:
    """Every actuator family by its name."""
    return {row.family: row for row in _load(Family, "families.csv")}


@cache
def sizes() -> dict[tuple[str, str], SizeRow]:
    """Every actuator size by (family, size)."""
    return {(row.family, row.size): row for row in _load(SizeRow, "actuator_sizes.csv")}


@cache
def valve_rows() -> dict[tuple[str, str, str], ValveRow]:
    """Every valve by (family, size, function)."""
    rows = _load(ValveRow, "valves.csv")
    return {(row.family, row.size, row.function): row for row in rows}


@cache
def ports() -> dict[str, PortRow]:
    """The tube of every port thread."""
    return {row.port: row for row in _load(PortRow, "ports.csv")}


def source(ident: str) -> Source:
    """The source ``ident`` (an error names the ids known: a table cites a missing one)."""
    known = sources()
    if ident not in known:  # pragma: no cover - tests/test_catalogue.py checks every row
        raise InputError(describe("catalogue source id", ident, sorted(known)))
    return known[ident]
