"""pneufdd's own Parquet format for a :class:`~pneufdd.recording.model.Recording`.

Layout (format ``pneufdd.recording``, version 1)
------------------------------------------------
One **row per channel**, in the recording's channel order, each row its own row
group, with the columns

========================  ==================  ==========================================
column                    type                content
========================  ==================  ==========================================
``name``                  string              channel name (Fig. 3.16 codes: ``P_In``)
``kind``                  string              ``"analog"`` or ``"digital"``
``unit``                  string              SI unit (``"1"`` for digital)
``rate_hz``               float64             sample rate [Hz]
``t0_s``                  float64             time of the first sample [s]
``dtype``                 string              ``"float32"``, ``"float64"`` or ``"uint8"``
``n_samples``             int64               number of samples
``values_float32``        list<float32>       the samples if ``dtype == "float32"``
``values_float64``        list<float64>       the samples if ``dtype == "float64"``
``values_uint8``          list<uint8>         the samples if ``dtype == "uint8"``
========================  ==================  ==========================================

Exactly one ``values_*`` cell of a row holds data; the other two are null. The file's
key-value metadata holds ``pneufdd.format`` (``"pneufdd.recording"``),
``pneufdd.format_version`` (``"1"``), ``pneufdd.recording`` (a JSON object with the
start time as ISO 8601 with microseconds and UTC offset, the IANA zone name and
``fold`` when there is one, the channel count, the free metadata and the writer's
version) and ``pneufdd.recording.crc32`` (CRC-32 of that JSON, as the Parquet footer
has no checksum of its own).

Why this layout: channels have their own lengths and rates (1 kHz analog beside
100 Hz digital on the rig, section 3.2.4), so a wide table would either pad the
slow channels ten-fold or mislead readers into thinking row ``i`` is one instant.
A row per channel keeps each channel exactly as sampled, keeps its dtype, and stays
readable by anyone: ``pandas.read_parquet(path)`` gives a small table of channels
whose ``values_*`` cells are NumPy arrays.

Encodings: floats are stored PLAIN (no dictionary, so no value is ever compared or
merged and every bit, NaN payloads and -0.0 included, comes back), digital channels
dictionary/RLE encoded, everything zstd-compressed, and every page carries a CRC-32
(checked on read), so flipped bytes raise an error instead of returning wrong data.
"""

from __future__ import annotations

import contextlib
import json
import zlib
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, FileFormatError, InputError, describe
from pneufdd.files import atomic_target
from pneufdd.limits import MAX_CHANNELS, check_json_depth, check_memory
from pneufdd.recording._files import FileExistsInputError, check_input_file, file_label
from pneufdd.recording.model import Channel, Recording

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "read_parquet",
    "recording_start_time",
    "write_parquet",
]

FORMAT_NAME = "pneufdd.recording"
"""Value of the ``pneufdd.format`` key in the file's key-value metadata."""
FORMAT_VERSION = 1
"""Layout version written; a reader accepts versions up to this one."""

_KEY_FORMAT = b"pneufdd.format"
_KEY_VERSION = b"pneufdd.format_version"
_KEY_RECORDING = b"pneufdd.recording"
_KEY_CHECKSUM = b"pneufdd.recording.crc32"  # the footer has no checksum of its own
_EXPECTED = f"a pneufdd recording (Parquet, format {FORMAT_NAME!r} version {FORMAT_VERSION})"
_MAGIC = b"PAR1"
_VALUE_COLUMNS = {"float32": "values_float32", "float64": "values_float64", "uint8": "values_uint8"}
_WIDEST = max(np.dtype(d).itemsize for d in _VALUE_COLUMNS)
"""Item size of the widest sample type [B]."""
_SCALAR_COLUMNS = ("name", "kind", "unit", "rate_hz", "t0_s", "dtype", "n_samples")
_MAX_SAMPLES = 2**31 - 1  # int32 list offsets


