"""CSV reader: column map, unit conversion to SI, time checks, clear errors."""

from __future__ import annotations

import tempfile
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import ChannelError, FileFormatError, InputError, UnitError
from pneufdd.recording import MissingFileError, read_csv, read_parquet, write_parquet
from recording_helpers import identical

# 1 psi = 6894.757293168361 Pa (NIST SP 811); gauge zero 101325 Pa (docs/assumptions.md)
PA_AT_90_PSIG = 90 * 6894.757293168361 + 101325.0  # 721853.1563851525 Pa
# 200 SLPM at the dissertation's standard density 1.294 kg/m^3 (section 3.4.1)
KG_S_AT_200_SLPM = 200.0e-3 / 60.0 * 1.294  # 0.0043133... kg/s

MAP = {"Supply [psig]": "P_In", "Flow [SLPM]": "Q_In", "Valve": "U_DNC_A"}
UNITS = {"P_In": "psig", "Q_In": "SLPM"}


def _write(tmp_path: Path, text: str, name: str = "run.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _rig_csv(tmp_path: Path) -> Path:
    return _write(
        tmp_path,
        "time,Supply [psig],Flow [SLPM],Valve,unused\n"
        "0.500,90,200,0,x\n"
        "0.501,90.5,,1,x\n"
        "0.502,0,0,1,x\n",
    )


def test_reads_and_converts_to_si_exactly(tmp_path: Path) -> None:
    rec = read_csv(_rig_csv(tmp_path), MAP, UNITS, digital=["U_DNC_A"])
    assert rec.channels == ("P_In", "Q_In", "U_DNC_A")
    _, p = rec.channel("P_In")
    _, q = rec.channel("Q_In")
    _, u = rec.channel("U_DNC_A")
    assert p[0] == pytest.approx(PA_AT_90_PSIG, rel=1e-15)
    assert p[0] == pytest.approx(721853.15638515, abs=1e-6)
    assert p[2] == 101325.0  # 0 psig is one standard atmosphere
    assert q[0] == pytest.approx(KG_S_AT_200_SLPM, rel=1e-15)
    assert np.isnan(q[1])  # blank cell
    assert q[2] == 0.0
    assert u.dtype == np.uint8
    assert u.tolist() == [0, 1, 1]
    assert rec.unit("P_In") == "Pa"
    assert rec.unit("Q_In") == "kg/s"
    assert rec.unit("U_DNC_A") == "1"
    assert rec.rate("P_In") == 1000.0
    assert rec.info("P_In").t0 == 0.5
    assert rec.metadata == {"source": {"format": "csv", "file": "run.csv"}}


def test_start_time_metadata_and_parquet_round_trip(tmp_path: Path) -> None:
    start = datetime(2011, 6, 14, 9, 30, tzinfo=UTC)
    rec = read_csv(
        _rig_csv(tmp_path),
        MAP,
        UNITS,
        digital=["U_DNC_A"],
        start_time=start,
        metadata={"machine": "festo-dsd"},
    )
    assert rec.start_time == start
    assert rec.metadata["machine"] == "festo-dsd"
    assert identical(read_parquet(write_parquet(rec, tmp_path / "run.parquet")), rec)


def test_long_file_gets_the_round_rate_and_matches_pandas(tmp_path: Path) -> None:
    n = 5000
    time = np.arange(n) / 1000.0
    pressure = 80.0 + np.sin(time)
    frame = pd.DataFrame({"t": time, "p": pressure})
    path = tmp_path / "long.csv"
    frame.to_csv(path, index=False, float_format="%.6f")
    rec = read_csv(path, {"p": "P_In"}, {"P_In": "bar(g)"}, time_column="t")
    assert rec.rate("P_In") == 1000.0  # not 999.9999999999999
    oracle = pd.read_csv(path)["p"].to_numpy() * 1e5 + 101325.0
    assert np.array_equal(rec.channel("P_In")[1], oracle)


def test_small_jitter_within_tolerance_is_accepted(tmp_path: Path) -> None:
    rows = "".join(f"{i * 0.01 + (2e-5 if i % 2 else 0.0):.6f},{i % 2}\n" for i in range(50))
    path = _write(tmp_path, "time,S\n" + rows)
    rec = read_csv(path, {"S": "S_DNC_A"}, {}, digital=["S_DNC_A"])
    assert rec.rate("S_DNC_A") == pytest.approx(100.0, rel=1e-3)
    with pytest.raises(InputError, match="not uniformly sampled"):
        read_csv(path, {"S": "S_DNC_A"}, {}, digital=["S_DNC_A"], rate_tolerance=0.001)


def test_drifting_clock_is_not_uniform(tmp_path: Path) -> None:
    # every step 0.05 % longer than the one before: each step looks fine, the grid drifts
    steps = 0.001 * 1.0005 ** np.arange(60)
    time = np.concatenate([[0.0], np.cumsum(steps)])
    rows = "".join(f"{t:.9f},1\n" for t in time)
    path = _write(tmp_path, "time,p\n" + rows)
    with pytest.raises(InputError, match=r"line \d+ \(t = .* s off the uniform grid"):
        read_csv(path, {"p": "P_In"}, {"P_In": "Pa"}, rate_tolerance=0.05)


def test_non_increasing_time_names_file_and_line(tmp_path: Path) -> None:
    path = _write(tmp_path, "time,p\n0.000,1\n0.001,1\n0.002,1\n0.002,1\n0.004,1\n")
    with pytest.raises(InputError, match=r"run\.csv', line 5: time is not strictly increasing"):
        read_csv(path, {"p": "P_In"}, {"P_In": "Pa"})
    backwards = _write(tmp_path, "time,p\n0.000,1\n0.001,1\n0.0005,1\n", "back.csv")
    with pytest.raises(InputError, match=r"back\.csv', line 4: .*0\.0005 s follows 0\.001 s"):
        read_csv(backwards, {"p": "P_In"}, {"P_In": "Pa"})


def test_gap_in_time_is_not_uniform(tmp_path: Path) -> None:
    rows = "".join(f"{t:.3f},1\n" for t in [0.0, 0.001, 0.002, 0.003, 0.006, 0.007])
    path = _write(tmp_path, "time,p\n" + rows)
    with pytest.raises(InputError) as info:
        read_csv(path, {"p": "P_In"}, {"P_In": "Pa"})
    message = str(info.value)
    assert "run.csv" in message
    assert "not uniformly sampled" in message
    assert "the step to line 6 is 0.003 s where the median step is 0.001 s (1000 Hz)" in message
    assert "resample" in message
    assert "rate_tolerance" in message


def test_blank_time_and_text_cells(tmp_path: Path) -> None:
    blank = _write(tmp_path, "time,p\n0.000,1\n,1\n0.002,1\n", "blank.csv")
    with pytest.raises(FileFormatError, match=r"blank\.csv', line 3: time column 'time' is blank"):
        read_csv(blank, {"p": "P_In"}, {"P_In": "Pa"})
    text = _write(tmp_path, "time,p\n0.000,1\n0.001,abc\n", "text.csv")
    with pytest.raises(FileFormatError, match=r"text\.csv', line 3, column 'p'.*'abc'"):
        read_csv(text, {"p": "P_In"}, {"P_In": "Pa"})


def test_digital_values_must_be_zero_or_one(tmp_path: Path) -> None:
    path = _write(tmp_path, "time,v\n0.00,0\n0.01,1\n0.02,2\n")
    with pytest.raises(ChannelError, match=r"line 4: value of digital channel 'U_DNC_A'.*2\.0"):
        read_csv(path, {"v": "U_DNC_A"}, {}, digital=["U_DNC_A"])
    blank = _write(tmp_path, "time,v\n0.00,0\n0.01,\n", "blank.csv")
    with pytest.raises(ChannelError, match=r"line 3: value of digital channel"):
        read_csv(blank, {"v": "U_DNC_A"}, {}, digital=["U_DNC_A"])


def test_map_errors(tmp_path: Path) -> None:
    path = _rig_csv(tmp_path)
    with pytest.raises(ChannelError, match=r"column\(s\) not in the file.*'Pressure'.*'time'"):
        read_csv(path, {"Pressure": "P_In"}, {"P_In": "Pa"})
    with pytest.raises(ChannelError, match="target of columns 'Supply \\[psig\\]' and 'Flow"):
        read_csv(path, {"Supply [psig]": "P_In", "Flow [SLPM]": "P_In"}, {"P_In": "psig"})
    with pytest.raises(ChannelError, match="digital"):
        read_csv(path, MAP, UNITS, digital=["U_XYZ"])
    with pytest.raises(ChannelError, match="time column"):
        read_csv(path, {"time": "T"}, {"T": "s"})
    with pytest.raises(ChannelError, match="units given for channels not in column_map"):
        read_csv(path, MAP, {**UNITS, "X_DNC": "mm"}, digital=["U_DNC_A"])


def test_unit_errors(tmp_path: Path) -> None:
    path = _rig_csv(tmp_path)
    with pytest.raises(UnitError, match=r"unknown unit of channel 'P_In'.*'furlong'.*'psig'"):
        read_csv(path, MAP, {"P_In": "furlong", "Q_In": "SLPM"}, digital=["U_DNC_A"])
    with pytest.raises(UnitError, match=r"ambiguous unit.*'psia'.*'psig'.*received 'psi'"):
        read_csv(path, MAP, {"P_In": "psi", "Q_In": "SLPM"}, digital=["U_DNC_A"])
    with pytest.raises(UnitError, match=r"unit of channel 'Q_In'.*pass units="):
        read_csv(path, MAP, {"P_In": "psig"}, digital=["U_DNC_A"])
    with pytest.raises(UnitError, match=r"digital"):
        read_csv(path, MAP, {**UNITS, "U_DNC_A": "V"}, digital=["U_DNC_A"])


def test_file_errors(tmp_path: Path) -> None:
    with pytest.raises(MissingFileError, match=r"absent\.csv.*does not exist"):
        read_csv(tmp_path / "absent.csv", MAP, UNITS)
    empty = _write(tmp_path, "", "empty.csv")
    with pytest.raises(FileFormatError, match=r"empty\.csv.*empty"):
        read_csv(empty, MAP, UNITS)
    header_only = _write(tmp_path, "time,p\n", "header.csv")
    with pytest.raises(FileFormatError, match=r"header\.csv.*number of data rows.*>= 2"):
        read_csv(header_only, {"p": "P_In"}, {"P_In": "Pa"})
    duplicate = _write(tmp_path, "time,p,p\n0,1,1\n0.1,1,1\n", "dup.csv")
    with pytest.raises(FileFormatError, match=r"dup\.csv.*duplicate column names.*'p'"):
        read_csv(duplicate, {"p": "P_In"}, {"P_In": "Pa"})
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00\x81garbage")
    with pytest.raises(
        FileFormatError, match=r"binary\.csv.*not a text file in encoding 'utf-8-sig'"
    ):
        read_csv(binary, {"p": "P_In"}, {"P_In": "Pa"})


def test_european_export_and_trailing_blank_lines(tmp_path: Path) -> None:
    path = tmp_path / "eu.csv"
    path.write_bytes(
        "Zeit;Druck [bar(g)];Temperatur\n0,00;6,5;20,0\n0,01;6,0;20,5\n\n\n".encode("latin-1")
    )
    rec = read_csv(
        path,
        {"Druck [bar(g)]": "P_In", "Temperatur": "T_In"},
        {"P_In": "bar(g)", "T_In": "degC"},
        time_column="Zeit",
        delimiter=";",
        decimal=",",
        encoding="latin-1",
    )
    assert rec.channel("P_In")[1].tolist() == [751325.0, 701325.0]
    assert rec.channel("T_In")[1].tolist() == [293.15, 293.65]
    assert rec.rate("P_In") == 100.0
    bad = tmp_path / "bad_eu.csv"
    bad.write_text("Zeit;p\n0,00;6,5\n0,01;6.5\n")
    with pytest.raises(FileFormatError, match=r"line 3, column 'p'.*'6\.5'"):
        read_csv(bad, {"p": "P_In"}, {"P_In": "Pa"}, time_column="Zeit", delimiter=";", decimal=",")


def test_spaces_after_delimiters_and_ragged_rows(tmp_path: Path) -> None:
    path = _write(tmp_path, "time, p\n0.000, 1\n0.001, 2\n")
    assert read_csv(path, {"p": "P_In"}, {"P_In": "kPa"}).channel("P_In")[1].tolist() == [
        1000.0,
        2000.0,
    ]
    ragged = _write(tmp_path, "time,p\n0.000,1\n0.001,2,3,4\n", "ragged.csv")
    with pytest.raises(FileFormatError, match=r"ragged\.csv.* is not valid CSV"):
        read_csv(ragged, {"p": "P_In"}, {"P_In": "Pa"})


@given(
    rate=st.one_of(
        st.sampled_from([1000.0, 100.0, 2048.0, 10.0, 1.0 / 3.0, 44100.0]),
        st.floats(min_value=0.5, max_value=1e5),
    ),
    t0=st.floats(min_value=-10.0, max_value=10.0),
    values=st.lists(
        st.floats(min_value=-1e9, max_value=1e9).filter(lambda v: v != 0.0),
        min_size=2,
        max_size=400,
    ),
)
def test_any_uniform_csv_reads_back_exactly(rate: float, t0: float, values: list[float]) -> None:
    time = t0 + np.arange(len(values)) / rate
    text = "time,p\n" + "".join(f"{float(t)!r},{v!r}\n" for t, v in zip(time, values, strict=True))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "p.csv"
        path.write_text(text)
        rec = read_csv(path, {"p": "P_In"}, {"P_In": "Pa"})
    read_time, read_values = rec.channel("P_In")
    assert read_values.tolist() == values  # bit-exact through the "Pa" identity conversion
    assert rec.info("P_In").t0 == time[0]
    # the (possibly snapped) rate puts every sample within 1e-6 of an interval of its time
    assert np.max(np.abs(read_time - time)) <= 1e-6 / rec.rate("P_In") + 1e-12 * (1 + abs(t0))
    if rate in (1000.0, 100.0, 2048.0, 10.0, 44100.0):
        assert rec.rate("P_In") == rate
