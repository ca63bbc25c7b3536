"""pneufdd's Parquet format: exact round trip, clear errors, no overwrite, atomic writes."""

from __future__ import annotations

import json
import tempfile
import zlib
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path
from zoneinfo import ZoneInfo

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import ChannelError, FileFormatError, InputError, UnitError
from pneufdd.recording import (
    Channel,
    FileExistsInputError,
    MissingFileError,
    Recording,
    read_parquet,
    write_parquet,
)
from pneufdd.recording import parquet as pneufdd_parquet
from recording_helpers import identical, rig_recording, same_bits

# ----------------------------------------------------------------- round trip


def test_rig_recording_round_trips_bit_for_bit(tmp_path: Path) -> None:
    rec = rig_recording(seconds=3.0)
    path = write_parquet(rec, tmp_path / "run.parquet")
    back = read_parquet(path)
    assert identical(rec, back)
    assert back.channels == rec.channels  # order kept: 11 analog, then 40 digital
    assert len(back.analog_channels) == 11
    assert len(back.digital_channels) == 40
    assert back.rate("P_In") == 1000.0
    assert back.rate("U_DNC_A") == 100.0
    assert back.info("P_In").values.dtype == np.float32
    assert back.info("U_DNC_A").values.dtype == np.uint8
    assert back.start_time == datetime(2011, 6, 14, 9, 30, 12, 345678, tzinfo=UTC)


def test_special_floats_keep_their_bits(tmp_path: Path) -> None:
    bits32 = np.array(
        [0x7FC00000, 0x7FC00001, 0xFFC00000, 0x7F800001, 0x80000000, 0x7F800000, 0xFF800000, 1],
        dtype=np.uint32,
    )
    bits64 = np.array([0x7FF8000000000001, 0xFFF8000000000000, 0x8000000000000000], np.uint64)
    rec = Recording(
        [
            Channel("a", bits32.view(np.float32), 1000.0, "Pa"),
            Channel("b", bits64.view(np.float64), 1000.0, "kg/s", t0=-0.0015),
            Channel("empty", np.array([], dtype=np.float64), 1000.0, "m"),
        ]
    )
    back = read_parquet(write_parquet(rec, tmp_path / "nan.parquet"))
    assert back.info("a").values.view(np.uint32).tolist() == bits32.tolist()
    assert back.info("b").values.view(np.uint64).tolist() == bits64.tolist()
    assert back.info("b").t0 == -0.0015
    assert back.info("empty").values.size == 0


def test_time_zone_and_microseconds_survive(tmp_path: Path) -> None:
    cases = [
        datetime(2024, 3, 31, 2, 30, 0, 1, tzinfo=ZoneInfo("Europe/Berlin")),  # in the DST gap
        datetime(2024, 10, 27, 2, 30, 0, 999999, tzinfo=ZoneInfo("Europe/Berlin"), fold=1),
        datetime(2011, 6, 14, 9, 30, 0, 5, tzinfo=timezone(timedelta(hours=-4))),
    ]
    for i, start in enumerate(cases):
        rec = Recording([Channel("P_In", np.ones(3), 1000.0, "Pa")], start_time=start)
        back = read_parquet(write_parquet(rec, tmp_path / f"tz{i}.parquet"))
        assert back.start_time.isoformat() == start.isoformat()
        assert back.start_time.tzinfo == start.tzinfo
        assert back.start_time.fold == start.fold
        assert identical(rec, back)


