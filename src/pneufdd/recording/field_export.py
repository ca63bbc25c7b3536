"""Write a recording as a PLC or DAQ tool exports it (the layouts of the import presets).

``pneufdd simulate --export-format NAME`` plays the plant engineer who exports a
trace: the twin's run is written in the layout :data:`~pneufdd.recording.csv_layout.PRESETS`
describes, under tag names and in engineering units (bar(g), l/min (ANR), mm), with
the role map that reads it back (``pneufdd import run.csv --format NAME --map run.toml``).
The layouts are those ``docs/assumptions.md`` states:

* ``twincat-scope``: the Scope View's metadata block (start as FILETIME), the channel
  name row with a time column headed ``Name`` before each sample-time group, the
  per-channel rows, a blank row, then the data; time in ms after the start, REAL32
  values (9 significant digits), bits 0/1, blank cells where a slower group ends;
* ``tia-trace`` / ``codesys-trace``: a ``key;value`` preamble with the start time, a
  header ``Time [ms]`` and ``"DB_Pneu".tag`` / ``PLC_PRG.tag`` names, every signal at
  the fastest rate (one trace clock), REAL values (7 digits), bits ``TRUE``/``FALSE``;
* ``csv-de``: ``;``, decimal comma, the first column the local date-time
  ``27.11.2026 14:03:05,123`` (Europe/Berlin, ms), 6 significant digits, bits 0/1.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any
from zoneinfo import ZoneInfo

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, FileExistsInputError, InputError, describe
from pneufdd.physics.units import UNITS
from pneufdd.recording.csv_layout import PRESETS
from pneufdd.recording.model import Recording

__all__ = ["EXPORT_FORMATS", "default_tags", "write_field_export"]

EXPORT_FORMATS = ("twincat-scope", "tia-trace", "codesys-trace", "csv-de")
"""Layouts :func:`write_field_export` writes (each a preset of ``pneufdd import --format``)."""

_PREFIX = {"tia-trace": '"DB_Pneu".', "codesys-trace": "PLC_PRG."}
_DIGITS = {"twincat-scope": 9, "tia-trace": 7, "codesys-trace": 7, "csv-de": 6}
_UNIT = {"P": "bar(g)", "Q": "l/min (ANR)", "X": "mm"}


def default_tags(recording: Recording, export_format: str) -> dict[str, tuple[str, str]]:
    """Channel -> (column name, unit): the channel's name (``"DB_Pneu".P_In`` for TIA,
    ``PLC_PRG.P_In`` for CODESYS), pressures in bar(g), flows in l/min (ANR), mm.

    Examples
    --------
    >>> rec = Recording.from_arrays({"P_In": [7e5, 7e5]}, 1000.0, units={"P_In": "Pa"})
    >>> default_tags(rec, "tia-trace")
    {'P_In': ('"DB_Pneu".P_In', 'bar(g)')}
    """
    prefix = _PREFIX.get(export_format, "")
    return {
        name: (
            prefix + name,
            "1"
            if recording.info(name).kind == "digital"
            else _UNIT.get(name[0], recording.unit(name)),
        )
        for name in recording.channels
    }


def _from_si(values: npt.NDArray[np.float64], unit: str) -> npt.NDArray[np.float64]:
    convert = UNITS[unit].to_si
    zero = convert(np.zeros(1))[0]
    scale = convert(np.ones(1))[0] - zero
    out: npt.NDArray[np.float64] = (values - zero) / scale
    return out


def _text(values: npt.NDArray[Any], digits: int, decimal: str) -> npt.NDArray[np.str_]:
    text = np.char.mod(f"%.{digits}g", values)
    text = np.where(np.isnan(values), "", text)
    return np.char.replace(text, ".", decimal) if decimal != "." else text


def _bits(values: npt.NDArray[Any], words: tuple[str, str] | None) -> npt.NDArray[np.str_]:
    on = np.asarray(values) >= 0.5
    if words is None:
        return np.where(on, "1", "0")
    return np.where(on, words[0], words[1])


def _map_text(
    tags: Mapping[str, tuple[str, str]], export_format: str, kinds: Mapping[str, str]
) -> str:
    lines = [
        f"# role map of a {export_format} export; read with:",
        f"#   pneufdd import EXPORT.csv --format {export_format} --map THIS.toml --out run.parquet",
        "[columns]",
    ]
    for name, (column, unit) in tags.items():
        key = '"' + column.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if kinds[name] == "digital":
            lines.append(f'{key} = {{ role = "{name}" }}')
        elif unit == "l/min (ANR)":
            lines.append(f'{key} = {{ role = "{name}", unit = "l/min", basis = "ANR" }}')
        else:
            lines.append(f'{key} = {{ role = "{name}", unit = "{unit}" }}')
    return "\n".join(lines) + "\n"


def _filetime(moment: datetime) -> int:
    delta = moment.astimezone(UTC) - datetime(1601, 1, 1, tzinfo=UTC)
    return (delta.days * 86_400 + delta.seconds) * 10_000_000 + delta.microseconds * 10


def _twincat(
    recording: Recording, tags: Mapping[str, tuple[str, str]], name: str
) -> list[list[str]]:
    digits = _DIGITS["twincat-scope"]
    order = sorted(recording.channels, key=lambda c: -recording.rate(c))  # by sample time
    groups: list[tuple[float, float, list[str]]] = []
    for channel in order:
        info = recording.info(channel)
        if groups and groups[-1][:2] == (info.rate_hz, info.t0):
            groups[-1][2].append(channel)
        else:
            groups.append((info.rate_hz, info.t0, [channel]))
    columns: list[npt.NDArray[np.str_]] = []
    rows: dict[str, list[str]] = {k: [] for k in ("Name", "Data-Type", "SampleTime[ms]", "Unit")}
    for rate, t0, members in groups:
        n = recording.info(members[0]).values.size
        ms = np.round((t0 + np.arange(n) / rate) * 1e3, 6)
        columns.append(_text(ms, 15, "."))
        rows["Name"].append("Name")
        for key in ("Data-Type", "SampleTime[ms]", "Unit"):
            rows[key].append(key)
        for channel in members:
            info = recording.info(channel)
            column, unit = tags[channel]
            if info.kind == "digital":
                columns.append(_bits(info.values, None))
                rows["Data-Type"].append("BIT")
            else:
                values = _from_si(info.values.astype(np.float64), unit).astype(np.float32)
                columns.append(_text(values.astype(np.float64), digits, "."))
                rows["Data-Type"].append("REAL32")
            rows["Name"].append(column)
            rows["SampleTime[ms]"].append(f"{1e3 / rate:g}")
            rows["Unit"].append("(None)" if unit == "1" else unit)
    start = recording.start_time
    end_time = start + timedelta(seconds=recording.duration)
    head = [
        ["Name", name],
        ["File", f"{name}.csv"],
        [
            "Starttime of export",
            str(_filetime(start)),
            start.strftime("%A, %d. %B %Y"),
            start.strftime("%H:%M:%S.%f")[:-3],
        ],
        [
            "Endtime of export",
            str(_filetime(end_time)),
            end_time.strftime("%A, %d. %B %Y"),
            end_time.strftime("%H:%M:%S.%f")[:-3],
        ],
        [],
        [],
        rows["Name"],
        rows["Data-Type"],
        rows["SampleTime[ms]"],
        rows["Unit"],
        [],
    ]
    return head + _table(columns)


def _table(columns: list[npt.NDArray[np.str_]]) -> list[list[str]]:
    length = max(c.size for c in columns)
    padded = [np.concatenate([c, np.full(length - c.size, "", dtype=c.dtype)]) for c in columns]
    return np.stack(padded, axis=1).tolist()  # type: ignore[no-any-return]


def _one_clock(
    recording: Recording, tags: Mapping[str, tuple[str, str]], export_format: str
) -> list[list[str]]:
    frame = recording.to_pandas()
    digits = _DIGITS[export_format]
    preset = PRESETS[export_format]
    decimal = preset.decimal
    start = recording.start_time
    time = frame.index.to_numpy(np.float64)
    if export_format == "csv-de":
        import pandas as pd

        zone = ZoneInfo(preset.timezone or "UTC")
        stamps = pd.Timestamp(start).tz_convert(zone) + pd.to_timedelta(
            np.round(time * 1e6), unit="us"
        )
        first = [s[:-3] for s in stamps.strftime("%d.%m.%Y %H:%M:%S,%f")]
        columns = [np.asarray(first)]
        header = ["Zeit"]
        head: list[list[str]] = []
        words = None
    else:
        columns = [_text(np.round(time * 1e3, 6), 15, decimal)]
        header = ["Time [ms]"]
        head = [
            ["Trace", "pneufdd"],
            [str(preset.start_key), start.isoformat()],
            ["Time base", "ms"],
            ["Signals", str(len(tags))],
            [],
        ]
        words = (preset.true_values[0], preset.false_values[0])
    for channel, (column, unit) in tags.items():
        values = frame[channel].ffill().bfill().to_numpy(np.float64)
        header.append(column)
        if recording.info(channel).kind == "digital":
            columns.append(_bits(values, words))
        else:
            columns.append(_text(_from_si(values, unit), digits, decimal))
    return [*head, header, *_table(columns)]


def write_field_export(
    recording: Recording,
    path: str | Path,
    export_format: str,
    tags: Mapping[str, tuple[str, str]] | None = None,
    overwrite: bool = False,
) -> str:
    """Write ``recording`` in a tool's export layout; return the role map that reads it.

    Parameters
    ----------
    recording : Recording
        Channels ``P_*`` [Pa], ``Q_*`` [kg/s], ``X_*`` [m], ``U_*``/``S_*`` (0/1).
    path : str or Path
        The CSV to write.
    export_format : str
        One of :data:`EXPORT_FORMATS`.
    tags : mapping, optional
        Channel -> (column name, unit); default :func:`default_tags`. Channels not
        named are not written.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    str
        The tag map (TOML) with each column's role and unit.

    Examples
    --------
    >>> import tempfile
    >>> rec = Recording.from_arrays({"P_In": [7e5, 7e5]}, 1000.0, {"U_A_A": [0, 1]}, 1000.0,
    ...                             units={"P_In": "Pa"})
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     text = write_field_export(rec, Path(folder) / "run.csv", "csv-de")
    >>> print(text.splitlines()[-1])
    "U_A_A" = { role = "U_A_A" }
    """
    if export_format not in EXPORT_FORMATS:
        raise InputError(describe("export format", export_format, EXPORT_FORMATS))
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsInputError(describe("output", str(path), "a new file (or overwrite)"))
    tags = dict(tags) if tags is not None else default_tags(recording, export_format)
    missing = [c for c in tags if c not in recording.channels]
    if missing:
        raise ChannelError(describe("channels to export", missing, recording.channels))
    if export_format == "twincat-scope":
        rows = _twincat(recording.select(list(tags)), tags, path.stem)
    else:
        rows = _one_clock(recording.select(list(tags)), tags, export_format)
    import csv

    from pneufdd.files import write_text_atomic

    class _Lines:
        def __init__(self) -> None:
            self.parts: list[str] = []

        def write(self, text: str) -> None:
            self.parts.append(text)

    sink = _Lines()
    csv.writer(sink, delimiter=PRESETS[export_format].delimiter, lineterminator="\r\n").writerows(
        rows
    )
    write_text_atomic(path, "".join(sink.parts), overwrite=overwrite)
    kinds = {c: recording.info(c).kind for c in tags}
    return _map_text(tags, export_format, kinds)
