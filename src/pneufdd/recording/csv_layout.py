"""How a field export lays out its CSV: the tag-map options and the named presets.

A PLC or DAQ tool writes its CSV its own way: a preamble or metadata block before the
header row, ``;`` and a decimal comma, ``TRUE``/``FALSE`` for bits, time in ms or as a
local date-time, one time column per sample time. The tag map (``docs/recording.md``)
describes that layout with a few top-level options, validated here::

    preset = "twincat-scope"   # or tia-trace, codesys-trace, csv-de (= --format)
    delimiter = ";"            # field separator
    decimal = ","              # decimal mark
    skip_rows = "auto"         # rows before the header row, or "auto" (detected)
    data_skip = "auto"         # rows between the header and the data, or "auto"
    true_values = ["TRUE"]     # texts read as 1 in digital columns (0/1 always work)
    false_values = ["FALSE"]
    timezone = "Europe/Berlin" # of date-times in the file without an offset
    start_time = 2026-11-27T14:03:05.123+01:00   # optional: the export's start

and, per time column (role ``time``, several allowed), ``unit`` = ``s``, ``ms``,
``us`` or ``datetime`` (with ``format``, a :func:`datetime.strptime` format, and an
optional ``timezone``); each channel may name its time column with ``time``.

A preset (:data:`PRESETS`) gives defaults for these options and the implicit time
column of a tool's layout, so the user's map holds only the roles; the map's own
options override the preset's.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from datetime import datetime
from typing import Any
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from pneufdd.errors import InputError, UnitError, describe

__all__ = [
    "LAYOUT_KEYS",
    "PRESETS",
    "TIME_UNITS",
    "CsvLayout",
    "Preset",
    "TimeSpec",
    "parse_layout",
    "parse_time_spec",
]

TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
"""Numeric time units of a time column -> seconds per unit; ``datetime`` is the other."""

LAYOUT_KEYS = (
    "preset",
    "delimiter",
    "decimal",
    "skip_rows",
    "data_skip",
    "true_values",
    "false_values",
    "timezone",
    "start_time",
)
"""Top-level tag-map keys that describe a CSV export's layout."""

MAX_SKIP_ROWS = 100_000
"""Most rows a preamble (or the rows between header and data) may have."""


@dataclass(frozen=True)
class TimeSpec:
    """How one time column is written.

    Attributes
    ----------
    unit : str
        ``s``, ``ms``, ``us`` (a number of those since some origin) or ``datetime``.
    format : str or None
        :func:`datetime.strptime` format of a ``datetime`` column; None: ISO 8601.
    timezone : str or None
        IANA zone of date-times without an offset; None: the map's, else UTC.
    """

    unit: str = "s"
    format: str | None = None
    timezone: str | None = None

    @property
    def seconds_per_unit(self) -> float:
        """Seconds per unit of a numeric time column [s]."""
        return TIME_UNITS[self.unit]


@dataclass(frozen=True)
class Preset:
    """Defaults of one export tool's CSV layout (``pneufdd import --format NAME``).

    ``time_header``: the header of the time column(s) when the map names none (every
    column so headed is one; None: the first column); ``start_key``: the preamble
    row that holds the export's start (its first cell, case-insensitive).
    """

    name: str
    delimiter: str
    decimal: str
    time: TimeSpec
    time_header: str | None = None
    true_values: tuple[str, ...] = ("TRUE", "True", "true")
    false_values: tuple[str, ...] = ("FALSE", "False", "false")
    start_key: str | None = None
    timezone: str | None = None
    description: str = ""


PRESETS: dict[str, Preset] = {
    "twincat-scope": Preset(
        "twincat-scope",
        delimiter=";",
        decimal=".",
        time=TimeSpec("ms"),
        time_header="Name",
        start_key="Starttime of export",
        description="Beckhoff TwinCAT 3 Scope View CSV export: a metadata block, the "
        "channel names in a row whose time columns are headed 'Name', per-channel rows "
        "(SampleTime[ms], ...), a blank row, then one time column [ms] per sample time",
    ),
    "tia-trace": Preset(
        "tia-trace",
        delimiter=";",
        decimal=".",
        time=TimeSpec("ms"),
        start_key="Start time",
        description="Siemens TIA Portal trace measurement CSV: a preamble of "
        "'key;value' rows, a header with the time [ms] first and '\"DB\".tag' names, "
        "TRUE/FALSE bits",
    ),
    "codesys-trace": Preset(
        "codesys-trace",
        delimiter=";",
        decimal=".",
        time=TimeSpec("ms"),
        start_key="Start time",
        description="CODESYS trace CSV export: a preamble, a header with the time [ms] "
        "first and the IEC variable names (PLC_PRG.x), TRUE/FALSE bits",
    ),
    "csv-de": Preset(
        "csv-de",
        delimiter=";",
        decimal=",",
        time=TimeSpec("datetime", "%d.%m.%Y %H:%M:%S,%f"),
        true_values=("TRUE", "WAHR", "true", "wahr"),
        false_values=("FALSE", "FALSCH", "false", "falsch"),
        timezone="Europe/Berlin",
        description="German-locale CSV: ';', decimal comma, the first column a local "
        "date-time '27.11.2026 14:03:05,123' (Europe/Berlin)",
    ),
}
"""The named export layouts ``pneufdd import --format`` knows (TDMS is read as is)."""