def test_pandas_and_pyarrow_users_can_read_the_file(tmp_path: Path) -> None:
    rec = rig_recording(seconds=1.0)
    path = write_parquet(rec, tmp_path / "run.parquet")
    frame = pd.read_parquet(path)
    assert list(frame["name"]) == list(rec.channels)
    row = frame.set_index("name").loc["P_In"]
    assert row["rate_hz"] == 1000.0
    assert row["unit"] == "Pa"
    assert same_bits(np.asarray(row["values_float32"], np.float32), rec.info("P_In").values)
    kv = pq.read_schema(path).metadata
    assert kv[b"pneufdd.format"] == b"pneufdd.recording"
    assert kv[b"pneufdd.format_version"] == b"1"
    info = json.loads(kv[b"pneufdd.recording"])
    assert info["metadata"] == rec.metadata
    assert info["start_time"] == "2011-06-14T09:30:12.345678+00:00"
    # one row group per channel: a single channel can be read alone
    parquet = pq.ParquetFile(path)
    assert parquet.num_row_groups == len(rec.channels)
    assert parquet.metadata.row_group(0).column(7).compression == "ZSTD"


_NAMES = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs", "Zs", "Cc")),
    min_size=1,
    max_size=12,
)
_RATES = st.one_of(
    st.sampled_from([1000.0, 100.0, 1.0 / 3.0, 2048.0, 12345.678]),
    st.floats(min_value=1e-3, max_value=1e6, allow_nan=False, allow_infinity=False),
)
_JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**53), max_value=2**53)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=10),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4)
    ),
    max_leaves=12,
)
_ZONES = st.one_of(
    st.just(UTC),
    st.sampled_from([ZoneInfo("Europe/Berlin"), ZoneInfo("America/Toronto")]),
    st.integers(min_value=-14 * 60, max_value=14 * 60).map(
        lambda m: timezone(timedelta(minutes=m))
    ),
)


@st.composite
def _channels(draw: st.DrawFn) -> Channel:
    name = draw(_NAMES).strip() or "x"
    kind_dtype = draw(st.sampled_from(["float32", "float64", "uint8"]))
    n = draw(st.integers(min_value=0, max_value=300))
    if kind_dtype == "uint8":
        values = np.asarray(draw(st.lists(st.integers(0, 1), min_size=n, max_size=n)), np.uint8)
        return Channel(name, values, draw(_RATES), "1", "digital", draw(st.floats(-10, 10)))
    width = 32 if kind_dtype == "float32" else 64
    floats = st.floats(width=width, allow_nan=True, allow_infinity=True, allow_subnormal=True)
    values = np.asarray(draw(st.lists(floats, min_size=n, max_size=n)), dtype=kind_dtype)
    # sprinkle NaNs with arbitrary payloads
    uint = np.uint32 if width == 32 else np.uint64
    payloads = draw(st.lists(st.integers(1, 2 ** (23 if width == 32 else 52) - 1), max_size=3))
    exponent = 0x7F800000 if width == 32 else 0x7FF0000000000000
    bits = values.view(uint).copy()
    for i, payload in enumerate(payloads[: bits.size]):
        bits[i * 7 % bits.size] = uint(exponent | payload)
    unit = draw(st.sampled_from(["Pa", "kg/s", "m", "K", "V", "1", "kg", "rad"]))
    return Channel(
        name, bits.view(values.dtype), draw(_RATES), unit, "analog", draw(st.floats(-1e3, 1e3))
    )


@given(
    channels=st.lists(_channels(), max_size=6, unique_by=lambda c: c.name),
    metadata=st.dictionaries(st.text(max_size=8), _JSON, max_size=4),
    start=st.datetimes(
        min_value=datetime(1900, 1, 1), max_value=datetime(2200, 1, 1), timezones=_ZONES
    ),
)
def test_round_trip_is_exact_for_any_recording(
    channels: list[Channel], metadata: dict[str, object], start: datetime
) -> None:
    rec = Recording(channels, start_time=start, metadata=metadata)
    with tempfile.TemporaryDirectory() as folder:
        back = read_parquet(write_parquet(rec, Path(folder) / "r.parquet"))
    assert identical(rec, back)


def test_recording_write_and_read_use_this_format(tmp_path: Path) -> None:
    rec = rig_recording(seconds=0.5)
    path = rec.write(tmp_path / "run.parquet")
    assert path == tmp_path / "run.parquet"
    assert identical(Recording.read(path), rec)
    assert identical(Recording.read(str(path)), rec)


