"""Read a uniformly sampled CSV file (one time column, one column per channel).

The user names which CSV column becomes which channel (codes of Fig. 3.16) and the
unit of each channel; values are converted to SI at this edge with
:func:`pneufdd.physics.units.to_si`. All channels of one CSV file share its time
column, so they share one sample rate.

Before anything is parsed, the file's size, its longest line and its number of lines
are checked (:func:`check_csv_size`), and once the header is read its number of
columns (:func:`check_csv_columns`) and the memory its rows imply
(:func:`check_csv_cells`), against ``docs/limits.md``: a small file may not declare a
million columns, nor a large one a single 100 MB line.
"""

from __future__ import annotations

import csv as _stdlib_csv
from collections import Counter
from collections.abc import Collection, Mapping
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, FileFormatError, InputError, UnitError, describe
from pneufdd.limits import (
    MAX_CSV_BYTES,
    MAX_CSV_COLUMNS,
    MAX_CSV_LINE_BYTES,
    check_memory,
)
from pneufdd.physics.units import UNITS, si_unit_of, to_si
from pneufdd.recording._files import check_input_file, file_label
from pneufdd.recording._sampling import snap_rate
from pneufdd.recording.model import ANALOG, DIGITAL, Channel, Recording

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["NA_TOKENS", "check_csv_cells", "check_csv_columns", "check_csv_size", "read_csv"]

NA_TOKENS = ("", "nan", "NaN", "NAN", "NA", "N/A", "n/a", "#N/A", "null", "NULL", "None")
"""Cell texts read as a missing sample (NaN); a blank cell is one of them."""

_HEADER_LINES = 1  # the first data row is line 2 of the file

NUMBER_CELL_BYTES = 32
"""Memory of a cell parsed as a number, with the text and copies around it [bytes]
(13 to 22 measured over 8 to 40 million cells)."""

TEXT_CELL_BYTES = 64
"""Memory of a cell read as text (a field export's columns), and its number [bytes]
(52 measured over 8 million cells)."""

_BLOCK_BYTES = 1 << 23  # read in 8 MiB blocks while counting lines


def check_csv_size(path: Path) -> int:
    """Refuse a CSV file too large or with too long a line, before it is parsed.

    Reads the file once in blocks (no line is held whole); a carriage return, a line
    feed or both end a line, as in every export tool.

    Parameters
    ----------
    path : Path
        The CSV file (checked to exist).

    Returns
    -------
    int
        Its number of lines (a last line without an end counts).

    Raises
    ------
    FileFormatError
        Larger than :data:`~pneufdd.limits.MAX_CSV_BYTES`, or a line longer than
        :data:`~pneufdd.limits.MAX_CSV_LINE_BYTES` (named by its number).
    """
    label = file_label(path)
    size = path.stat().st_size
    if size > MAX_CSV_BYTES:
        raise FileFormatError(
            describe(f"{label}: size [bytes] (split the export)", f"{size:,}",
                     f"at most {MAX_CSV_BYTES:,} (docs/limits.md)")
        )  # fmt: skip
    lines = current = 0  # current: bytes of the line running on into the next block
    with path.open("rb") as handle:
        while block := handle.read(_BLOCK_BYTES):
            data = np.frombuffer(block, np.uint8)
            ends = np.flatnonzero((data == 0x0A) | (data == 0x0D))
            if ends.size:
                lengths = np.diff(ends, prepend=-1) - 1
                lengths[0] += current
                long = np.flatnonzero(lengths > MAX_CSV_LINE_BYTES)
                if long.size:
                    before = block[: int(ends[long[0]])]
                    _too_long(label, lines + 1 + int(long[0]) - before.count(b"\r\n"))
                lines += int(ends.size) - block.count(b"\r\n")
                current = len(block) - 1 - int(ends[-1])
            else:
                current += len(block)
            if current > MAX_CSV_LINE_BYTES:
                _too_long(label, lines + 1)
    return lines + (current > 0)


def _too_long(label: str, line: int) -> None:
    raise FileFormatError(
        describe(f"{label}: length of line {line:,} [bytes]", f"> {MAX_CSV_LINE_BYTES:,}",
                 f"at most {MAX_CSV_LINE_BYTES:,} (docs/limits.md; is it a CSV export?)")
    )  # fmt: skip


