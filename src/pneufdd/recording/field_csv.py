"""Read a field export's CSV as the tool wrote it (the layout of a tag map or a preset).

The reader finds the header row (skipped or detected), the first data row, reads the
needed columns with pandas (``usecols``, so the cost grows with the rows and the
columns used, and linearly with the columns present), converts each time column (s,
ms, us or date-time with a format and zone) and each channel on its own time column,
drops the blank tail of a channel whose time column ends early (TwinCAT's slower
sample times), and keeps the export's wall-clock start as ``start_time``
(``docs/recording.md``).
"""

from __future__ import annotations

import bisect
import csv as _stdlib_csv
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any
from zoneinfo import ZoneInfo

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, FileFormatError, InputError, describe
from pneufdd.physics.units import to_si
from pneufdd.recording._files import file_label
from pneufdd.recording.csv import (
    NA_TOKENS,
    TEXT_CELL_BYTES,
    _time_base,
    check_csv_cells,
    check_csv_columns,
    check_csv_size,
)
from pneufdd.recording.csv_layout import MAX_SKIP_ROWS, CsvLayout, TimeSpec
from pneufdd.recording.model import ANALOG, DIGITAL, Channel, Recording

if TYPE_CHECKING:
    import pandas as pd

    from pneufdd.recording.tag_map import TagMap

__all__ = ["FILETIME_EPOCH", "read_field_csv"]

FILETIME_EPOCH = datetime(1601, 1, 1, tzinfo=UTC)
"""Origin of Windows FILETIME (100 ns ticks), TwinCAT Scope's start time."""

_MIN_RATE_HZ = 50.0
_MAX_RATE_HZ = 1e6
_START_FORMATS = (
    "%Y-%m-%d %H:%M:%S.%f",
    "%Y-%m-%dT%H:%M:%S.%f",
    "%Y-%m-%d %H:%M:%S",
    "%d.%m.%Y %H:%M:%S.%f",
    "%d.%m.%Y %H:%M:%S,%f",
    "%d.%m.%Y %H:%M:%S",
    "%m/%d/%Y %I:%M:%S.%f %p",
    "%m/%d/%Y %H:%M:%S.%f",
)


@dataclass(frozen=True)
class _Head:
    """Where the parts of the file are: preamble rows, header, first data line."""

    preamble: list[list[str]]
    header: list[str]
    header_line: int  # 1-based
    data_line: int  # 1-based line of the first data row


def _rows(handle: Any, delimiter: str) -> Iterator[tuple[int, list[str]]]:
    reader = _stdlib_csv.reader(handle, delimiter=delimiter, skipinitialspace=True)
    for row in reader:
        yield reader.line_num, [c.strip() for c in row]


def _find_header(
    label: str, rows: Iterator[tuple[int, list[str]]], skip: int | str, wanted: set[str]
) -> tuple[list[list[str]], list[str], int]:
    preamble: list[list[str]] = []
    best: tuple[int, list[str]] = (-1, [])
    for count, (line, row) in enumerate(rows):
        if count > MAX_SKIP_ROWS:
            break
        if skip == "auto":
            hits = len(wanted.intersection(row))
            if hits == len(wanted):
                return preamble, row, line
            if hits > best[0]:
                best = (hits, row)
        elif count == skip:
            return preamble, row, line
        preamble.append(row)
    if skip != "auto":
        raise FileFormatError(
            describe(
                f"{label}: skip_rows (rows before the header)", skip, "fewer than the file has"
            )
        )
    missing = sorted(wanted.difference(best[1]))
    raise ChannelError(
        describe(
            f"{label}: no row holds every column of the tag map (searched "
            f"{min(len(preamble), MAX_SKIP_ROWS)} rows); missing from the closest row",
            missing,
            [c for c in best[1] if c] or "a header row with the map's columns",
        )
    )


def _is_time(cell: str, spec: TimeSpec, decimal: str) -> bool:
    if not cell:
        return False
    if spec.unit != "datetime":
        try:
            float(cell.replace(decimal, "."))
        except ValueError:
            return False
        return True
    try:
        if spec.format is None:
            datetime.fromisoformat(cell)
        else:
            datetime.strptime(cell, spec.format)
    except ValueError:
        return False
    return True