def _schema() -> pa.Schema:
    import pyarrow as pa

    return pa.schema(
        [
            pa.field("name", pa.string(), nullable=False),
            pa.field("kind", pa.string(), nullable=False),
            pa.field("unit", pa.string(), nullable=False),
            pa.field("rate_hz", pa.float64(), nullable=False),
            pa.field("t0_s", pa.float64(), nullable=False),
            pa.field("dtype", pa.string(), nullable=False),
            pa.field("n_samples", pa.int64(), nullable=False),
            pa.field("values_float32", pa.list_(pa.float32())),
            pa.field("values_float64", pa.list_(pa.float64())),
            pa.field("values_uint8", pa.list_(pa.uint8())),
        ]
    )


# --------------------------------------------------------------------- write
def _arrow_array(values: npt.NDArray[Any]) -> pa.Array:
    """A one-dimensional NumPy array as an Arrow array, without copying.

    Built from the array's buffer: ``pyarrow.array`` would first import pandas to
    ask whether ``values`` is a pandas object (0.3 s of a command that only writes
    a recording, issue 13).
    """
    import pyarrow as pa

    flat = np.ascontiguousarray(values.astype(values.dtype.newbyteorder("<"), copy=False))
    return pa.Array.from_buffers(
        pa.from_numpy_dtype(flat.dtype), flat.size, [None, pa.py_buffer(flat)]
    )


def _arrow_string(text: str) -> pa.Array:
    """One string as an Arrow ``string`` array of length 1 (see :func:`_arrow_array`)."""
    import pyarrow as pa

    data = text.encode("utf-8")
    offsets = np.array([0, len(data)], dtype="<i4")
    return pa.Array.from_buffers(pa.string(), 1, [None, pa.py_buffer(offsets), pa.py_buffer(data)])


def _channel_table(channel: Channel, schema: pa.Schema) -> pa.Table:
    import pyarrow as pa

    values = np.ascontiguousarray(channel.values)
    dtype = values.dtype.name
    if dtype not in _VALUE_COLUMNS:  # the model only makes these three
        raise ChannelError(describe(f"dtype of channel {channel.name!r}", dtype, _VALUE_COLUMNS))
    if values.size > _MAX_SAMPLES:
        raise ChannelError(
            describe(
                f"length of channel {channel.name!r} (split the recording)",
                values.size,
                f"<= {_MAX_SAMPLES} samples",
            )
        )
    columns: dict[str, pa.Array] = {
        "name": _arrow_string(channel.name),
        "kind": _arrow_string(channel.kind),
        "unit": _arrow_string(channel.unit),
        "rate_hz": _arrow_array(np.array([channel.rate_hz], dtype=np.float64)),
        "t0_s": _arrow_array(np.array([channel.t0], dtype=np.float64)),
        "dtype": _arrow_string(dtype),
        "n_samples": _arrow_array(np.array([values.size], dtype=np.int64)),
    }
    for name, column in _VALUE_COLUMNS.items():
        list_type = schema.field(column).type
        if name == dtype:
            offsets = _arrow_array(np.array([0, values.size], dtype=np.int32))
            columns[column] = pa.ListArray.from_arrays(
                offsets, _arrow_array(values), type=list_type
            )
        else:
            columns[column] = pa.nulls(1, type=list_type)
    return pa.Table.from_arrays([columns[f.name] for f in schema], schema=schema)


def _recording_info(recording: Recording) -> dict[str, Any]:
    from pneufdd import __version__

    start = recording.start_time
    zone = start.tzinfo.key if isinstance(start.tzinfo, ZoneInfo) else None
    return {
        "start_time": start.isoformat(timespec="microseconds"),
        "time_zone": zone,
        "fold": start.fold,
        "n_channels": len(recording.channels),
        "metadata": recording.metadata,
        "writer": f"pneufdd {__version__}",
    }


def _refuse_overwrite(path: Path) -> FileExistsInputError:
    return FileExistsInputError(
        f"{file_label(path)} exists; refusing to overwrite it "
        "(pass overwrite=True to replace it, or choose another path)"
    )