def check_csv_columns(path: Path, columns: int) -> None:
    """Refuse a header of more than :data:`~pneufdd.limits.MAX_CSV_COLUMNS` columns."""
    if columns > MAX_CSV_COLUMNS:
        raise FileFormatError(
            describe(f"{file_label(path)}: number of columns in the header", f"{columns:,}",
                     f"at most {MAX_CSV_COLUMNS:,} (docs/limits.md)")
        )  # fmt: skip


def check_csv_cells(path: Path, lines: int, parsed: int, cell_bytes: int | None = None) -> None:
    """Refuse rows whose parsed cells would need more memory than the budget.

    Parameters
    ----------
    path : Path
        The CSV file.
    lines : int
        Its number of lines (:func:`check_csv_size`): the rows it may hold.
    parsed : int
        Columns the reader parses in every row.
    cell_bytes : int, optional
        Memory of one parsed cell [bytes]; default :data:`NUMBER_CELL_BYTES`.
    """
    check_memory(
        f"{file_label(path)}: {lines:,} lines x {parsed:,} columns parsed (split the "
        "export, or ignore columns)",
        lines * parsed * (cell_bytes or NUMBER_CELL_BYTES) + path.stat().st_size,
        error=FileFormatError,
    )


def _line(row: int) -> int:
    """File line number of data row ``row`` (0-based; line 1 is the header)."""
    return row + _HEADER_LINES + 1


def _check_maps(
    label: str,
    column_map: Mapping[str, str],
    units: Mapping[str, str],
    time_column: str,
    digital: Collection[str],
) -> None:
    if not column_map:
        raise ChannelError(
            describe(f"{label}: column_map", dict(column_map), "at least one column")
        )
    seen: dict[str, str] = {}
    for column, channel in column_map.items():
        if column == time_column:
            raise ChannelError(
                describe(f"{label}: column_map key", column, "data columns, not the time column")
            )
        if channel in seen:
            raise ChannelError(
                describe(
                    f"{label}: channel name {channel!r} is the target of columns "
                    f"{seen[channel]!r} and {column!r}",
                    channel,
                    "each channel name once",
                )
            )
        seen[channel] = column
    unknown_digital = sorted(set(digital) - set(seen))
    if unknown_digital:
        raise ChannelError(
            describe(f"{label}: digital (channel names)", unknown_digital, sorted(seen))
        )
    unknown_units = sorted(set(units) - set(seen))
    if unknown_units:
        raise ChannelError(
            describe(
                f"{label}: units given for channels not in column_map", unknown_units, sorted(seen)
            )
        )
    for channel in seen:
        where = f"of channel {channel!r} in {label}"
        if channel in digital:
            if units.get(channel, "1") != "1":
                raise UnitError(describe(f"unit {where} (digital 0/1)", units[channel], ["1"]))
            continue
        if channel not in units:
            raise UnitError(
                describe(f"unit {where} (pass units={{{channel!r}: ...}})", None, sorted(UNITS))
            )
        si_unit_of(units[channel], where)


def _read_header(path: Path, delimiter: str, encoding: str) -> list[str]:
    label = file_label(path)
    try:
        with path.open(newline="", encoding=encoding) as handle:
            reader = _stdlib_csv.reader(handle, delimiter=delimiter, skipinitialspace=True)
            header = next(reader, None)
    except UnicodeDecodeError as exc:
        raise FileFormatError(
            f"{label} is not a text file in encoding {encoding!r} ({exc}); expected a CSV "
            "file (pass encoding=... if it is in another encoding)"
        ) from exc
    except _stdlib_csv.Error as exc:
        raise FileFormatError(f"{label}: the header row is not valid CSV ({exc})") from exc
    if not header or not any(cell.strip() for cell in header):
        raise FileFormatError(f"{label} has no header row; expected column names on line 1")
    counts = Counter(header)  # linear in the number of columns (issue 39: 100k columns)
    duplicated = sorted(c for c, n in counts.items() if n > 1)
    if duplicated:
        raise FileFormatError(
            describe(f"{label}: duplicate column names in the header", duplicated, "unique names")
        )
    return header