@dataclass(frozen=True)
class CsvLayout:
    """A CSV export's layout, from the tag map's options and its preset.

    Attributes
    ----------
    preset : Preset or None
        The named layout the options start from.
    delimiter, decimal : str
        Field separator and decimal mark.
    skip_rows, data_skip : int or "auto"
        Rows before the header row; rows between the header row and the data.
    true_values, false_values : tuple of str
        Texts read as 1 / 0 in digital columns (besides the numbers 0 and 1).
    timezone : str or None
        IANA zone of date-times without an offset (time columns, ``start_time``).
    start_time : datetime or None
        The export's start given in the map (overrides what the file says).
    times : dict of str to TimeSpec
        Time column (the map's key) -> how it is written.
    channel_time : dict of str to str
        Data column -> the time column it names with ``time``.
    """

    preset: Preset | None = None
    delimiter: str = ","
    decimal: str = "."
    skip_rows: int | str = 0
    data_skip: int | str = 0
    true_values: tuple[str, ...] = ()
    false_values: tuple[str, ...] = ()
    timezone: str | None = None
    start_time: datetime | None = None
    times: dict[str, TimeSpec] = field(default_factory=dict)
    channel_time: dict[str, str] = field(default_factory=dict)

    @property
    def plain(self) -> bool:
        """True for a plain CSV: header on line 1, one time column in s, 0/1 bits."""
        return (
            self.preset is None
            and self.skip_rows == 0
            and self.data_skip == 0
            and not self.true_values
            and not self.false_values
            and self.start_time is None
            and not self.channel_time
            and len(self.times) == 1
            and all(t == TimeSpec("s") for t in self.times.values())
        )

    def implicit_time(self) -> tuple[str | None, TimeSpec] | None:
        """The preset's time column (header or None: first column) when the map has none."""
        if self.times or self.preset is None:
            return None
        spec = self.preset.time
        return self.preset.time_header, replace(spec, timezone=spec.timezone or self.timezone)


def _timezone(where: str, value: Any) -> str:
    if not isinstance(value, str):
        raise InputError(describe(where, value, "an IANA time zone, e.g. 'Europe/Berlin'"))
    try:
        ZoneInfo(value)
    except (ZoneInfoNotFoundError, ValueError) as exc:
        raise InputError(
            describe(where, value, "an IANA time zone, e.g. 'Europe/Berlin' or 'UTC'")
        ) from exc
    return value


def parse_time_spec(where: str, entry: Mapping[str, Any]) -> TimeSpec:
    """Validate a time column's ``unit``, ``format`` and ``timezone``.

    Examples
    --------
    >>> parse_time_spec("map", {"unit": "ms"}).seconds_per_unit
    0.001
    """
    unit = entry.get("unit", "s")
    allowed = [*TIME_UNITS, "datetime"]
    if unit not in allowed:
        raise UnitError(describe(f"{where}.unit (time)", unit, allowed))
    fmt, zone = entry.get("format"), entry.get("timezone")
    if unit != "datetime":
        for key, value in (("format", fmt), ("timezone", zone)):
            if value is not None:
                raise InputError(
                    describe(
                        f"{where}.{key} (time in {unit})", value, "only with unit = 'datetime'"
                    )
                )
        return TimeSpec(unit)
    if fmt is not None and (not isinstance(fmt, str) or "%" not in fmt):
        raise InputError(
            describe(f"{where}.format", fmt, "a strptime format, e.g. '%d.%m.%Y %H:%M:%S,%f'")
        )
    if zone is not None:
        zone = _timezone(f"{where}.timezone", zone)
    return TimeSpec("datetime", fmt, zone)


