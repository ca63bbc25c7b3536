"""Tag maps: a plant's own column/channel names (PLC tags) -> pneufdd channel roles.

A DAQ or PLC export names its columns after the PLC's tags (``Y1.0``, ``B1.4``,
``DB10.X3.1``). A tag map (a small TOML file, ``docs/recording.md``) says which role
each column plays, in which unit and, for a flow, on which standard basis::

    [columns]
    "t"      = { role = "time", unit = "s" }
    "B_P1"   = { role = "P_In", unit = "bar(g)" }
    "B_F1"   = { role = "Q_In", unit = "l/min", basis = "ANR" }
    "Y1.0"   = { role = "U_FEED_A" }
    "B1.4"   = { role = "S_FEED_B" }

Optional top-level keys: ``ignore`` (columns present in the file but not used),
``rate_hz`` (the expected sample rate; a file at another rate is refused), and the
layout of a field export (``preset``, ``delimiter``, ``decimal``, ``skip_rows``,
``data_skip``, ``true_values``, ``false_values``, ``timezone``, ``start_time``; time
columns in s, ms, us or as date-times, several of them:
:mod:`pneufdd.recording.csv_layout`). :func:`read_mapped` reads a CSV, TDMS or Parquet
file with a map; every command that reads recordings takes ``--map``.

The same file serves live sources (``pneufdd monitor --tags``, ``docs/monitor.md``):
each column may add ``node`` (OPC UA node id; default ``ns=2;s=<column>``) and
``rate_hz`` (grid rate [Hz]), the top level ``lateness_s`` [s] and ``end`` (a tag that
ends the stream). Only for live sources (``load_tag_map(path, live=True)``), a map may
instead name pneufdd's channels directly, values in SI units::

    [channels.P_In]
    node = "ns=2;s=P_In"
    rate_hz = 20

This module is the one reader of tag-map files; the monitor builds its
:class:`~pneufdd.monitor.sources.ChannelTags` from the :class:`TagMap` read here.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pneufdd.errors import ChannelError, FileFormatError, InputError, UnitError, describe
from pneufdd.limits import MAX_RATE_HZ, read_text_capped
from pneufdd.physics.units import UNITS
from pneufdd.recording._files import check_input_file, file_label
from pneufdd.recording.csv_layout import (
    LAYOUT_KEYS,
    CsvLayout,
    TimeSpec,
    parse_layout,
    parse_time_spec,
)
from pneufdd.recording.derived import (
    FLOW_DIRECTIONS,
    SwitchSpec,
    combine_flow_parts,
    derive_switches,
    flow_part_role,
    parse_switches,
)
from pneufdd.recording.model import DIGITAL, Channel, Recording

__all__ = [
    "FLOW_BASES",
    "MIN_RATE_HZ",
    "ROLE_PATTERN",
    "ColumnRole",
    "LiveTag",
    "TagMap",
    "load_tag_map",
    "parse_tag_map",
    "read_mapped",
]

ROLE_PATTERN = re.compile(
    r"^(time|P_In|Q_In|[US]_[A-Z][A-Z0-9_]*|[PQ]_[A-Z][A-Z0-9_]*_[AB]|X_[A-Z][A-Z0-9_]*)$"
)
"""Allowed roles: ``time``, ``P_In``, ``Q_In``, ``U_<ACT>_A/B``, ``S_<ACT>_A/B``,
``U_<VAC>``, ``S_<VAC>``, line sensors ``P_<ACT>_A/B``, ``Q_<ACT>_A/B`` and a position
``X_<ACT>`` (channel codes of Fig. 3.16)."""

FLOW_BASES: dict[str, str] = {
    "ANR": "l/min (ANR)",
    "SLPM": "SLPM",
}
"""Flow basis -> the :data:`~pneufdd.physics.units.UNITS` key of litres per minute on it:
``ANR`` = ISO 8778 (20 degC, 100 kPa), ``SLPM`` = 0 degC, 1013 mbar."""

_LITRES_PER_MINUTE = ("l/min", "lpm", "L/min", "Nl/min")
_QUANTITY = {"P": "pressure", "Q": "mass flow", "X": "length"}

MIN_RATE_HZ = 50.0
"""Slowest sample rate accepted: steps must be timed to a few tens of ms [Hz]."""


@dataclass(frozen=True)
class ColumnRole:
    """What one column of the file is: its role (channel name) and its unit."""

    column: str
    role: str
    unit: str  # a UNITS key ("1" for digital channels, "s" for time)

    @property
    def digital(self) -> bool:
        """Valve solenoids ``U_*`` and switches ``S_*`` are 0/1."""
        return self.role[:2] in ("U_", "S_")


@dataclass(frozen=True)
class LiveTag:
    """How a live source (``pneufdd monitor --tags``) receives one channel.

    Attributes
    ----------
    channel : str
        The pneufdd channel (the column's role).
    tag : str
        The name a stream gives it: the PLC tag (the column), or the channel itself in
        the ``[channels]`` form.
    node : str or None
        OPC UA node id; None: ``ns=2;s=<tag>``.
    rate_hz : float or None
        Grid rate [Hz]; None: the monitor's default.
    unit : str or None
        Unit of the live values (a :data:`~pneufdd.physics.units.UNITS` key); None:
        already SI (the ``[channels]`` form).
    """

    channel: str
    tag: str
    node: str | None = None
    rate_hz: float | None = None
    unit: str | None = None


@dataclass(frozen=True)
class TagMap:
    """A parsed, validated tag map.

    ``columns`` is empty only for the live-only ``[channels]`` form; ``live``,
    ``lateness_s`` and ``end`` are what live sources need (file readers ignore them).
    """

    columns: tuple[ColumnRole, ...]
    ignore: tuple[str, ...] = ()
    rate_hz: float | None = None
    delimiter: str = ","
    decimal: str = "."
    source: str = "<map>"
    live: tuple[LiveTag, ...] = ()
    lateness_s: float = 1.0
    end: str | None = None
    layout: CsvLayout = field(default_factory=lambda: CsvLayout(times={"time": TimeSpec()}))
    switches: tuple[SwitchSpec, ...] = ()

    @property
    def time_column(self) -> str | None:
        """The column with the role ``time`` (CSV), or None."""
        for c in self.columns:
            if c.role == "time":
                return c.column
        return None

    @property
    def channels(self) -> tuple[ColumnRole, ...]:
        """Every role except ``time``."""
        return tuple(c for c in self.columns if c.role != "time")


def _unit(source: str, column: str, role: str, entry: Mapping[str, Any]) -> str:
    where = f"{source}: columns.{column!r}"
    unit = entry.get("unit")
    basis = entry.get("basis")
    if role == "time":  # s, ms, us or datetime: checked by parse_time_spec
        return "s"
    if role[:2] in ("U_", "S_"):
        if unit not in (None, "1"):
            raise UnitError(describe(f"{where}.unit (digital 0/1 role {role})", unit, ["1"]))
        if basis is not None:
            raise InputError(describe(f"{where}.basis (digital role {role})", basis, "no basis"))
        return "1"
    quantity = _QUANTITY[role[0]]
    if not isinstance(unit, str):
        allowed = sorted(k for k, s in UNITS.items() if s.quantity == quantity)
        raise UnitError(describe(f"{where}.unit (role {role}, a {quantity})", unit, allowed))
    if quantity == "mass flow":
        if basis is not None and (not isinstance(basis, str) or basis not in FLOW_BASES):
            raise UnitError(describe(f"{where}.basis", basis, sorted(FLOW_BASES)))
        if unit in _LITRES_PER_MINUTE:
            if basis is None:
                raise UnitError(
                    describe(
                        f"{where}.basis (unit {unit!r} needs the standard its litres are on)",
                        None,
                        sorted(FLOW_BASES),
                    )
                )
            unit = FLOW_BASES[basis]
        elif basis is not None and unit in FLOW_BASES.values() and unit != FLOW_BASES[basis]:
            raise UnitError(
                describe(f"{where}: unit {unit!r} with basis", basis, [unit.split()[0]])
            )
    spec = UNITS.get(unit)
    if spec is None or spec.quantity != quantity:
        allowed = sorted(k for k, s in UNITS.items() if s.quantity == quantity)
        if quantity == "mass flow":
            allowed += [f"{u} (with basis)" for u in _LITRES_PER_MINUTE[:1]]
        raise UnitError(describe(f"{where}.unit (role {role}, a {quantity})", unit, allowed))
    return unit


_LIVE_KEYS = ("node", "rate_hz")
_LAYOUT_COLUMN_KEYS = ("format", "timezone", "time")
_COLUMN_KEYS = ("role", "unit", "basis", "direction", *_LIVE_KEYS, *_LAYOUT_COLUMN_KEYS)


def _node(where: str, entry: Mapping[str, Any]) -> str | None:
    node = entry.get("node")
    if node is not None and not isinstance(node, str):
        raise InputError(describe(f"{where}.node", node, "an OPC UA node id, e.g. 'ns=2;s=B_P1'"))
    return node


def _grid_rate(where: str, entry: Mapping[str, Any]) -> float | None:
    rate = entry.get("rate_hz")
    if rate is None:
        return None
    if (
        isinstance(rate, bool)
        or not isinstance(rate, int | float)
        or not (math.isfinite(rate) and 0.1 <= rate <= MAX_RATE_HZ)
    ):
        raise InputError(
            describe(f"{where}.rate_hz", rate, f"a grid rate from 0.1 to {MAX_RATE_HZ:g} Hz")
        )
    return float(rate)


def _live_options(data: Mapping[str, Any], source: str) -> tuple[float, str | None]:
    """``lateness_s`` [s] (default 1) and ``end`` (an end tag, or None) of a map."""
    lateness = data.get("lateness_s", 1.0)
    if (
        isinstance(lateness, bool)
        or not isinstance(lateness, int | float)
        or not (math.isfinite(lateness) and 0 <= lateness <= 3600)
    ):
        raise InputError(describe(f"{source}: lateness_s", lateness, "0 to 3600 [s]"))
    end = data.get("end")
    if end is not None and not isinstance(end, str):
        raise InputError(describe(f"{source}: end", end, "the node id of a boolean tag"))
    return float(lateness), end


def _parse_channel_form(data: Mapping[str, Any], source: str) -> TagMap:
    """The live-only form: ``[channels.<channel>]`` with ``node``/``rate_hz``, SI values."""
    known = {"channels", "lateness_s", "end"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(describe(f"{source}: unknown top-level key", unknown[0], sorted(known)))
    table = data.get("channels", {})
    if not isinstance(table, Mapping):
        raise InputError(describe(f"{source}: [channels]", table, "a table per channel"))
    live = []
    for name, entry in table.items():
        where = f"{source}: channels.{name!r}"
        if not isinstance(entry, Mapping):
            raise InputError(describe(where, entry, "a table { node = ..., rate_hz = ... }"))
        extra = sorted(set(entry) - set(_LIVE_KEYS))
        if extra:
            raise InputError(describe(f"{where}: unknown key", extra[0], list(_LIVE_KEYS)))
        live.append(LiveTag(str(name), str(name), _node(where, entry), _grid_rate(where, entry)))
    lateness, end = _live_options(data, source)
    return TagMap(columns=(), source=source, live=tuple(live), lateness_s=lateness, end=end)


def _column_layout(
    where: str, column: str, role: str, entry: Mapping[str, Any], layout: dict[str, Any]
) -> None:
    """Collect a column's time spec (role ``time``) or its ``time`` column (a channel)."""
    if role == "time":
        if "time" in entry:
            raise InputError(describe(f"{where}.time (a time column)", entry["time"], "none"))
        layout["times"][column] = parse_time_spec(where, entry)
        return
    for key in ("format", "timezone"):
        if key in entry:
            raise InputError(
                describe(f"{where}.{key} (role {role})", entry[key], "time columns only")
            )
    time = entry.get("time")
    if time is not None:
        if not isinstance(time, str):
            raise InputError(describe(f"{where}.time", time, "the name of a time column"))
        layout["channel_time"][column] = time


def parse_tag_map(
    data: Mapping[str, Any],
    source: str = "<map>",
    *,
    live: bool = False,
    preset: str | None = None,
) -> TagMap:
    """Validate a parsed tag-map TOML document.

    Parameters
    ----------
    data : mapping
        The parsed TOML document.
    source : str
        The map's name in messages (its file name).
    live : bool
        For a live source (``pneufdd monitor --tags``): the ``[channels]`` form is
        allowed too (module docstring).
    preset : str, optional
        A named export layout (``--format``, :data:`~pneufdd.recording.csv_layout.PRESETS`);
        wins over the map's ``preset``.

    Raises
    ------
    InputError
        Naming the map, the column and what is allowed: an unknown key, a role that is
        not a channel code, a role given twice, a unit that does not fit the role or is
        unknown, a flow in litres without its basis, a grid rate that is not > 0, a map
        with both ``[channels]`` and ``[columns]``.

    Examples
    --------
    >>> m = parse_tag_map({"columns": {"t": {"role": "time", "unit": "s"},
    ...     "B_F1": {"role": "Q_In", "unit": "l/min", "basis": "ANR"},
    ...     "Y1.0": {"role": "U_FEED_A"}}})
    >>> [(c.column, c.role, c.unit) for c in m.channels]
    [('B_F1', 'Q_In', 'l/min (ANR)'), ('Y1.0', 'U_FEED_A', '1')]
    """
    if live and "columns" not in data:
        return _parse_channel_form(data, source)
    if live and "channels" in data:
        raise InputError(
            describe(
                f"{source}: tag-map form",
                "both [channels] and [columns]",
                "one form: [columns] keyed by PLC tag, or [channels] keyed by channel",
            )
        )
    known = {"columns", "ignore", "rate_hz", "lateness_s", "end", "switches", *LAYOUT_KEYS}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(describe(f"{source}: unknown top-level key", unknown[0], sorted(known)))
    table = data.get("columns")
    if not isinstance(table, Mapping) or not table:
        raise InputError(
            describe(f"{source}: [columns]", table, 'a table: "<column>" = { role = ... }')
        )
    roles: list[ColumnRole] = []
    live_tags: list[LiveTag] = []
    seen: dict[str, str] = {}
    layout_parts: dict[str, Any] = {"times": {}, "channel_time": {}}
    for column, entry in table.items():
        where = f"{source}: columns.{column!r}"
        if isinstance(entry, str):  # shorthand: "Y1.0" = "U_FEED_A"
            entry = {"role": entry}
        if not isinstance(entry, Mapping):
            raise InputError(describe(where, entry, "{ role = ..., unit = ..., basis = ... }"))
        extra = sorted(set(entry) - set(_COLUMN_KEYS))
        if extra:
            raise InputError(describe(f"{where}: unknown key", extra[0], list(_COLUMN_KEYS)))
        role = entry.get("role")
        if not isinstance(role, str) or not ROLE_PATTERN.fullmatch(role):
            raise InputError(
                describe(
                    f"{where}.role",
                    role,
                    "time, P_In, Q_In, U_<ACT>_A/B, S_<ACT>_A/B, U_<VAC>, S_<VAC>, "
                    "P_<ACT>_A/B, Q_<ACT>_A/B, X_<ACT> (ACT: upper-case letters, digits, _)",
                )
            )
        role = _flow_part(where, role, entry, live)
        if role in seen and role != "time":  # several time columns: one per sample time
            raise ChannelError(
                describe(
                    f"{source}: role {role!r} is given to columns {seen[role]!r} and {column!r}",
                    role,
                    "each role once",
                )
            )
        seen[role] = str(column)
        roles.append(ColumnRole(str(column), role, _unit(source, str(column), role, entry)))
        _column_layout(where, str(column), role, entry, layout_parts)
        node, rate = _node(where, entry), _grid_rate(where, entry)
        if role != "time":
            live_tags.append(LiveTag(role, str(column), node, rate, roles[-1].unit))
    if not any(r.role.startswith("U_") for r in roles):
        raise ChannelError(
            describe(
                f"{source}: valve solenoid roles",
                [],
                "at least one U_<ACT>_A/B (steps start at valve firings)",
            )
        )
    ignore = data.get("ignore", [])
    if not isinstance(ignore, list) or not all(isinstance(x, str) for x in ignore):
        raise InputError(describe(f"{source}: ignore", ignore, "a list of column names"))
    rate = data.get("rate_hz")
    if rate is not None and (
        isinstance(rate, bool)
        or not isinstance(rate, int | float)
        or not MIN_RATE_HZ <= rate <= MAX_RATE_HZ
    ):
        raise InputError(
            describe(f"{source}: rate_hz", rate, f"{MIN_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz")
        )
    _check_flow_parts(source, seen)
    layout = parse_layout(data, source, layout_parts["times"], layout_parts["channel_time"], preset)
    switches = parse_switches(
        data.get("switches", {}),
        source,
        {r.role: r.unit for r in roles if r.role.startswith("X_")},
        set(seen),
    )
    lateness, end = _live_options(data, source)
    return TagMap(
        columns=tuple(roles),
        ignore=tuple(ignore),
        rate_hz=None if rate is None else float(rate),
        delimiter=layout.delimiter,
        decimal=layout.decimal,
        source=source,
        live=tuple(live_tags),
        lateness_s=lateness,
        end=end,
        layout=layout,
        switches=switches,
    )


def _flow_part(where: str, role: str, entry: Mapping[str, Any], live: bool) -> str:
    """The role a column is read under: ``<role>.in``/``.out`` for one flow direction."""
    direction = entry.get("direction")
    if direction is None:
        return role
    if direction not in FLOW_DIRECTIONS or not role.startswith("Q_") or live:
        raise InputError(
            describe(
                f"{where}.direction (role {role})",
                direction,
                "'in' or 'out' on a flow role (Q_...), in a map read from files",
            )
        )
    return flow_part_role(role, str(direction))


def _check_flow_parts(source: str, seen: Mapping[str, str]) -> None:
    """A flow given both whole and by direction is refused."""
    for role in seen:
        base, dot, direction = role.rpartition(".")
        if dot and direction in FLOW_DIRECTIONS and base in seen:
            raise ChannelError(
                describe(
                    f"{source}: role {base!r} is given to column {seen[base]!r} and, by "
                    f"direction, to {seen[role]!r}",
                    base,
                    "one signed column, or an in and an out column",
                )
            )


def load_tag_map(path: str | Path, *, live: bool = False, preset: str | None = None) -> TagMap:
    """Read and validate a tag-map TOML file (see :func:`parse_tag_map`).

    ``live=True`` (``pneufdd monitor --tags``) also allows the ``[channels]`` form, and
    an empty file (every channel at the monitor's defaults); ``preset`` names an export
    layout (``pneufdd import --format``).
    """
    path = Path(path)
    if live and path.is_file() and path.stat().st_size == 0:
        return parse_tag_map({}, path.name, live=True)
    path = check_input_file(path, "a tag map (.toml)")
    text = read_text_capped(path, "tag map")  # a regular file of at most 4 MiB
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"{file_label(path)} is not valid TOML ({exc})") from exc
    except RecursionError as exc:
        raise FileFormatError(
            f"{file_label(path)} is nested too deep to read; expected a flat tag map"
        ) from exc
    return parse_tag_map(data, path.name, live=live, preset=preset)