def _scan(
    path: Path, layout: CsvLayout, wanted: set[str], probe: Mapping[int, TimeSpec] | None
) -> _Head:
    """Find the header row and the first data row (``probe``: time column -> spec, by index)."""
    label = file_label(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = _rows(handle, layout.delimiter)
            preamble, header, header_line = _find_header(label, rows, layout.skip_rows, wanted)
            data_line = header_line + 1
            if layout.data_skip == "auto" and probe is not None:
                time_specs = probe or {0: TimeSpec()}
                for count, (line, row) in enumerate(rows):
                    if count > MAX_SKIP_ROWS:
                        break
                    if row and all(
                        i < len(row) and _is_time(row[i], spec, layout.decimal)
                        for i, spec in time_specs.items()
                    ):
                        return _Head(preamble, header, header_line, line)
                    data_line = line + 1
                raise FileFormatError(
                    f"{label}: no data row after the header row (line {header_line})"
                )
            if isinstance(layout.data_skip, int):
                data_line += layout.data_skip
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{label} is not a UTF-8 CSV file ({exc})") from exc
    except _stdlib_csv.Error as exc:
        raise FileFormatError(f"{label} is not valid CSV ({exc})") from exc
    return _Head(preamble, header, header_line, data_line)


def _columns(
    label: str, tag_map: TagMap, header: list[str]
) -> tuple[dict[str, list[int]], dict[str, TimeSpec]]:
    """Column name -> its indices in the header; the time columns and their specs."""
    where: dict[str, list[int]] = {}
    for index, name in enumerate(header):
        where.setdefault(name, []).append(index)
    layout = tag_map.layout
    times = dict(layout.times)
    implicit = layout.implicit_time()
    if implicit is not None:
        times = {header[0] if implicit[0] is None else implicit[0]: implicit[1]}
    if not times:
        raise InputError(
            describe(
                f"{tag_map.source}: the role 'time' (needed for {label})",
                None,
                'one column with { role = "time", unit = "s" } (or ms, us, datetime), or --format',
            )
        )
    duplicated = sorted(n for n, i in where.items() if len(i) > 1 and n and n not in times)
    mapped = {c.column for c in tag_map.channels}
    clash = [n for n in duplicated if n in mapped]
    if clash:
        raise FileFormatError(
            describe(
                f"{label}: duplicate names of mapped columns in the header", clash, "unique names"
            )
        )
    return where, times


def _read_cells(path: Path, head: _Head, layout: CsvLayout, indices: list[int]) -> pd.DataFrame:
    import pandas as pd

    label = file_label(path)
    try:
        frame: pd.DataFrame = pd.read_csv(
            path,
            sep=layout.delimiter,
            header=None,
            names=list(range(len(head.header))),
            usecols=indices,
            skiprows=head.data_line - 1,
            dtype=str,
            keep_default_na=False,
            na_filter=False,
            skip_blank_lines=False,
            skipinitialspace=True,
            encoding="utf-8-sig",
            index_col=False,
        )
    except pd.errors.EmptyDataError as exc:
        raise FileFormatError(f"{label}: no data rows after line {head.data_line - 1}") from exc
    except (pd.errors.ParserError, ValueError) as exc:
        raise FileFormatError(f"{label} is not valid CSV ({exc})") from exc
    return frame.fillna("")


def _numbers(text: pd.Series, decimal: str) -> pd.Series:
    import pandas as pd

    if decimal != ".":  # as the locale reads it: '.' is no decimal mark there
        text = text.str.replace(".", "?", regex=False).str.replace(decimal, ".", regex=False)
    return pd.to_numeric(text, errors="coerce")


def _bad_cell(label: str, line: int, column: str, cell: str, allowed: str) -> FileFormatError:
    return FileFormatError(describe(f"{label}, line {line}, column {column!r}", cell, allowed))


def _time_seconds(
    label: str, column: str, text: pd.Series, spec: TimeSpec, decimal: str, first_line: int
) -> tuple[pd.Series, int]:
    """Seconds (or tz-aware date-times) of a time column and its length (blank tail cut)."""
    import pandas as pd

    text = text.str.strip()
    blank = (text == "").to_numpy()
    n = int(np.argmax(blank)) if blank.any() else blank.size
    if blank[n:].size and not blank[n:].all():
        later = n + int(np.argmin(blank[n:]))
        raise FileFormatError(
            f"{label}: time column {column!r} is blank at line {first_line + n} but goes on "
            f"at line {first_line + later}; allowed: blanks only after its last sample"
        )
    text = text.iloc[:n]
    if spec.unit == "datetime":
        stamps = pd.to_datetime(text, format=spec.format or "ISO8601", errors="coerce")
        bad = np.flatnonzero(stamps.isna().to_numpy())
        if bad.size:
            raise _bad_cell(
                label,
                first_line + int(bad[0]),
                column,
                str(text.iloc[bad[0]]),
                f"a date-time like format {spec.format or 'ISO 8601'!r}",
            )
        if stamps.dt.tz is None:
            zone = spec.timezone or "UTC"
            try:
                stamps = stamps.dt.tz_localize(
                    ZoneInfo(zone), ambiguous="infer", nonexistent="raise"
                )
            except (ValueError, TypeError) as exc:  # pytz/zoneinfo ambiguity errors are ValueErrors
                raise InputError(
                    f"{label}: time column {column!r}: the local times cannot be placed in "
                    f"time zone {zone!r} ({exc}); allowed: times that exist there (or a UTC "
                    "offset in the format, %z)"
                ) from exc
        return stamps, n
    seconds = _numbers(text, decimal)
    bad = np.flatnonzero(seconds.isna().to_numpy())
    if bad.size:
        raise _bad_cell(
            label,
            first_line + int(bad[0]),
            column,
            str(text.iloc[bad[0]]),
            f"a time in {spec.unit} (decimal mark {decimal!r})",
        )
    return seconds * spec.seconds_per_unit, n


def _values(
    label: str,
    column: str,
    role: str,
    text: pd.Series,
    n: int,
    layout: CsvLayout,
    first_line: int,
) -> npt.NDArray[Any]:
    """Parse a channel's cells up to its time column's length ``n``."""
    text = text.str.strip()
    tail = np.flatnonzero((text.iloc[n:] != "").to_numpy())
    if tail.size:
        raise _bad_cell(
            label,
            first_line + n + int(tail[0]),
            column,
            str(text.iloc[n + int(tail[0])]),
            "blank where its time column has ended",
        )
    text = text.iloc[:n]
    digital = role[:2] in ("U_", "S_")
    if digital:
        numbers = _numbers(text, layout.decimal)
        numbers = numbers.mask(text.isin(layout.true_values), 1.0)
        numbers = numbers.mask(text.isin(layout.false_values), 0.0)
        raw = numbers.to_numpy(np.float64)
        bad = np.flatnonzero((raw != 0.0) & (raw != 1.0))
        if bad.size:
            allowed = ["0", "1", *layout.true_values, *layout.false_values]
            raise ChannelError(
                describe(
                    f"{label}, line {first_line + int(bad[0])}: value of digital role {role} "
                    f"(column {column!r})",
                    str(text.iloc[bad[0]]),
                    allowed,
                )
            )
        return raw.astype(np.uint8)
    na = text.isin(NA_TOKENS).to_numpy()
    parsed: npt.NDArray[np.float64] = _numbers(text, layout.decimal).to_numpy(np.float64)
    bad = np.flatnonzero(np.isnan(parsed) & ~na)
    if bad.size:
        raise _bad_cell(
            label,
            first_line + int(bad[0]),
            column,
            str(text.iloc[bad[0]]),
            f"a number with decimal mark {layout.decimal!r}, or blank (read as NaN)",
        )
    return parsed


def _preamble_start(head: _Head, layout: CsvLayout) -> datetime | None:
    """The export's start from its preamble (TwinCAT FILETIME, or a 'Start time' row)."""
    preset = layout.preset
    if preset is None or preset.start_key is None:
        return None
    key = preset.start_key.lower()
    zone = ZoneInfo(layout.timezone or "UTC")
    for row in head.preamble:
        if len(row) < 2 or row[0].rstrip(":").lower() != key:
            continue
        cell = row[1]
        if cell.isdigit():  # FILETIME: 100 ns ticks since 1601-01-01 UTC
            return FILETIME_EPOCH + timedelta(microseconds=int(cell) // 10)
        try:
            stamp = datetime.fromisoformat(cell)
        except ValueError:
            stamp = None
            for fmt in _START_FORMATS:
                try:
                    stamp = datetime.strptime(cell, fmt)
                    break
                except ValueError:
                    continue
        if stamp is not None:
            return stamp if stamp.tzinfo is not None else stamp.replace(tzinfo=zone)
    return None


def _check_rate(label: str, column: str, spec: TimeSpec, rate: float) -> None:
    if _MIN_RATE_HZ <= rate <= _MAX_RATE_HZ:
        return
    raise InputError(
        describe(
            f"{label}: time column {column!r} read in {spec.unit} gives a sample rate",
            f"{rate:g} Hz",
            f"{_MIN_RATE_HZ:g} Hz to {_MAX_RATE_HZ:g} Hz; is the time unit right (unit = "
            "'s', 'ms' or 'us' in the tag map)?",
        )
    )


def read_field_csv(path: Path, tag_map: TagMap, metadata: Mapping[str, Any]) -> Recording:
    """Read a CSV export in the layout of ``tag_map`` (its options or preset).

    Parameters
    ----------
    path : Path
        The export (checked to exist by the caller).
    tag_map : TagMap
        Roles, units and ``layout`` (:class:`~pneufdd.recording.csv_layout.CsvLayout`).
    metadata : mapping
        Metadata of the recording (``source``).

    Returns
    -------
    Recording
        Each channel at the rate of its own time column, SI units; ``start_time`` = the
        map's ``start_time``, else the first date-time of the time columns, else the
        start the preamble gives, else 1970-01-01 UTC.

    Raises
    ------
    ChannelError
        No header row holds the map's columns; a column the file does not map; digital
        values that are neither 0/1 nor a boolean text of the layout.
    FileFormatError
        A cell that is not a number (or not a date-time of the format), a time column
        blank in the middle, a value after its time column ended, malformed CSV.
    InputError
        Time not uniform or not increasing, a sample rate that suggests a wrong time unit.
    """
    from pneufdd.recording.tag_map import _check_unmapped

    layout = tag_map.layout
    label = file_label(path)
    wanted = {c.column for c in tag_map.columns}
    implicit = layout.implicit_time()
    if implicit is not None and implicit[0] is not None:
        wanted.add(implicit[0])
    lines = check_csv_size(path)  # size and line lengths, before a row is parsed
    head = _scan(path, layout, wanted, None)
    check_csv_columns(path, len(head.header))
    where, times = _columns(label, tag_map, head.header)
    _check_unmapped(label, tag_map, [c for c in where if c and c not in times])
    probe = {where[name][0]: spec for name, spec in times.items() if name in where}
    if layout.data_skip == "auto":
        head = _scan(path, layout, wanted, probe)
    time_index = sorted(i for name in times for i in where.get(name, []))
    if not time_index:
        raise ChannelError(
            describe(f"{label}: time column(s) not in the header", sorted(times), head.header)
        )
    owners: dict[str, int] = {}
    for role in tag_map.channels:  # the nearest (named) time column on its left
        own = layout.channel_time.get(role.column)
        candidates = where.get(own, []) if own else time_index
        if not candidates:
            raise ChannelError(
                describe(f"{label}: time column of {role.column!r}", own, sorted(times))
            )
        left = bisect.bisect_left(candidates, where[role.column][0])
        owners[role.column] = candidates[max(left - 1, 0)]
    used = sorted(set(owners.values()))
    indices = sorted({*used, *(where[c][0] for c in owners)})
    check_csv_cells(path, lines, len(indices), TEXT_CELL_BYTES)
    frame = _read_cells(path, head, layout, indices)
    if frame.shape[0] and "EOF" in {str(c).strip() for c in frame.iloc[-1]}:  # TwinCAT's EOF tag
        frame = frame.iloc[:-1]
    first = head.data_line
    header = head.header
    parsed = {
        i: _time_seconds(label, header[i], frame[i], _spec(times, header[i]), layout.decimal, first)
        for i in used
    }
    import pandas as pd

    dated = {i for i in used if _spec(times, header[i]).unit == "datetime"}
    firsts: list[datetime] = [parsed[i][0].iloc[0].to_pydatetime() for i in dated if parsed[i][1]]
    start = layout.start_time or (min(firsts) if firsts else None)
    start = start or _preamble_start(head, layout)
    bases: dict[int, tuple[float, float, int]] = {}
    for i, (column, n) in parsed.items():
        if i in dated:  # date-times: seconds after the start
            origin = pd.Series(pd.Timestamp(start or datetime(1970, 1, 1, tzinfo=UTC)))
            column = (column - origin.iloc[0]).dt.total_seconds()
        values = column.to_numpy(np.float64)
        t0, rate = _time_base(label, header[i], values, 0.01, line_offset=first - 2)
        _check_rate(label, header[i], _spec(times, header[i]), rate)
        bases[i] = (t0, rate, n)
    channels = []
    for role in tag_map.channels:
        t0, rate, n = bases[owners[role.column]]
        raw = _values(label, role.column, role.role, frame[where[role.column][0]], n, layout, first)
        if role.digital:
            channels.append(Channel(role.role, raw, rate, "1", DIGITAL, t0))
        else:
            values, si_unit = to_si(raw, role.unit, f"of column {role.column!r} in {label}")
            channels.append(Channel(role.role, values, rate, si_unit, ANALOG, t0))
    meta = dict(metadata)
    if layout.preset is not None:
        meta["source"] = {**meta.get("source", {}), "preset": layout.preset.name}
    return Recording(channels, start_time=start, metadata=meta)


def _spec(times: Mapping[str, TimeSpec], name: str) -> TimeSpec:
    return times[name]
