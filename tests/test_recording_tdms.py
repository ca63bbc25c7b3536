"""TDMS reader: waveform timing, units, digital detection, naming and clear errors."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

from pneufdd.errors import ChannelError, FileFormatError, UnitError
from pneufdd.recording import MissingFileError, read_parquet, read_tdms, write_parquet
from recording_helpers import identical

START = np.datetime64("2011-06-14T09:30:00.000000")
PA_AT_90_PSIG = 90 * 6894.757293168361 + 101325.0
KG_S_AT_200_SLPM = 200.0e-3 / 60.0 * 1.294


def _wave(group: str, name: str, data: Any, dt: float | None, **props: Any) -> ChannelObject:
    properties = dict(props)
    if dt is not None:
        properties["wf_increment"] = dt
    return ChannelObject(group, name, np.asarray(data), properties=properties)


def _write(path: Path, *channels: ChannelObject, **root: Any) -> Path:
    with TdmsWriter(path) as writer:
        writer.write_segment([RootObject(root), *channels])
    return path


def _rig(tmp_path: Path) -> Path:
    return _write(
        tmp_path / "rig.tdms",
        GroupObject("AI"),
        _wave("AI", "P_In", [90.0, 0.0, 45.0], 0.001, unit_string="psig", wf_start_time=START),
        _wave(
            "AI",
            "Q_In",
            np.array([200.0, 0.0], np.float32),
            0.001,
            unit_string="SLPM",
            wf_start_time=START + np.timedelta64(250, "ms"),
            wf_start_offset=0.002,
        ),
        _wave("DI", "U_DNC_A", np.array([0, 1, 1], np.uint8), 0.01, wf_start_time=START),
        _wave("DI", "S_DNC_B", np.array([True, False]), 0.01, wf_start_time=START),
        author="test rig",
    )


def test_reads_rates_offsets_units_and_digital(tmp_path: Path) -> None:
    rec = read_tdms(_rig(tmp_path))
    assert rec.channels == ("P_In", "Q_In", "U_DNC_A", "S_DNC_B")
    assert rec.analog_channels == ("P_In", "Q_In")
    assert rec.digital_channels == ("U_DNC_A", "S_DNC_B")
    assert rec.rate("P_In") == 1000.0
    assert rec.rate("U_DNC_A") == 100.0
    _, p = rec.channel("P_In")
    assert p[0] == pytest.approx(PA_AT_90_PSIG, rel=1e-15)
    assert p[1] == 101325.0
    _, q = rec.channel("Q_In")
    assert q[0] == pytest.approx(KG_S_AT_200_SLPM, rel=1e-7)  # stored as float32 in the file
    assert q.dtype == np.float64
    assert rec.unit("Q_In") == "kg/s"
    assert rec.channel("U_DNC_A")[1].tolist() == [0, 1, 1]
    assert rec.channel("S_DNC_B")[1].tolist() == [1, 0]
    assert rec.info("S_DNC_B").values.dtype == np.uint8
    assert rec.start_time == datetime(2011, 6, 14, 9, 30, tzinfo=UTC)
    assert rec.info("P_In").t0 == 0.0
    assert rec.info("Q_In").t0 == pytest.approx(0.252, abs=1e-12)  # 250 ms later + 2 ms offset
    assert rec.metadata["source"]["format"] == "tdms"
    assert rec.metadata["source"]["properties"] == {"author": "test rig"}
    assert identical(read_parquet(write_parquet(rec, tmp_path / "rig.parquet")), rec)


def test_channel_map_selects_and_renames(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "daq.tdms",
        _wave("Dev1", "ai0", [6.0, 5.0], 0.001, unit_string="bar(g)"),
        _wave("Dev1", "ai1", [1.0, 2.0], 0.001, unit_string="V"),
        _wave("Dev1", "port0/line0", np.array([1, 0], np.uint8), 0.01),
    )
    rec = read_tdms(path, {"Dev1/port0/line0": "U_DNC_A", "ai0": "P_In"})
    assert rec.channels == ("U_DNC_A", "P_In")
    assert rec.channel("P_In")[1].tolist() == [701325.0, 601325.0]
    with pytest.raises(ChannelError, match=r"daq\.tdms.*channel_map key not in the file.*'ai9'"):
        read_tdms(path, {"ai9": "P_In"})


def test_units_argument_overrides_and_missing_unit_errors(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "u.tdms",
        _wave("AI", "X_DNC", [12.5, 200.0], 0.001),
        _wave("AI", "P_In", [6.0], 0.001, unit_string="psi"),
    )
    with pytest.raises(
        UnitError, match=r"unit of channel 'X_DNC' \(TDMS AI/X_DNC\) in file .*u\.tdms"
    ):
        read_tdms(path)
    with pytest.raises(UnitError, match=r"ambiguous unit.*'P_In'.*'psia'.*'psig'"):
        read_tdms(path, units={"X_DNC": "mm"})
    rec = read_tdms(path, units={"X_DNC": "mm", "P_In": "bar(g)"})
    assert rec.channel("X_DNC")[1].tolist() == [0.0125, 0.2]
    assert rec.unit("X_DNC") == "m"
    assert rec.channel("P_In")[1].tolist() == [701325.0]
    with pytest.raises(ChannelError, match="units names channels not read"):
        read_tdms(path, units={"Q_In": "SLPM"})


def test_integer_channels_are_digital_unless_told(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "int.tdms", _wave("AI", "raw", np.array([0, 2047, 4095], np.int16), 0.001)
    )
    with pytest.raises(ChannelError, match=r"int\.tdms.*integer dtype int16.*digital=\[\]"):
        read_tdms(path)
    rec = read_tdms(path, units={"raw": "V"}, digital=[])
    assert rec.analog_channels == ("raw",)
    assert rec.channel("raw")[1].tolist() == [0.0, 2047.0, 4095.0]
    floats = _write(tmp_path / "f.tdms", _wave("DI", "U", [0.0, 1.0], 0.01))
    rec = read_tdms(floats, digital=["U"])
    assert rec.digital_channels == ("U",)
    assert rec.info("U").values.dtype == np.uint8


def test_odd_rates_snap_to_their_round_value(tmp_path: Path) -> None:
    path = _write(tmp_path / "r.tdms", _wave("AI", "P", [1.0, 2.0], 1.0 / 3000.0, unit_string="Pa"))
    assert read_tdms(path).rate("P") == 3000.0


def test_missing_wf_increment_is_a_clear_error(tmp_path: Path) -> None:
    path = _write(tmp_path / "nowf.tdms", _wave("AI", "P_In", [1.0, 2.0], None, unit_string="Pa"))
    with pytest.raises(FileFormatError, match=r"nowf\.tdms.*AI/P_In wf_increment.*received None"):
        read_tdms(path)


def test_same_channel_name_in_two_groups(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "two.tdms",
        _wave("run1", "P_In", [1.0], 0.001, unit_string="Pa"),
        _wave("run2", "P_In", [2.0], 0.001, unit_string="Pa"),
    )
    with pytest.raises(
        ChannelError, match=r"run1/P_In' and 'run2/P_In' both become channel 'P_In'"
    ):
        read_tdms(path)
    with pytest.raises(
        ChannelError, match=r"'P_In' is in several groups.*'run1/P_In', 'run2/P_In'"
    ):
        read_tdms(path, {"P_In": "P_In"})
    rec = read_tdms(path, {"run2/P_In": "P_In"})
    assert rec.channel("P_In")[1].tolist() == [2.0]


def test_bad_files(tmp_path: Path) -> None:
    with pytest.raises(MissingFileError, match=r"absent\.tdms.*does not exist"):
        read_tdms(tmp_path / "absent.tdms")
    empty = tmp_path / "empty.tdms"
    empty.write_bytes(b"")
    with pytest.raises(FileFormatError, match=r"empty\.tdms.*empty"):
        read_tdms(empty)
    text = tmp_path / "text.tdms"
    text.write_text("time,P_In\n0,1\n" * 10)
    with pytest.raises(FileFormatError, match=r"text\.tdms.*not a readable TDMS file"):
        read_tdms(text)


@pytest.mark.parametrize("fraction", [0.3, 0.5, 0.9])
def test_truncated_file_names_it(tmp_path: Path, fraction: float) -> None:
    data = _rig(tmp_path).read_bytes()
    cut = tmp_path / "cut.tdms"
    cut.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(FileFormatError, match=r"cut\.tdms.*(truncated|not a readable)"):
        read_tdms(cut)


def test_given_start_time_sets_offsets(tmp_path: Path) -> None:
    start = datetime(2011, 6, 14, 9, 29, 59, tzinfo=UTC)  # one second before the waveforms
    rec = read_tdms(_rig(tmp_path), start_time=start, metadata={"machine": "festo-dsd"})
    assert rec.start_time == start
    assert rec.info("P_In").t0 == 1.0
    assert rec.info("Q_In").t0 == pytest.approx(1.252, abs=1e-12)
    assert rec.metadata["machine"] == "festo-dsd"
    assert rec.metadata["source"]["file"] == "rig.tdms"
    with pytest.raises(ChannelError, match=r"digital names channels not read.*'U_XYZ'"):
        read_tdms(_rig(tmp_path), digital=["U_XYZ"])


def test_labview_zero_timestamp_means_unset(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "zero.tdms",
        _wave(
            "AI", "P_In", [1.0], 0.001, unit_string="Pa", wf_start_time=np.datetime64("1904-01-01")
        ),
    )
    rec = read_tdms(path)
    assert rec.start_time == datetime(1970, 1, 1, tzinfo=UTC)
    assert rec.info("P_In").t0 == 0.0