def _check_unmapped(label: str, tag_map: TagMap, present: list[str]) -> None:
    mapped = {c.column for c in tag_map.columns} | set(tag_map.ignore)
    unmapped = [c for c in present if c not in mapped]
    if unmapped:
        raise ChannelError(
            describe(
                f"{label}: column(s) the tag map {tag_map.source} does not map",
                unmapped,
                "a role for each (or list them under ignore = [...] in the map)",
            )
        )


def _check_rates(label: str, tag_map: TagMap, recording: Recording) -> None:
    for name in recording.channels:
        rate = recording.rate(name)
        if not MIN_RATE_HZ <= rate <= MAX_RATE_HZ:  # the rates every command accepts
            raise InputError(
                describe(
                    f"{label}: sample rate of channel {name!r}",
                    f"{rate:g} Hz",
                    f"{MIN_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz (steps are timed to tens of ms; "
                    "docs/limits.md)",
                )
            )
        if tag_map.rate_hz is not None and abs(rate - tag_map.rate_hz) > 1e-3 * tag_map.rate_hz:
            raise InputError(
                describe(
                    f"{label}: sample rate of channel {name!r} (rate_hz of {tag_map.source})",
                    f"{rate:g} Hz",
                    f"{tag_map.rate_hz:g} Hz",
                )
            )