def write_parquet(recording: Recording, path: str | Path, overwrite: bool = False) -> Path:
    """Write ``recording`` to ``path`` in pneufdd's Parquet format (exact round trip).

    The file is written to a temporary name in the same folder, flushed to disk and
    then moved to ``path`` in one step, so an interrupted write never leaves a partial
    file at ``path``. See the module docstring for the layout.

    Parameters
    ----------
    recording : Recording
        The recording to write.
    path : str or Path
        Target file, conventionally ending in ``.parquet``.
    overwrite : bool
        Replace an existing file at ``path``; refused by default.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    FileExistsInputError
        If ``path`` exists and ``overwrite`` is false (the file is left untouched).
    InputError
        If ``path`` is a folder or its folder does not exist.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> from pneufdd.recording import Recording, read_parquet
    >>> rec = Recording.from_arrays({"P_In": np.array([6.0e5, np.nan], dtype=np.float32)},
    ...                             1000.0, units={"P_In": "Pa"})
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_parquet(rec, Path(folder) / "run.parquet")
    ...     read_parquet(path).equals(rec)
    True
    """
    import pyarrow.parquet as pq

    path = Path(path)
    if not isinstance(recording, Recording):
        raise InputError(describe("recording to write", type(recording).__name__, ["Recording"]))
    if path.is_dir():
        raise InputError(f"{file_label(path)} is a folder; give a file name ending in .parquet")
    if not path.parent.is_dir():
        raise InputError(f"{file_label(path)}: folder {str(path.parent)!r} does not exist")
    if path.exists() and not overwrite:
        raise _refuse_overwrite(path)
    info = json.dumps(_recording_info(recording), allow_nan=False).encode()
    schema = _schema().with_metadata(
        {
            _KEY_FORMAT: FORMAT_NAME.encode(),
            _KEY_VERSION: str(FORMAT_VERSION).encode(),
            _KEY_RECORDING: info,
            _KEY_CHECKSUM: str(zlib.crc32(info)).encode(),
        }
    )
    with (
        atomic_target(path, overwrite, _refuse_overwrite) as tmp,
        pq.ParquetWriter(
            tmp,
            schema,
            compression="zstd",
            compression_level=3,
            use_dictionary=["name", "kind", "unit", "dtype", "values_uint8.list.element"],
            write_statistics=list(_SCALAR_COLUMNS),
            write_page_checksum=True,
        ) as writer,
    ):
        for name in recording.channels:
            writer.write_table(_channel_table(recording.info(name), schema))
    return path


# ---------------------------------------------------------------------- read
def _check_magic(path: Path) -> None:
    size = path.stat().st_size
    with path.open("rb") as handle:
        head = handle.read(4)
        handle.seek(max(size - 4, 0))
        tail = handle.read(4)
    if head != _MAGIC:
        raise FileFormatError(
            f"{file_label(path)} is not a Parquet file (it does not start with {_MAGIC!r}); "
            f"expected {_EXPECTED}"
        )
    if tail != _MAGIC or size < 12:
        raise FileFormatError(
            f"{file_label(path)} is truncated or corrupted: it starts like a Parquet file but "
            f"its {size} bytes do not end with the Parquet footer ({_MAGIC!r}); "
            "was the copy or the write interrupted?"
        )


def _check_format(path: Path, kv: dict[bytes, bytes]) -> dict[str, Any]:
    label = file_label(path)
    name = kv.get(_KEY_FORMAT)
    if name is None:
        raise FileFormatError(
            f"{label} is a Parquet file but not a pneufdd recording: its key-value metadata "
            f"has no {_KEY_FORMAT.decode()!r} entry; expected {_EXPECTED}. Read it with "
            "pandas.read_parquet, or convert it to CSV and use read_csv with a column map"
        )
    if name != FORMAT_NAME.encode():
        raise FileFormatError(
            describe(
                f"{label}: {_KEY_FORMAT.decode()}", name.decode(errors="replace"), [FORMAT_NAME]
            )
        )
    raw_version = kv.get(_KEY_VERSION, b"").decode(errors="replace")
    if not raw_version.isdigit() or not 1 <= int(raw_version) <= FORMAT_VERSION:
        raise FileFormatError(
            describe(
                f"{label}: {_KEY_VERSION.decode()} (a newer version needs a newer pneufdd)",
                raw_version,
                f"1 to {FORMAT_VERSION}",
            )
        )
    raw = kv.get(_KEY_RECORDING, b"")
    if kv.get(_KEY_CHECKSUM) != str(zlib.crc32(raw)).encode():
        raise FileFormatError(
            f"{label} is corrupted: its {_KEY_RECORDING.decode()!r} metadata does not match "
            f"its CRC-32 ({_KEY_CHECKSUM.decode()!r})"
        )
    check_json_depth(raw, f"{label}: its {_KEY_RECORDING.decode()!r} metadata")
    try:
        info = json.loads(raw)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise FileFormatError(
            f"{label} is corrupted: its {_KEY_RECORDING.decode()!r} metadata "
            f"is not valid JSON ({exc})"
        ) from exc
    if not isinstance(info, dict) or not {"start_time", "n_channels", "metadata"} <= info.keys():
        raise FileFormatError(
            f"{label} is corrupted: its {_KEY_RECORDING.decode()!r} metadata lacks start_time, "
            "n_channels or metadata"
        )
    return info