def _first_bad_cell(frame: pd.DataFrame, decimal: str) -> tuple[str, int, str] | None:
    """Locate the first cell of ``frame`` (read as text) that is neither a number nor NA."""
    import pandas as pd

    first: tuple[str, int, str] | None = None
    for column in frame.columns:
        text = frame[column].astype(str).str.strip()
        if decimal != ".":  # as pandas reads it: the decimal mark, and "." is no number
            text = text.str.replace(".", "?", regex=False).str.replace(decimal, ".", regex=False)
        numbers = pd.to_numeric(text.where(~text.isin(NA_TOKENS)), errors="coerce")
        bad = np.flatnonzero(numbers.isna().to_numpy() & ~text.isin(NA_TOKENS).to_numpy())
        if bad.size and (first is None or bad[0] < first[1]):
            first = (str(column), int(bad[0]), str(frame[column].iloc[bad[0]]))
    return first


WIDE_COLUMNS = 1_000
"""Columns from which a CSV file's row widths are checked apart (see ``_read_table``)."""


def _row_widths_checked(path: Path, dialect: dict[str, str], label: str) -> bool:
    """For a file of :data:`WIDE_COLUMNS` columns or more, refuse a row with too many
    fields (pandas' own check, which ``usecols`` skips) and return True."""
    try:
        return _wide_rows_checked(path, dialect, label)
    except (UnicodeDecodeError, _stdlib_csv.Error):
        return False  # pandas reports it, as for any file


def _wide_rows_checked(path: Path, dialect: dict[str, str], label: str) -> bool:
    with path.open(encoding=dialect["encoding"], newline="") as handle:
        reader = _stdlib_csv.reader(handle, delimiter=dialect["delimiter"], skipinitialspace=True)
        width = len(next(reader, []))
        if width < WIDE_COLUMNS:
            return False
        for row in reader:
            if len(row) > width:
                raise FileFormatError(
                    f"{label} is not valid CSV (line {reader.line_num} has {len(row)} "
                    f"fields where the header has {width})"
                )
    return True


def _read_table(path: Path, columns: list[str], dialect: dict[str, str]) -> pd.DataFrame:
    import pandas as pd

    options: dict[str, Any] = {
        "sep": dialect["delimiter"],
        "decimal": dialect["decimal"],
        "encoding": dialect["encoding"],
        "skipinitialspace": True,
        "skip_blank_lines": False,  # keeps line numbers in messages right
        "keep_default_na": False,
        "na_values": list(NA_TOKENS),
    }
    label = file_label(path)
    # All columns are parsed (not usecols), so a row with too many fields is an error
    # rather than silently shifted data; only the wanted ones must be numbers. A wide
    # export (thousands of ignored columns) has its rows' widths checked in one pass
    # of the csv module instead, and only the wanted columns parsed: linear in the
    # number of columns (issue 39: 100,000 ignored columns took 93 s).
    parse: dict[str, Any] = {**options, "dtype": dict.fromkeys(columns, np.float64)}
    if _row_widths_checked(path, dialect, label):
        parse["usecols"] = columns
    try:
        frame: pd.DataFrame = pd.read_csv(path, **parse)[columns]
    except pd.errors.ParserError as exc:  # before ValueError: it is one
        raise FileFormatError(f"{label} is not valid CSV ({exc})") from exc
    except ValueError:
        pass  # a cell is not a number: find it below
    else:
        blank = frame.isna().all(axis=1).to_numpy()
        keep = blank.size
        while keep and blank[keep - 1]:  # trailing empty lines
            keep -= 1
        return frame.iloc[:keep]
    try:
        text = pd.read_csv(
            path, dtype=str, usecols=columns, **{**options, "na_values": [], "na_filter": False}
        )
    except ValueError as exc:
        raise FileFormatError(f"{label} is not valid CSV ({exc})") from exc
    bad = _first_bad_cell(text, dialect["decimal"])
    if bad is None:  # pragma: no cover - the float parse failed, so some cell is bad
        raise FileFormatError(f"{label}: a cell is not a number")
    column, row, cell = bad
    raise FileFormatError(
        describe(
            f"{label}, line {_line(row)}, column {column!r}: cell is not a number",
            cell,
            f"a number or blank (read as NaN; also {', '.join(t for t in NA_TOKENS if t)})",
        )
    )


