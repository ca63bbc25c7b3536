"""Field exports as the tools write them (issue 33 item 1): presets round-trip, errors."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import ChannelError, FileFormatError, InputError
from pneufdd.recording import Recording
from pneufdd.recording.field_export import EXPORT_FORMATS, write_field_export
from pneufdd.recording.tag_map import load_tag_map, parse_tag_map, read_mapped

START = datetime(2026, 11, 27, 14, 3, 5, 123000, tzinfo=ZoneInfo("Europe/Berlin"))
DIGITS = {"twincat-scope": 9, "tia-trace": 7, "codesys-trace": 7, "csv-de": 6}
"""Significant digits each export writes (TwinCAT: REAL32 in full)."""


def _run() -> Recording:
    rng = np.random.default_rng(33)
    n = 2000
    return Recording.from_arrays(
        {
            "P_In": 7.0e5 + 1.0e4 * rng.standard_normal(n),
            "Q_In": 2.0e-3 * rng.random(n),
            "X_DNC": 0.2 * rng.random(n),
        },
        1000.0,
        {"U_DNC_A": (np.arange(200) // 40) % 2, "S_DNC_B": (np.arange(200) // 70) % 2},
        100.0,
        units={"P_In": "Pa", "Q_In": "kg/s", "X_DNC": "m"},
        start_time=START,
    )


def _export(tmp_path: Path, fmt: str) -> tuple[Recording, Path, Path]:
    rec = _run()
    data, mapping = tmp_path / "export.csv", tmp_path / "tags.toml"
    mapping.write_text(write_field_export(rec, data, fmt))
    return rec, data, mapping


@pytest.mark.parametrize("fmt", EXPORT_FORMATS)
def test_each_preset_round_trips_within_the_exports_precision(tmp_path: Path, fmt: str) -> None:
    rec, data, mapping = _export(tmp_path, fmt)
    back = read_mapped(data, load_tag_map(mapping, preset=fmt))
    assert back.start_time == rec.start_time  # the export's wall-clock start is kept
    assert back.channels == rec.channels
    original, again = rec.to_pandas(), back.to_pandas()
    np.testing.assert_array_equal(original.index, again.index)
    for name in rec.channels:
        if name[0] in "US":  # bits are exact
            np.testing.assert_array_equal(original[name], again[name])
            continue
        # one unit in the last written digit of the largest value in the export unit
        scale = {"P": 1e5, "Q": 1.185e-3 / 60 * 1.0, "X": 1e-3}[name[0]]
        gauge = 101325.0 if name[0] == "P" else 0.0
        largest = float(np.max(np.abs(original[name] - gauge))) / scale
        if fmt == "twincat-scope":  # REAL32: half a unit in the 24th bit
            tolerance = largest * 2.0**-24 * scale
        else:
            tolerance = 10.0 ** (np.floor(np.log10(largest)) + 1 - DIGITS[fmt]) * scale
        error = float(np.max(np.abs(original[name] - again[name])))
        assert error <= tolerance, (name, error, tolerance)
    if fmt == "twincat-scope":  # one time column per sample time: rates kept
        assert (back.rate("P_In"), back.rate("U_DNC_A")) == (1000.0, 100.0)


def test_twincat_layout_as_the_scope_writes_it(tmp_path: Path) -> None:
    """A hand-written Scope View export: header block, 'Name' time columns, blank tail."""
    text = (
        "Name;Pneu\nFile;C:\\scope\\pneu.csv\n"
        "Starttime of export;134402581851230000;Freitag, 27. November 2026;14:03:05.123\n"
        "Endtime of export;134402581852230000;Freitag, 27. November 2026;14:03:05.223\n\n\n"
        "Name;MAIN.p1;Name;MAIN.y1\nSymbolComment;;SymbolComment;\n"
        "Data-Type;REAL32;Data-Type;BIT\nSampleTime[ms];1;SampleTime[ms];10\n\n"
        + "".join(
            f"{i};{6.0 + i / 100:.2f};{10 * i if i < 6 else ''};{i % 2 if i < 6 else ''}\n"
            for i in range(60)
        )
        + "EOF\n"
    )
    data, mapping = tmp_path / "scope.csv", tmp_path / "tags.toml"
    data.write_text(text)
    mapping.write_text(
        '[columns]\n"MAIN.p1" = { role = "P_In", unit = "bar(g)" }\n"MAIN.y1" = "U_A_A"\n'
    )
    rec = read_mapped(data, load_tag_map(mapping, preset="twincat-scope"))
    assert rec.start_time == datetime(2026, 11, 27, 13, 3, 5, 123000, tzinfo=UTC)
    assert (rec.rate("P_In"), rec.rate("U_A_A")) == (1000.0, 100.0)
    assert rec.channel("U_A_A")[1].tolist() == [0, 1, 0, 1, 0, 1]
    assert rec.channel("P_In")[1][59] == pytest.approx(6.59e5 + 101325.0)


def test_options_without_a_preset_german_locale(tmp_path: Path) -> None:
    data, mapping = tmp_path / "de.csv", tmp_path / "tags.toml"
    data.write_text(
        "Anlage;Presse 3\n\nZeit;Druck;Ventil\n"
        "27.11.2026 14:03:05,123;5,5;FALSCH\n27.11.2026 14:03:05,133;5,25;WAHR\n"
        "27.11.2026 14:03:05,143;5,0;WAHR\n"
    )
    mapping.write_text(
        'delimiter = ";"\ndecimal = ","\nskip_rows = "auto"\n'
        'true_values = ["WAHR"]\nfalse_values = ["FALSCH"]\n[columns]\n'
        '"Zeit" = { role = "time", unit = "datetime", format = "%d.%m.%Y %H:%M:%S,%f", '
        'timezone = "Europe/Berlin" }\n"Druck" = { role = "P_In", unit = "bar(g)" }\n'
        '"Ventil" = "U_A_A"\n'
    )
    rec = read_mapped(data, load_tag_map(mapping))
    assert (rec.start_time, rec.rate("P_In")) == (START, 100.0)
    assert rec.channel("P_In")[1].tolist() == pytest.approx([651325.0, 626325.0, 601325.0])
    assert rec.channel("U_A_A")[1].tolist() == [0, 1, 1]


def test_several_time_columns_named_per_channel(tmp_path: Path) -> None:
    data, mapping = tmp_path / "two.csv", tmp_path / "tags.toml"
    rows = "".join(
        f"{i},{7.0 - i / 1000:.4f},{10 * i if i < 5 else ''},{i % 2 if i < 5 else ''}\n"
        for i in range(50)
    )
    data.write_text("t_fast,p,t_slow,y\n" + rows)
    mapping.write_text(
        'start_time = "2026-11-27T14:03:05.123+01:00"\n[columns]\n'
        '"t_fast" = { role = "time", unit = "ms" }\n"t_slow" = { role = "time", unit = "ms" }\n'
        '"p" = { role = "P_In", unit = "bar", time = "t_fast" }\n'
        '"y" = { role = "U_A_A", time = "t_slow" }\n'
    )
    rec = read_mapped(data, load_tag_map(mapping))
    assert rec.start_time == START
    assert (rec.rate("P_In"), rec.rate("U_A_A")) == (1000.0, 100.0)
    assert rec.channel("U_A_A")[1].tolist() == [0, 1, 0, 1, 0]


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({"preset": "excel"}, "twincat-scope"),
        ({"skip_rows": -1}, "auto"),
        ({"delimiter": ";", "decimal": ";"}, "decimal"),
        ({"true_values": ["1"], "false_values": ["1"]}, "each in one"),
        ({"timezone": "Mars/Olympus"}, "IANA"),
        ({"start_time": "yesterday"}, "ISO 8601"),
    ],
)
def test_layout_options_are_validated(options: dict[str, object], words: str) -> None:
    columns = {"t": {"role": "time", "unit": "ms"}, "y": {"role": "U_A_A"}}
    with pytest.raises(InputError, match=words):
        parse_tag_map({**options, "columns": columns}, "tags.toml")


def test_time_unit_and_channel_time_are_validated() -> None:
    with pytest.raises(InputError, match="'minutes'"):
        parse_tag_map({"columns": {"t": {"role": "time", "unit": "minutes"}, "y": "U_A_A"}})
    with pytest.raises(InputError, match="only with unit = 'datetime'"):
        parse_tag_map({"columns": {"t": {"role": "time", "format": "%H"}, "y": "U_A_A"}})
    with pytest.raises(InputError, match="t_slow"):
        parse_tag_map(
            {"columns": {"t": {"role": "time"}, "y": {"role": "U_A_A", "time": "t_slow"}}}
        )


def _cli(*args: str) -> int:
    return main([str(a) for a in args])


@pytest.mark.parametrize(
    ("fmt", "edit", "error", "words"),
    [
        # a missing column: the map names a tag the export does not have
        ("tia-trace", ('"DB_Pneu".X_DNC', '"DB_Pneu".X_DNC2'), ChannelError, "X_DNC2"),
        # a bad decimal: the map says ',' but the file writes '.'
        (
            "twincat-scope",
            ("[columns]", 'decimal = ","\n[columns]'),
            FileFormatError,
            "decimal mark",
        ),
        # a wrong time unit: ms read as s gives 1 Hz
        (
            "tia-trace",
            ("[columns]", '[columns]\n"Time [ms]" = { role = "time", unit = "s" }'),
            InputError,
            "time unit",
        ),
    ],
)
def test_error_cases_name_file_and_column_with_exit_2(
    tmp_path: Path,
    fmt: str,
    edit: tuple[str, str],
    error: type[Exception],
    words: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    _, data, mapping = _export(tmp_path, fmt)
    text = mapping.read_text()
    if "X_DNC2" in edit[1]:
        text = text.replace('\\"DB_Pneu\\".X_DNC"', '\\"DB_Pneu\\".X_DNC2"')
    else:
        text = text.replace(*edit)
    mapping.write_text(text)
    with pytest.raises(error, match=words):
        read_mapped(data, load_tag_map(mapping, preset=fmt))
    assert (
        _cli("import", data, "--format", fmt, "--map", mapping, "--out", tmp_path / "r.parquet")
        == 2
    )
    message = capsys.readouterr().err
    assert "export.csv" in " ".join(message.split())


@pytest.mark.parametrize("fmt", ["twincat-scope", "tia-trace", "csv-de"])
def test_simulate_export_then_import_end_to_end(tmp_path: Path, fmt: str) -> None:
    csv_path, parquet = tmp_path / "run.csv", tmp_path / "run.parquet"
    twin = tmp_path / "twin.parquet"
    assert _cli("simulate", "--cycles", "1", "--out", twin) == 0
    assert _cli("simulate", "--cycles", "1", "--export-format", fmt, "--out", csv_path) == 0
    assert (
        _cli(
            "import",
            csv_path,
            "--format",
            fmt,
            "--map",
            csv_path.with_suffix(".toml"),
            "--out",
            parquet,
        )
        == 0
    )
    original, back = Recording.read(twin), Recording.read(parquet)
    assert back.channels == original.channels
    assert back.start_time == original.start_time
    a, b = original.to_pandas(), back.to_pandas()
    for name in original.channels:
        if name[0] in "US":
            np.testing.assert_array_equal(a[name], b[name])
        else:
            span = float(np.max(np.abs(a[name]))) + 1e-30
            assert float(np.max(np.abs(a[name] - b[name]))) <= 1e-5 * span, name


def test_simulate_export_options_are_checked(tmp_path: Path) -> None:
    assert _cli("simulate", "--export-format", "excel", "--out", tmp_path / "r.csv") == 2
    assert _cli("simulate", "--export-format", "csv-de", "--out", tmp_path / "r.parquet") == 2
    assert (
        _cli("simulate", "--export-map", tmp_path / "m.toml", "--out", tmp_path / "r.parquet") == 2
    )
