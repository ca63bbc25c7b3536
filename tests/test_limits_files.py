"""Issue 39: TDMS and CSV files are checked against their limits before they are parsed.

Small crafted files that declare huge sizes (``tests/fuzzing_files.py`` builds them;
``make fuzz`` runs them through the commands): each is refused with exit 2 naming the
file, the field, the value and the limit (``docs/limits.md``), before anything of the
declared size is allocated. A whole file still reads back exactly.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest

import fuzzing_files as ff
from pneufdd import Recording, limits
from pneufdd.errors import FileFormatError, InputError
from pneufdd.recording import csv as csv_module
from pneufdd.recording import tdms as tdms_module
from pneufdd.recording.tag_map import load_tag_map, read_mapped


@pytest.fixture(scope="module")
def rec() -> Recording:
    """Two cycles' worth of channels: analog at 1 kHz, a valve at 100 Hz."""
    t = np.arange(2000) / 1000.0
    return Recording.from_arrays(
        {"P_In": 6e5 + 1e3 * np.sin(t), "Q_In": 1e-4 + 0 * t},
        1000.0,
        {"U_FEED_A": (np.arange(200) // 50) % 2},
        100.0,
        units={"P_In": "Pa", "Q_In": "kg/s"},
    )


@pytest.fixture(scope="module")
def export(rec: Recording) -> tuple[bytes, str]:
    return ff.tdms_of(rec)


def _read(tmp_path: Path, data: bytes, tags: str, name: str = "run.tdms") -> Recording:
    path, mapping = tmp_path / name, tmp_path / "tags.toml"
    path.write_bytes(data)
    mapping.write_text(tags)
    return read_mapped(path, load_tag_map(mapping))


def test_a_whole_tdms_file_reads_back_exactly(tmp_path: Path, rec: Recording, export) -> None:
    data, tags = export
    back = _read(tmp_path, data, tags)
    for name in rec.channels:
        assert back.rate(name) == rec.rate(name)
        np.testing.assert_array_equal(back.channel(name)[1], rec.channel(name)[1])
    assert back.info("U_FEED_A").values.dtype == np.uint8


@pytest.mark.parametrize(
    ("name", "shown"),
    [
        ("name_4gib", "a length its TDMS metadata declares at byte {at} (a name, a property or "
         "a data block): received '4,294,967,280 bytes'; allowed: at most the 4 bytes left in "
         "the file"),
        ("objects_4e9", "objects listed by the segment at byte {end}: received '4,294,967,280'; "
         "allowed: at most 20,000 (docs/limits.md)"),
        ("objects_x_segments", "objects listed over all segments (objects x segments; "
         "defragment the file with NI's TDMS tools, which join its segments): received 'more "
         "than 2,000,000'; allowed: at most 2,000,000 (docs/limits.md)"),
        ("p_in_increment_1e-300", "TDMS channel AI/P_In wf_increment (the sample interval [s]; "
         "pneufdd reads uniformly sampled waveform channels, select only those with "
         "channel_map): received 1e-300; allowed: >= 1e-07 s (at most 1e+07 Hz"),
        ("p_in_increment_text", "wf_increment (the sample interval [s]; pneufdd reads "
         "uniformly sampled waveform channels, select only those with channel_map): received "
         "'fast'"),
        ("p_in_offset_nan", "TDMS channel AI/P_In wf_start_offset [s]: received nan; allowed: a "
         "finite time"),
        ("p_in_offset_text", "wf_start_offset [s]: received 'soon'"),
    ],
)  # fmt: skip
def test_tdms_headers_past_their_limits_are_refused(
    tmp_path: Path, export, name: str, shown: str
) -> None:
    data, tags = export
    hostile = dict((n, c) for n, c, _ in ff.hostile_tdms(data))[name]
    with pytest.raises(InputError) as caught:
        _read(tmp_path, hostile, tags)
    text = str(caught.value)
    assert text.startswith(f"file '{tmp_path / 'run.tdms'}'")
    assert shown.format(at=f"{len(data) + 36:,}", end=f"{len(data):,}") in text


def test_tdms_segment_count_is_bounded(tmp_path: Path, export) -> None:
    _, tags = export
    first = ff.tdms_segment(ff.TOC_METADATA | ff.TOC_NEW_LIST, [])
    many = first + ff.tdms_segment(ff.TOC_RAW, []) * 100_000  # 2.8 MB of empty segments
    with pytest.raises(FileFormatError, match=r"number of segments \(defragment the file with "
                       r"NI's TDMS tools, which join its segments\): received 'more than "
                       r"100,000'; allowed: at most 100,000"):  # fmt: skip
        _read(tmp_path, many, tags)
    with pytest.raises(InputError, match="holds no channels"):  # one fewer: npTDMS reads it
        _read(tmp_path, many[:-28], tags)


def test_tdms_types_are_checked_before_the_samples_are_read(tmp_path: Path, export) -> None:
    data, tags = export
    found = {n: c for n, c, _ in ff.hostile_tdms(data)}
    extra = tags.replace('"AI/P_In"', '"AI/extra"')
    # a string channel declaring 2^60 values: refused from its type, unread
    with pytest.raises(InputError, match=r"dtype of channel 'P_In' \(TDMS AI/extra\).*"
                       r"received 'object'; allowed: numeric"):  # fmt: skip
        _read(tmp_path, found["string_channel_2e60"], extra)
    with pytest.raises(InputError, match=r"received 'datetime64\[us\]'; allowed: numeric"):
        _read(tmp_path, found["time_channel"], extra)


def test_tdms_memory_is_checked_from_the_metadata(
    tmp_path: Path, export, monkeypatch: pytest.MonkeyPatch
) -> None:
    data, tags = export
    # the real case needs a file of gigabytes: scale the bytes per sample instead
    monkeypatch.setattr(tdms_module, "SAMPLE_COPIES", 10**6)
    with pytest.raises(FileFormatError, match=r"samples of the channels read \(4,200 samples; "
                       r"split long recordings\): needs about 33\.6 GB of memory; allowed: at "
                       r"most 1\.6 GB"):  # fmt: skip
        _read(tmp_path, data, tags)
    monkeypatch.undo()
    monkeypatch.setattr(tdms_module, "METADATA_BYTES_PER_BYTE", 10**9)
    with pytest.raises(FileFormatError, match=r"TDMS metadata \(1 segments, \d[\d,]* bytes of "
                       r"metadata, 6 objects listed\): needs about"):  # fmt: skip
        _read(tmp_path, data, tags)


def test_a_damaged_tdms_file_is_refused_quietly(tmp_path: Path, export, capfd) -> None:
    """npTDMS's warnings (a damaged file: megabytes of quoted bytes) become one clipped
    error, not console output; a DAQmx index declaring 16 GiB of widths is refused."""
    data, tags = export
    found = {n: c for n, c, _ in ff.hostile_tdms(data)}
    with pytest.raises(FileFormatError, match="is truncated or corrupted: npTDMS reported"):
        _read(tmp_path, data[: len(data) // 2], tags)
    with pytest.raises(FileFormatError, match=r"daqmx\.tdms' is not a readable TDMS file"):
        _read(tmp_path, found["daqmx_widths_4e9"], tags, "daqmx.tdms")
    with pytest.raises(FileFormatError) as caught:
        _read(tmp_path, found["name_4gib"][:-60] + b"\xff" * 60, tags)
    assert len(str(caught.value)) < 2_000
    assert capfd.readouterr().err == ""


def test_every_tdms_header_field_damaged_is_refused_or_read(tmp_path: Path, export) -> None:
    """Each 4-byte field of the metadata set to 0, 2^31 or 2^32 - 1: an InputError or a
    recording, never another exception (the first round: 439 of 1,485 exited 3)."""
    data, tags = export
    meta_end = 28 + struct.unpack("<Q", data[20:28])[0]
    outcomes = {"read": 0, "refused": 0}
    for offset in range(28, meta_end - 3, 4):
        for value in (0, 0x8000_0000, 0xFFFF_FFFF):
            damaged = data[:offset] + struct.pack("<L", value) + data[offset + 4 :]
            try:
                _read(tmp_path, damaged, tags)
                outcomes["read"] += 1
            except InputError:
                outcomes["refused"] += 1
    assert outcomes["refused"] > outcomes["read"] > 0


# ----------------------------------------------------------------------- CSV


def test_csv_lines_are_counted_with_every_line_end(tmp_path: Path) -> None:
    path = tmp_path / "a.csv"
    path.write_bytes(b"t,x\r\n0,1\r1,2\n2,3\r\n3,4")
    assert csv_module.check_csv_size(path) == 5
    path.write_bytes(b"t,x\n" * 3)
    assert csv_module.check_csv_size(path) == 3


def test_csv_size_line_length_and_columns_are_bounded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "long.csv"
    path.write_bytes(b"t,x\r\n0,1\r\n" + b"7" * (limits.MAX_CSV_LINE_BYTES + 1) + b"\r\n1,2\r\n")
    with pytest.raises(FileFormatError, match=r"long.csv': length of line 3 \[bytes\]: received "
                       r"'> 16,777,216'; allowed: at most 16,777,216"):  # fmt: skip
        csv_module.check_csv_size(path)
    wide = tmp_path / "wide.csv"
    wide.write_text("t,P," + ",".join(f"c{i}" for i in range(1_000_000)) + "\n0,1\n")
    with pytest.raises(FileFormatError, match=r"wide.csv': number of columns in the header: "
                       r"received '1,000,002'; allowed: at most 200,000"):  # fmt: skip
        csv_module.read_csv(wide, {"P": "P_In"}, {"P_In": "bar"}, time_column="t")
    monkeypatch.setattr(csv_module, "MAX_CSV_BYTES", 10)
    with pytest.raises(FileFormatError, match=r"size \[bytes\] \(split the export\): received "
                       r"'\d[\d,]*'; allowed: at most 10 \(docs/limits.md\)"):  # fmt: skip
        csv_module.check_csv_size(path)


def test_csv_rows_are_checked_against_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.csv"
    path.write_text("t,P,x\n" + "".join(f"{i / 1000},6.0,1\n" for i in range(100)))
    # 101 lines x 3 columns: scale the bytes per cell instead of writing gigabytes
    monkeypatch.setattr(csv_module, "NUMBER_CELL_BYTES", 10**7)
    with pytest.raises(FileFormatError, match=r"run.csv': 101 lines x 3 columns parsed \(split "
                       r"the export, or ignore columns\): needs about 3\.0 GB"):  # fmt: skip
        csv_module.read_csv(path, {"P": "P_In"}, {"P_In": "bar"}, time_column="t")
    monkeypatch.undo()
    rec = csv_module.read_csv(path, {"P": "P_In"}, {"P_In": "bar"}, time_column="t")
    assert rec.rate("P_In") == 1000.0
    assert math.isclose(float(rec.channel("P_In")[1][0]), 6e5)