def _time_base(
    label: str,
    time_column: str,
    time: npt.NDArray[np.float64],
    tolerance: float,
    line_offset: int = 0,
) -> tuple[float, float]:
    """Check ``time`` and return ``(t0 [s], rate [Hz])``.

    ``line_offset``: lines before the header row (a field export's preamble), so that
    messages name the file's own line numbers.
    """

    def _line(row: int) -> int:
        return row + _HEADER_LINES + 1 + line_offset

    if time.size < 2:
        raise FileFormatError(
            describe(
                f"{label}: number of data rows", int(time.size), ">= 2 to find the sample rate"
            )
        )
    blank = np.flatnonzero(~np.isfinite(time))
    if blank.size:
        raise FileFormatError(
            f"{label}, line {_line(int(blank[0]))}: time column {time_column!r} is blank or "
            "not finite; every row needs a time [s]"
        )
    steps = np.diff(time)
    backwards = np.flatnonzero(steps <= 0.0)
    if backwards.size:
        row = int(backwards[0]) + 1
        raise InputError(
            f"{label}, line {_line(row)}: time is not strictly increasing: "
            f"{float(time[row])!r} s follows {float(time[row - 1])!r} s in column {time_column!r}"
        )
    index = np.arange(time.size, dtype=np.float64)

    def deviation(rate: float) -> npt.NDArray[np.float64]:
        off: npt.NDArray[np.float64] = np.abs(time - (time[0] + index / rate))
        return off

    exact = (time.size - 1) / (time[-1] - time[0])
    best = float(np.max(deviation(exact)))
    rate = snap_rate(exact, lambda r: float(np.max(deviation(r))) <= best + 1e-6 / r)
    off = deviation(rate)
    worst = int(np.argmax(off))
    if off[worst] > tolerance / rate:
        typical = float(np.median(steps))
        odd = np.flatnonzero(np.abs(steps - typical) > tolerance * typical)
        if odd.size:  # a gap or a jump: name the first
            row = int(odd[0]) + 1
            where = (
                f"the step to line {_line(row)} is {float(steps[row - 1]):.6g} s where the "
                f"median step is {typical:.6g} s ({1.0 / typical:.6g} Hz)"
            )
        else:  # small steps that add up: the grid drifts
            where = (
                f"the sample at line {_line(worst)} (t = {float(time[worst])!r} s) lies "
                f"{float(off[worst]):.6g} s off the uniform grid of {rate!r} Hz"
            )
        raise InputError(
            f"{label}: column {time_column!r} is not uniformly sampled: {where}; allowed: "
            f"rate_tolerance = {tolerance!r} of one sample interval. pneufdd stores uniformly "
            "sampled channels: resample the data onto a uniform time grid first (e.g. "
            "numpy.interp or pandas resample), split the file at gaps, or raise "
            "rate_tolerance if the jitter is acceptable"
        )
    return float(time[0]), rate