# ------------------------------------------------------------- overwriting


def test_refuses_to_overwrite_and_leaves_the_file_alone(tmp_path: Path) -> None:
    path = tmp_path / "run.parquet"
    first = rig_recording(seconds=0.5, seed=1)
    write_parquet(first, path)
    before = path.read_bytes()
    with pytest.raises(FileExistsInputError, match=r"run\.parquet.*overwrite=True"):
        write_parquet(rig_recording(seconds=0.5, seed=2), path)
    with pytest.raises(FileExistsError):
        rig_recording(seconds=0.5, seed=2).write(path)
    with pytest.raises(InputError):
        write_parquet(rig_recording(seconds=0.5, seed=2), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.parquet"]  # no temp files


def test_overwrite_true_replaces(tmp_path: Path) -> None:
    path = tmp_path / "run.parquet"
    write_parquet(rig_recording(seconds=0.5, seed=1), path)
    second = rig_recording(seconds=0.5, seed=2)
    write_parquet(second, path, overwrite=True)
    assert identical(read_parquet(path), second)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.parquet"]


def test_interrupted_write_leaves_no_partial_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = {"n": 0}
    real = pneufdd_parquet._channel_table

    def failing(channel: Channel, schema: pa.Schema) -> pa.Table:
        calls["n"] += 1
        if calls["n"] == 5:
            raise KeyboardInterrupt
        return real(channel, schema)

    monkeypatch.setattr(pneufdd_parquet, "_channel_table", failing)
    path = tmp_path / "run.parquet"
    with pytest.raises(KeyboardInterrupt):
        write_parquet(rig_recording(seconds=0.5), path)
    assert list(tmp_path.iterdir()) == []
    # an existing file survives an interrupted overwrite unchanged
    monkeypatch.setattr(pneufdd_parquet, "_channel_table", real)
    original = rig_recording(seconds=0.5, seed=3)
    write_parquet(original, path)
    before = path.read_bytes()
    calls["n"] = 0
    monkeypatch.setattr(pneufdd_parquet, "_channel_table", failing)
    with pytest.raises(KeyboardInterrupt):
        write_parquet(rig_recording(seconds=0.5), path, overwrite=True)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["run.parquet"]


def test_write_to_a_folder_or_missing_folder_is_refused(tmp_path: Path) -> None:
    rec = rig_recording(seconds=0.1)
    with pytest.raises(InputError, match="is a folder"):
        write_parquet(rec, tmp_path)
    with pytest.raises(InputError, match="does not exist"):
        write_parquet(rec, tmp_path / "nowhere" / "run.parquet")


# --------------------------------------------------------------- bad files


@pytest.fixture
def written(tmp_path: Path) -> Path:
    return write_parquet(rig_recording(seconds=1.0), tmp_path / "good.parquet")


def test_missing_file_names_it(tmp_path: Path) -> None:
    path = tmp_path / "absent.parquet"
    with pytest.raises(MissingFileError, match=r"absent\.parquet.*does not exist") as info:
        read_parquet(path)
    assert isinstance(info.value, FileNotFoundError)
    assert isinstance(info.value, FileFormatError)


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.parquet"
    path.write_bytes(b"")
    with pytest.raises(FileFormatError, match=r"empty\.parquet.*empty \(0 bytes\)"):
        read_parquet(path)


@pytest.mark.parametrize("fraction", [0.5, 0.01, 0.9, 0.999])
def test_truncated_file_names_it(written: Path, fraction: float) -> None:
    data = written.read_bytes()
    cut = written.with_name("cut.parquet")
    cut.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(FileFormatError, match=r"cut\.parquet.* is truncated or corrupted"):
        read_parquet(cut)


def test_file_missing_its_last_byte(written: Path) -> None:
    data = written.read_bytes()
    cut = written.with_name("cut.parquet")
    cut.write_bytes(data[:-1])
    with pytest.raises(FileFormatError, match=r"cut\.parquet.*truncated"):
        read_parquet(cut)


def test_corrupted_data_bytes_are_detected(written: Path) -> None:
    meta = pq.ParquetFile(written).metadata
    column = meta.row_group(0).column(7)  # P_In samples
    assert column.path_in_schema == "values_float32.list.element"
    data = bytearray(written.read_bytes())
    middle = column.data_page_offset + column.total_compressed_size // 2
    data[middle : middle + 16] = bytes(16)
    bad = written.with_name("bad.parquet")
    bad.write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match=r"bad\.parquet.* is corrupted"):
        read_parquet(bad)