def _start_time(path: Path, info: dict[str, Any]) -> datetime:
    try:
        start = datetime.fromisoformat(info["start_time"])
    except (TypeError, ValueError) as exc:
        raise FileFormatError(
            describe(f"{file_label(path)}: start_time", info["start_time"], "ISO 8601 with offset")
        ) from exc
    if start.tzinfo is None:
        raise FileFormatError(
            describe(f"{file_label(path)}: start_time", info["start_time"], "a UTC offset")
        )
    zone = info.get("time_zone")
    if isinstance(zone, str):  # the same wall time in the same IANA zone, if this system knows it
        with contextlib.suppress(ZoneInfoNotFoundError, ValueError):
            zoned = start.replace(tzinfo=ZoneInfo(zone), fold=int(info.get("fold", 0)) & 1)
            if zoned.utcoffset() == start.utcoffset():
                start = zoned
    return start


READ_BYTES_PER_BYTE = 4
"""Working memory per byte of sample data while a recording is read and used (Arrow's
table, its NumPy copy, the channel and one working copy)."""


def _check_declared_size(path: Path, metadata: Any) -> None:
    """Refuse a file whose channels declare more samples than memory allows, unread.

    A few kB of zstd can declare 10^8 identical samples; the footer's value counts
    say so before any page is decompressed.
    """
    if metadata.num_rows > MAX_CHANNELS:  # one row per channel
        raise FileFormatError(
            describe(
                f"{file_label(path)}: number of channels",
                metadata.num_rows,
                f"at most {MAX_CHANNELS:,} (docs/limits.md)",
            )
        )
    declared = 0
    for group in range(metadata.num_row_groups):
        row_group = metadata.row_group(group)
        for col in range(row_group.num_columns):
            chunk = row_group.column(col)
            column = chunk.path_in_schema.split(".", 1)[0]
            if column.startswith("values_"):
                # a damaged footer may name a column no dtype has: the widest one counts
                dtype = column[len("values_") :]
                itemsize = np.dtype(dtype).itemsize if dtype in _VALUE_COLUMNS else _WIDEST
                declared += max(int(chunk.num_values), 0) * itemsize
    check_memory(
        f"{file_label(path)}: samples declared by its channels "
        f"({declared:,} bytes of samples; split long recordings)",
        READ_BYTES_PER_BYTE * declared,
        error=FileFormatError,
    )


def _row_values(path: Path, table: pa.Table, row: int, name: str) -> npt.NDArray[Any]:
    label = f"{file_label(path)}, channel {name!r}"
    dtype = table.column("dtype")[row].as_py()
    if dtype not in _VALUE_COLUMNS:
        raise FileFormatError(describe(f"{label}: dtype", dtype, _VALUE_COLUMNS))
    for other, column in _VALUE_COLUMNS.items():
        filled = table.column(column)[row].is_valid
        if filled != (other == dtype):
            raise FileFormatError(
                f"{label} is corrupted: column {column!r} is "
                f"{'filled' if filled else 'empty'} but the channel's dtype is {dtype!r}"
            )
    cell = table.column(_VALUE_COLUMNS[dtype])[row].values
    if cell.null_count:
        raise FileFormatError(f"{label} is corrupted: {cell.null_count} samples are null")
    values: npt.NDArray[Any] = np.asarray(cell.to_numpy(zero_copy_only=False))
    expected = table.column("n_samples")[row].as_py()
    if values.dtype != np.dtype(dtype) or values.size != expected:
        raise FileFormatError(
            f"{label} is corrupted: {values.size} samples of {values.dtype} where the file "
            f"declares {expected} of {dtype}"
        )
    return values


