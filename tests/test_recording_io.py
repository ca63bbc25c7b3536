"""read_any / Recording.read: dispatch on the file suffix, clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from nptdms import ChannelObject, TdmsWriter

from pneufdd import Recording
from pneufdd.errors import FileFormatError, InputError
from pneufdd.recording import MissingFileError, read_any
from recording_helpers import identical, rig_recording


def test_dispatch_by_suffix(tmp_path: Path) -> None:
    rec = rig_recording(seconds=0.2)
    parquet = rec.write(tmp_path / "RUN.PARQUET")
    assert identical(read_any(parquet), rec)
    csv = tmp_path / "run.csv"
    csv.write_text("time,p\n0.0,1\n0.001,2\n")
    from_csv = Recording.read(csv, column_map={"p": "P_In"}, units={"P_In": "bar"})
    assert from_csv.channel("P_In")[1].tolist() == [1.0e5, 2.0e5]
    tdms = tmp_path / "run.tdms"
    with TdmsWriter(tdms) as writer:
        writer.write_segment(
            [
                ChannelObject(
                    "AI", "P_In", np.array([1.0]), {"wf_increment": 0.001, "unit_string": "kPa"}
                )
            ]
        )
    assert Recording.read(tdms).channel("P_In")[1].tolist() == [1000.0]


def test_unknown_suffix_lists_those_allowed(tmp_path: Path) -> None:
    path = tmp_path / "run.mat"
    path.write_bytes(b"MATLAB 5.0")
    with pytest.raises(
        FileFormatError,
        match=r"run\.mat.*received '\.mat'; allowed: '\.parquet', '\.csv', '\.tdms'",
    ):
        read_any(path)


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(MissingFileError, match=r"nothing\.parquet.*does not exist"):
        Recording.read(tmp_path / "nothing.parquet")
    with pytest.raises(FileNotFoundError):
        read_any(tmp_path / "nothing.tdms")


def test_parquet_takes_no_options(tmp_path: Path) -> None:
    path = rig_recording(seconds=0.1).write(tmp_path / "r.parquet")
    with pytest.raises(InputError, match=r"options for a \.parquet file.*'units'"):
        read_any(path, units={"P_In": "Pa"})