def test_every_flipped_byte_is_detected_or_harmless(tmp_path: Path) -> None:
    """Flip bytes all over a small file: the reader errors or returns the exact recording."""
    rng = np.random.default_rng(5)
    rec = Recording(
        [
            Channel("P_In", rng.normal(6e5, 1e3, 40).astype(np.float32), 1000.0, "Pa"),
            Channel("Q_In", rng.normal(1e-3, 1e-5, 40), 1000.0, "kg/s", t0=0.25),
            Channel("U_DNC_A", (rng.random(4) > 0.5).astype(np.uint8), 100.0, "1", "digital"),
        ],
        metadata={"machine": "festo", "leaks": [{"location": "DNC_A", "turns": 3.5}]},
    )
    data = write_parquet(rec, tmp_path / "small.parquet").read_bytes()
    flipped = tmp_path / "flipped.parquet"
    detected = harmless = 0
    for position in range(0, len(data), 7):
        corrupt = bytearray(data)
        corrupt[position] ^= 0xFF
        flipped.write_bytes(bytes(corrupt))
        try:
            back = read_parquet(flipped)
        except InputError as exc:
            message = str(exc)
            detected += 1
            assert "flipped.parquet" in message
        else:
            assert identical(back, rec), f"silent change after flipping byte {position}"
            harmless += 1
    assert detected > harmless > 0


def test_other_file_kinds(tmp_path: Path) -> None:
    text = tmp_path / "notes.parquet"
    text.write_text("time,P_In\n0,1\n")
    with pytest.raises(FileFormatError, match=r"notes\.parquet.* is not a Parquet file"):
        read_parquet(text)
    folder = tmp_path / "dir.parquet"
    folder.mkdir()
    with pytest.raises(FileFormatError, match=r"dir\.parquet.* is not a regular file"):
        read_parquet(folder)


def test_foreign_parquet_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "pandas.parquet"
    pd.DataFrame({"time": [0.0, 0.001], "P_In": [1.0, 2.0]}).to_parquet(path)
    with pytest.raises(FileFormatError) as info:
        read_parquet(path)
    message = str(info.value)
    assert "pandas.parquet" in message
    assert "not a pneufdd recording" in message
    assert "'pneufdd.recording' version 1" in message
    assert message.startswith(f"file {str(path)!r} is a Parquet file but not a pneufdd recording")


def _rewrite(
    source: Path, target: Path, table: pa.Table, changes: dict[bytes, bytes] | None = None
) -> Path:
    """Write ``table`` with the key-value metadata of ``source``, changed as given."""
    kv = {**pq.read_schema(source).metadata, **(changes or {})}
    kv[b"pneufdd.recording.crc32"] = str(zlib.crc32(kv[b"pneufdd.recording"])).encode()
    pq.write_table(table.replace_schema_metadata(kv), target)
    return target