def read_csv(
    path: str | Path,
    column_map: Mapping[str, str],
    units: Mapping[str, str],
    time_column: str = "time",
    digital: Collection[str] = (),
    start_time: datetime | None = None,
    metadata: Mapping[str, Any] | None = None,
    rate_tolerance: float = 0.01,
    delimiter: str = ",",
    decimal: str = ".",
    encoding: str = "utf-8-sig",
) -> Recording:
    """Read a uniformly sampled CSV file into a :class:`Recording`.

    Parameters
    ----------
    path : str or Path
        CSV file with a header row (UTF-8, optional BOM).
    column_map : mapping of str to str
        CSV column -> channel name, e.g. ``{"Supply pressure": "P_In"}``. Only mapped
        columns are read; the order of the map is the channel order.
    units : mapping of str to str
        Channel name -> unit of the CSV values, a key of
        :data:`pneufdd.physics.units.UNITS` (``"psig"``, ``"bar(g)"``, ``"SLPM"``,
        ``"mm"``...). Values are converted to SI. Digital channels need no unit.
    time_column : str
        Column holding the time of each row [s].
    digital : collection of str
        Channel names that are digital (valve solenoids ``U_*``, switches ``S_*``):
        every value must be 0 or 1; they are stored as uint8.
    start_time : datetime, optional
        Wall-clock time of t = 0 of the time column (default: 1970-01-01 UTC).
    metadata : mapping, optional
        Free JSON-compatible metadata; ``source`` is added with the file name unless given.
    rate_tolerance : float
        Largest allowed distance of any row's time from the uniform grid, as a
        fraction of one sample interval [1].
    delimiter : str
        Field separator (``";"`` for many European exports).
    decimal : str
        Decimal mark (``","`` for many European exports).
    encoding : str
        Text encoding; the default reads UTF-8 with or without a byte-order mark.

    Returns
    -------
    Recording
        Analog channels as float64 in SI units, digital channels as uint8; all at the
        rate of the time column, ``t0`` = the first time [s].

    Raises
    ------
    MissingFileError, FileFormatError
        Missing, empty or malformed file, a cell that is not a number, a blank time.
    ChannelError
        A mapped column missing from the file, two columns mapped to one channel, a
        digital channel with values other than 0/1.
    UnitError
        A unit not in the registry (the message lists those allowed) or an ambiguous
        one such as ``"psi"`` (say ``"psia"`` or ``"psig"``).
    InputError
        Time not strictly increasing (the message names the line) or not uniform
        within ``rate_tolerance``.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "run.csv"
    ...     _ = path.write_text("t,supply psig,valve\\n0.000,90,0\\n0.001,90.5,1\\n")
    ...     rec = read_csv(path, {"supply psig": "P_In", "valve": "U_DNC_A"},
    ...                    units={"P_In": "psig"}, time_column="t", digital=["U_DNC_A"])
    >>> rec.rate("P_In"), rec.unit("P_In"), round(float(rec.channel("P_In")[1][0]))
    (1000.0, 'Pa', 721853)
    """
    path = check_input_file(Path(path), "a CSV file with a header row")
    label = file_label(path)
    if not (isinstance(rate_tolerance, int | float) and 0.0 < rate_tolerance < 0.5):
        raise InputError(describe("rate_tolerance", rate_tolerance, "0 < rate_tolerance < 0.5"))
    digital = set(digital)
    _check_maps(label, column_map, units, time_column, digital)
    lines = check_csv_size(path)
    header = _read_header(path, delimiter, encoding)
    check_csv_columns(path, len(header))
    wanted = [time_column, *column_map]
    present = set(header)
    missing = [c for c in wanted if c not in present]
    if missing:
        raise ChannelError(describe(f"{label}: column(s) not in the file", missing, header))
    wide = len(header) >= WIDE_COLUMNS  # only the wanted columns are parsed
    check_csv_cells(path, lines, len(wanted) if wide else len(header))
    dialect = {"delimiter": delimiter, "decimal": decimal, "encoding": encoding}
    frame = _read_table(path, wanted, dialect)
    t0, rate = _time_base(
        label, time_column, frame[time_column].to_numpy(np.float64), float(rate_tolerance)
    )
    channels = []
    for column, name in column_map.items():
        raw = frame[column].to_numpy(np.float64)
        if name in digital:
            bad = np.flatnonzero((raw != 0.0) & (raw != 1.0))  # NaN is bad too
            if bad.size:
                raise ChannelError(
                    describe(
                        f"{label}, line {_line(int(bad[0]))}: value of digital channel "
                        f"{name!r} (column {column!r})",
                        "" if np.isnan(raw[bad[0]]) else float(raw[bad[0]]),
                        "0 or 1",
                    )
                )
            channels.append(Channel(name, raw.astype(np.uint8), rate, "1", DIGITAL, t0))
        else:
            values, si_unit = to_si(raw, units[name], f"of channel {name!r} in {label}")
            channels.append(Channel(name, values, rate, si_unit, ANALOG, t0))
    meta = dict(metadata or {})
    meta.setdefault("source", {"format": "csv", "file": path.name})
    return Recording(channels, start_time=start_time, metadata=meta)