def _skip(source: str, key: str, value: Any) -> int | str:
    if value == "auto":
        return "auto"
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SKIP_ROWS:
        raise InputError(
            describe(f"{source}: {key}", value, f"'auto' or a number of rows 0 to {MAX_SKIP_ROWS}")
        )
    return value


def _texts(source: str, key: str, value: Any) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(x, str) and x.strip() for x in value):
        raise InputError(describe(f"{source}: {key}", value, 'a list of texts, e.g. ["TRUE"]'))
    return tuple(x.strip() for x in value)


def _start(source: str, value: Any, zone: str | None) -> datetime | None:
    if value is None:
        return None
    if isinstance(value, str):
        with contextlib.suppress(ValueError):
            value = datetime.fromisoformat(value)
    if not isinstance(value, datetime):
        raise InputError(
            describe(
                f"{source}: start_time", value, "an ISO 8601 date-time, e.g. 2026-11-27T14:03:05"
            )
        )
    start: datetime = value
    if start.tzinfo is None and zone is not None:
        start = start.replace(tzinfo=ZoneInfo(zone))
    return start


def parse_layout(
    data: Mapping[str, Any],
    source: str,
    times: dict[str, TimeSpec],
    channel_time: dict[str, str],
    preset: str | None = None,
) -> CsvLayout:
    """Validate the layout options of a parsed tag map (module docstring).

    Parameters
    ----------
    data : mapping
        The parsed TOML document (only :data:`LAYOUT_KEYS` are read).
    source : str
        The map's name in messages.
    times, channel_time : dict
        The map's time columns and the channels' ``time`` keys (validated here).
    preset : str, optional
        A preset named outside the map (``--format``); it wins over the map's ``preset``.

    Raises
    ------
    InputError
        An unknown preset, a separator or decimal mark that is not one character (or
        both the same), a skip that is neither ``auto`` nor a row count, booleans that
        are not lists of texts or overlap, an unknown time zone, a bad ``start_time``,
        a channel's ``time`` that is not a time column of the map.

    Examples
    --------
    >>> layout = parse_layout({"preset": "csv-de"}, "map", {}, {})
    >>> layout.delimiter, layout.decimal, layout.skip_rows
    (';', ',', 'auto')
    """
    name = preset if preset is not None else data.get("preset")
    chosen = None
    if name is not None:
        if name not in PRESETS:
            raise InputError(describe(f"{source}: preset (--format)", name, sorted(PRESETS)))
        chosen = PRESETS[name]
    auto: int | str = "auto" if chosen is not None else 0
    dialect = {}
    for key, default in (
        ("delimiter", chosen.delimiter if chosen else ","),
        ("decimal", chosen.decimal if chosen else "."),
    ):
        value = data.get(key, default)
        if not isinstance(value, str) or len(value) != 1 or value in '\r\n"':
            raise InputError(describe(f"{source}: {key}", value, "one character, e.g. ';'"))
        dialect[key] = value
    if dialect["delimiter"] == dialect["decimal"]:
        raise InputError(
            describe(f"{source}: decimal (the same as delimiter)", dialect["decimal"], "another")
        )
    true_values = _texts(
        source, "true_values", data.get("true_values", list(chosen.true_values) if chosen else [])
    )
    false_values = _texts(
        source,
        "false_values",
        data.get("false_values", list(chosen.false_values) if chosen else []),
    )
    both = sorted(set(true_values) & set(false_values))
    if both:
        raise InputError(
            describe(f"{source}: texts in true_values and false_values", both, "each in one")
        )
    zone = data.get("timezone", chosen.timezone if chosen else None)
    if zone is not None:
        zone = _timezone(f"{source}: timezone", zone)
    for column, time in channel_time.items():
        if time not in times and not (chosen is not None and not times):
            raise InputError(
                describe(
                    f"{source}: columns.{column!r}.time", time, sorted(times) or "a time column"
                )
            )
    return CsvLayout(
        preset=chosen,
        delimiter=dialect["delimiter"],
        decimal=dialect["decimal"],
        skip_rows=_skip(source, "skip_rows", data.get("skip_rows", auto)),
        data_skip=_skip(source, "data_skip", data.get("data_skip", auto)),
        true_values=true_values,
        false_values=false_values,
        timezone=zone,
        start_time=_start(source, data.get("start_time"), zone),
        times={k: replace(v, timezone=v.timezone or zone) for k, v in times.items()},
        channel_time=dict(channel_time),
    )