def test_newer_or_other_format_is_refused(written: Path) -> None:
    table = pq.read_table(written)
    newer = _rewrite(
        written, written.with_name("v2.parquet"), table, {b"pneufdd.format_version": b"2"}
    )
    with pytest.raises(FileFormatError, match=r"v2\.parquet.*newer.*received '2'; allowed: 1 to 1"):
        read_parquet(newer)
    other = _rewrite(
        written, written.with_name("o.parquet"), table, {b"pneufdd.format": b"acme.log"}
    )
    with pytest.raises(FileFormatError, match=r"o\.parquet.*'acme\.log'.*'pneufdd\.recording'"):
        read_parquet(other)


def test_tampered_metadata_is_detected(written: Path) -> None:
    table = pq.read_table(written)
    kv = dict(pq.read_schema(written).metadata)
    kv[b"pneufdd.recording"] = kv[b"pneufdd.recording"].replace(b"festo-dsd", b"festo-dsX")
    path = written.with_name("tampered.parquet")
    pq.write_table(table.replace_schema_metadata(kv), path)
    with pytest.raises(FileFormatError, match=r"tampered\.parquet.*CRC-32"):
        read_parquet(path)


def test_duplicate_channel_names_in_a_file(written: Path) -> None:
    table = pq.read_table(written)
    names = table.column("name").to_pylist()
    names[1] = names[0]
    table = table.set_column(0, table.schema.field(0), pa.array(names, pa.string()))
    path = _rewrite(written, written.with_name("dup.parquet"), table)
    with pytest.raises(ChannelError, match=r"dup\.parquet.*duplicate channel name.*'P_In'"):
        read_parquet(path)


def test_unknown_unit_in_a_file(written: Path) -> None:
    table = pq.read_table(written)
    units = table.column("unit").to_pylist()
    units[0] = "furlong"
    table = table.set_column(2, table.schema.field(2), pa.array(units, pa.string()))
    path = _rewrite(written, written.with_name("unit.parquet"), table)
    with pytest.raises(UnitError, match=r"unit\.parquet.*'P_In'.*'furlong'.*'Pa'"):
        read_parquet(path)


def test_declared_length_must_match(written: Path) -> None:
    table = pq.read_table(written)
    counts = table.column("n_samples").to_pylist()
    counts[0] += 1
    table = table.set_column(6, table.schema.field(6), pa.array(counts, pa.int64()))
    path = _rewrite(written, written.with_name("len.parquet"), table)
    with pytest.raises(
        FileFormatError, match=r"len\.parquet', channel 'P_In' is corrupted: 1000 samples.*1001"
    ):
        read_parquet(path)


def test_channel_count_must_match(written: Path) -> None:
    table = pq.read_table(written).slice(0, 3)
    path = _rewrite(written, written.with_name("rows.parquet"), table)
    with pytest.raises(FileFormatError, match=r"rows\.parquet.*3 channel rows.*51"):
        read_parquet(path)


def test_a_damaged_column_name_in_a_chunk_of_the_footer_is_read_or_refused(
    tmp_path: Path,
) -> None:
    # found by make fuzz (seed 97,000,310, bitflip_17): one bit flipped "values_float64"
    # in a column chunk's path into "values_f|oat64", and the declared-size check
    # crashed on it (exit 3); the samples are intact, so the file reads as written
    rec = rig_recording()
    path = write_parquet(rec, tmp_path / "run.parquet")
    data = path.read_bytes()
    first = data.find(b"values_float64")
    at = data.find(b"values_float64", first + 1)  # a chunk's path, after the schema's
    assert first > 0
    assert at > first
    flipped = bytearray(data)
    flipped[at + len("values_f")] ^= 0x10  # 'l' -> '|'
    assert flipped[at : at + 14] == b"values_f|oat64"
    path.write_bytes(bytes(flipped))
    assert identical(read_parquet(path), rec)
    # the same flip in the schema itself is refused, naming the file
    flipped = bytearray(data)
    flipped[first + len("values_f")] ^= 0x10
    path.write_bytes(bytes(flipped))
    with pytest.raises(FileFormatError, match=r"run\.parquet"):
        read_parquet(path)