def _csv_header(path: Path, tag_map: TagMap) -> list[str]:
    import csv

    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            row = next(csv.reader(handle, delimiter=tag_map.delimiter, skipinitialspace=True), [])
    except (UnicodeDecodeError, csv.Error) as exc:
        raise FileFormatError(
            f"{file_label(path)} is not a UTF-8 CSV file ({exc}); expected a CSV export "
            f"with the columns of {tag_map.source}"
        ) from exc
    return [c for c in row if c]


def read_mapped(path: str | Path, tag_map: TagMap) -> Recording:
    """Read a CSV, TDMS or Parquet file whose columns the tag map names.

    Parameters
    ----------
    path : str or Path
        A ``.csv`` (one time column, every channel on it), ``.tdms`` (channels by name
        or ``group/channel``) or ``.parquet`` file (channels renamed).
    tag_map : TagMap
        From :func:`load_tag_map`.

    Returns
    -------
    Recording
        Channels under their roles, SI units; ``metadata["source"]["tag_map"]`` names
        the map.

    Raises
    ------
    ChannelError
        A column the map names is not in the file; a column of the file the map neither
        maps nor ignores; digital values other than 0/1.
    InputError
        A sample rate below :data:`MIN_RATE_HZ` or other than the map's ``rate_hz``; a CSV
        map without a ``time`` role.
    """
    from pneufdd.recording.io import SUFFIXES

    path = Path(path)
    label = file_label(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise FileFormatError(describe(f"{label}: file suffix", path.suffix, SUFFIXES))
    check_input_file(path, f"a {suffix} file")
    if not tag_map.columns:
        raise InputError(
            describe(
                f"{tag_map.source}: [columns] (needed to read {label})",
                None,
                "a [columns] table; the [channels] form serves only live sources",
            )
        )
    channel_map = {c.column: c.role for c in tag_map.channels}
    units = {c.role: c.unit for c in tag_map.channels if not c.digital}
    digital = [c.role for c in tag_map.channels if c.digital]
    meta = {"source": {"file": path.name, "tag_map": tag_map.source, "format": suffix[1:]}}
    if suffix == ".csv" and not tag_map.layout.plain:
        from pneufdd.recording.field_csv import read_field_csv

        rec = read_field_csv(path, tag_map, meta)
    elif suffix == ".csv":
        from pneufdd.recording.csv import read_csv

        time_column = tag_map.time_column
        if time_column is None:
            raise InputError(
                describe(
                    f"{tag_map.source}: the role 'time' (needed for {label})",
                    None,
                    'one column with { role = "time", unit = "s" }',
                )
            )
        header = _csv_header(path, tag_map)
        present = set(header)
        missing = [c.column for c in tag_map.columns if c.column not in present]
        if missing:
            raise ChannelError(
                describe(f"{label}: column(s) of the tag map not in the file", missing, header)
            )
        _check_unmapped(label, tag_map, header)
        rec = read_csv(
            path,
            channel_map,
            units,
            time_column=time_column,
            digital=digital,
            metadata=meta,
            delimiter=tag_map.delimiter,
            decimal=tag_map.decimal,
        )
    elif suffix == ".tdms":
        from pneufdd.recording.tdms import read_tdms

        rec = read_tdms(path, channel_map, units, digital, metadata=meta)
    else:
        from pneufdd.recording.parquet import read_parquet

        stored = read_parquet(path)
        _check_unmapped(label, tag_map, list(stored.channels))
        missing = [c for c in channel_map if c not in stored.channels]
        if missing:
            raise ChannelError(
                describe(f"{label}: column(s) of the map not in the file", missing, stored.channels)
            )
        channels = []
        for column, role in channel_map.items():
            info = stored.info(column)
            values = info.values
            if role in digital and info.kind != DIGITAL:
                bad = np.flatnonzero((values != 0) & (values != 1))
                if bad.size:
                    raise ChannelError(
                        describe(
                            f"{label}: digital role {role} (column {column!r})",
                            values[bad[0]],
                            "0 or 1",
                        )
                    )
                values = values.astype(np.uint8)
            kind = DIGITAL if role in digital else info.kind
            unit = "1" if kind == DIGITAL else info.unit
            channels.append(Channel(role, values, info.rate_hz, unit, kind, info.t0))
        rec = Recording(
            channels, start_time=stored.start_time, metadata={**stored.metadata, **meta}
        )
    rec = combine_flow_parts(rec, label)
    rec = derive_switches(rec, tag_map.switches, label)
    _check_rates(label, tag_map, rec)
    return rec