def _with_file(path: Path, exc: InputError) -> InputError:
    """The same kind of error, its message prefixed with the file."""
    return type(exc)(f"{file_label(path)}: {exc}")


def read_parquet(path: str | Path) -> Recording:
    """Read a recording written by :func:`write_parquet`.

    Parameters
    ----------
    path : str or Path
        A ``.parquet`` file in pneufdd's format (see the module docstring).

    Returns
    -------
    Recording
        Exactly the recording written: channels in order, names, kinds, units, rates,
        offsets, dtypes, every value bit for bit, start time and metadata.

    Raises
    ------
    MissingFileError
        If ``path`` does not exist.
    FileFormatError
        If the file is empty, truncated, corrupted, not Parquet, a Parquet file
        written by someone else, or of a newer format version. The message names
        the file and what was expected.
    ChannelError, UnitError
        If the file declares duplicate channel names, unknown units or invalid
        channels (messages name the file).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = check_input_file(Path(path), _EXPECTED)
    label = file_label(path)
    _check_magic(path)
    # A corrupted footer can fail in many ways inside pyarrow; all of them mean the same.
    unreadable = (pa.ArrowException, OSError, UnicodeError, ValueError)
    try:
        parquet = pq.ParquetFile(path, page_checksum_verification=True)
        kv = dict(parquet.schema_arrow.metadata or {})
        metadata = parquet.metadata
    except unreadable as exc:
        raise FileFormatError(
            f"{label} is corrupted: its Parquet footer cannot be read "
            f"({type(exc).__name__}: {exc}); expected {_EXPECTED}"
        ) from exc
    try:
        info = _check_format(path, kv)
        _check_declared_size(path, metadata)
        table = parquet.read()
        names = table.column_names
    except InputError:
        raise
    except unreadable as exc:
        raise FileFormatError(
            f"{label} is corrupted: its data cannot be read ({type(exc).__name__}: {exc}); "
            "re-copy or re-write the file"
        ) from exc
    finally:
        parquet.close()
    wrong = [
        f.name
        for f in _schema()
        if f.name not in names or table.schema.field(f.name).type != f.type
    ]
    if wrong:
        raise FileFormatError(
            f"{label} is corrupted: column(s) {wrong} are missing or of the wrong type"
        )
    if table.num_rows != info["n_channels"]:
        raise FileFormatError(
            f"{label} is corrupted: {table.num_rows} channel rows where the file declares "
            f"{info['n_channels']}"
        )
    start_time = _start_time(path, info)
    try:
        channels = []
        for row in range(table.num_rows):
            scalars = {c: table.column(c)[row].as_py() for c in _SCALAR_COLUMNS}
            name = scalars["name"]
            for column in _SCALAR_COLUMNS:  # a null cell: the file is damaged
                if scalars[column] is None:
                    raise FileFormatError(
                        describe(
                            f"{label}: {column} of channel row {row} ({name!r})",
                            None,
                            "a value (the file is damaged; re-copy or re-write it)",
                        )
                    )
            channels.append(
                Channel(
                    name,
                    _row_values(path, table, row, name),
                    scalars["rate_hz"],
                    scalars["unit"],
                    scalars["kind"],
                    scalars["t0_s"],
                )
            )
        return Recording(channels, start_time=start_time, metadata=info["metadata"])
    except FileFormatError:
        raise
    except InputError as exc:
        raise _with_file(path, exc) from exc
    except UnicodeError as exc:
        raise FileFormatError(f"{label} is corrupted: a text cell is not UTF-8 ({exc})") from exc


def recording_start_time(path: str | Path) -> datetime | None:
    """The start time a pneufdd Parquet file records, read from its footer only.

    None when the file is no pneufdd recording or its start time cannot be read (the
    caller shows no date rather than a wrong one); reading the data checks the file.
    """
    import pyarrow.parquet as pq

    try:
        kv = pq.read_metadata(str(path)).metadata or {}
        info = json.loads(kv[_KEY_RECORDING].decode("utf-8"))
        start = datetime.fromisoformat(str(info["start_time"]))
    except (OSError, KeyError, ValueError, TypeError, AttributeError):
        return None
    return start if start.tzinfo is not None else None
