"""Tag maps: a PLC export under its own tag names -> a pneufdd recording (issue 10)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import ChannelError, InputError, UnitError
from pneufdd.physics.constants import ANR, DISSERTATION_STANDARD
from pneufdd.recording import Recording
from pneufdd.recording.plc_export import write_plc_csv
from pneufdd.recording.tag_map import load_tag_map, parse_tag_map, read_mapped
from pneufdd.sim import simulate

CSV = "t,B_P1,B_F1,Y1.0,B1.4\n0.000,6.0,100.0,0,0\n0.010,6.0,100.0,1,0\n0.020,5.5,200.0,1,1\n"
MAP = """
[columns]
"t"      = { role = "time", unit = "s" }
"B_P1"   = { role = "P_In", unit = "bar(g)" }
"B_F1"   = { role = "Q_In", unit = "l/min", basis = "ANR" }
"Y1.0"   = { role = "U_FEED_A" }
"B1.4"   = { role = "S_FEED_B" }
"""


def _files(tmp_path: Path, csv: str = CSV, tag_map: str = MAP) -> tuple[Path, Path]:
    data, mapping = tmp_path / "export.csv", tmp_path / "tags.toml"
    data.write_text(csv)
    mapping.write_text(tag_map)
    return data, mapping


def test_the_issue_map_reads_a_csv_in_si(tmp_path: Path) -> None:
    data, mapping = _files(tmp_path)
    rec = read_mapped(data, load_tag_map(mapping))
    assert rec.channels == ("P_In", "Q_In", "U_FEED_A", "S_FEED_B")
    assert rec.rate("P_In") == 100.0
    assert rec.channel("P_In")[1][0] == pytest.approx(7e5 + 1325.0)
    # 100 l/min at ISO 8778 (20 degC, 100 kPa, 1.185 kg/m^3 at 65 % RH) as mass flow
    assert rec.channel("Q_In")[1][0] == pytest.approx(100e-3 / 60 * ANR.density)
    assert rec.channel("U_FEED_A")[1].tolist() == [0, 1, 1]
    assert rec.metadata["source"]["tag_map"] == "tags.toml"


def test_slpm_basis_differs_from_anr(tmp_path: Path) -> None:
    data, mapping = _files(tmp_path, tag_map=MAP.replace('basis = "ANR"', 'basis = "SLPM"'))
    rec = read_mapped(data, load_tag_map(mapping))
    assert rec.channel("Q_In")[1][0] == pytest.approx(100e-3 / 60 * DISSERTATION_STANDARD.density)


@pytest.mark.parametrize(
    ("edit", "error", "words"),
    [
        (
            ('"B1.4"   = { role = "S_FEED_B" }', '"B1.4" = { role = "U_FEED_A" }'),
            ChannelError,
            "given to columns",
        ),
        (('unit = "bar(g)"', 'unit = "psi"'), UnitError, "psig"),
        (('unit = "bar(g)"', 'unit = "furlong"'), UnitError, "furlong"),
        ((', basis = "ANR"', ""), UnitError, "basis"),
        (('basis = "ANR"', 'basis = "NTP"'), UnitError, "NTP"),
        (('role = "P_In"', 'role = "pressure"'), InputError, "P_<ACT>_A/B"),
        (('"B1.4"   = { role = "S_FEED_B" }', ""), ChannelError, "B1.4"),
        (('"B1.4"', '"B9.9"'), ChannelError, "B9.9"),
    ],
)
def test_clear_errors(
    tmp_path: Path, edit: tuple[str, str], error: type[Exception], words: str
) -> None:
    data, mapping = _files(tmp_path, tag_map=MAP.replace(*edit))
    with pytest.raises(error, match=words.replace("(", r"\(").replace(")", r"\)")):
        read_mapped(data, load_tag_map(mapping))


def test_slow_rates_and_rate_mismatch_are_refused(tmp_path: Path) -> None:
    slow = CSV.replace("0.010", "0.100").replace("0.020", "0.200")
    data, mapping = _files(tmp_path, csv=slow)
    with pytest.raises(InputError, match="10 Hz"):
        read_mapped(data, load_tag_map(mapping))
    data, mapping = _files(tmp_path, tag_map="rate_hz = 1000\n" + MAP)
    with pytest.raises(InputError, match="1000 Hz"):
        read_mapped(data, load_tag_map(mapping))


def test_digital_role_with_a_unit_is_refused() -> None:
    with pytest.raises(UnitError, match="digital"):
        parse_tag_map({"columns": {"Y1.0": {"role": "U_FEED_A", "unit": "bar"}}})


def test_import_cli_round_trips_a_simulated_plc_export(tmp_path: Path) -> None:
    rec = simulate("press-fit-cell", cycles=2, seed=96_000_001)
    tags = write_plc_csv(rec, tmp_path / "plc.csv", tmp_path / "tags.toml")
    assert tags["U_FEED_A"].startswith("Y")
    assert tags["P_In"] == "B_P1"
    out = tmp_path / "rec.parquet"
    args = ["import", str(tmp_path / "plc.csv"), "--map", str(tmp_path / "tags.toml")]
    assert main([*args, "--out", str(out)]) == 0
    assert main([*args, "--out", str(out)]) == 2  # never overwrites
    back = Recording.read(out)
    assert set(back.channels) == set(rec.channels)
    p_sim, p_back = rec.channel("P_In")[1], back.channel("P_In")[1]
    assert np.nanmax(np.abs(p_back - p_sim)) < 1.0  # bar(g) to 5 decimals: < 1 Pa
    q_sim, q_back = rec.channel("Q_In")[1], back.channel("Q_In")[1]
    assert np.nanmax(np.abs(q_back - q_sim)) < 1e-7  # l/min to 4 decimals
    # the same map wherever a recording is read: steps straight from the CSV
    assert main(["steps", str(tmp_path / "plc.csv"), "--map", str(tmp_path / "tags.toml")]) == 0


def test_the_monitors_keys_do_not_change_the_import(tmp_path: Path) -> None:
    """One file for ``import --map`` and ``monitor --tags`` (docs/monitor.md)."""
    live = MAP.replace('unit = "bar(g)" }', 'unit = "bar(g)", rate_hz = 50 }').replace(
        'basis = "ANR" }', 'basis = "ANR", node = "ns=3;s=DB10.F1" }'
    )
    data, mapping = _files(tmp_path, tag_map='lateness_s = 2.0\nend = "ns=2;s=Done"\n' + live)
    parsed = load_tag_map(mapping)
    (tmp_path / "plain.toml").write_text(MAP)
    plain = read_mapped(data, load_tag_map(tmp_path / "plain.toml"))
    rec = read_mapped(data, parsed)
    for name in plain.channels:
        assert rec.channel(name)[1].tolist() == plain.channel(name)[1].tolist()
    assert parsed.lateness_s == 2.0
    assert parsed.end == "ns=2;s=Done"
    by_channel = {t.channel: t for t in parsed.live}
    assert by_channel["P_In"].tag == "B_P1"
    assert by_channel["P_In"].rate_hz == 50.0
    assert by_channel["Q_In"].node == "ns=3;s=DB10.F1"
    assert by_channel["Q_In"].unit == "l/min (ANR)"
    assert "time" not in by_channel


def test_the_channel_form_is_for_live_sources_only(tmp_path: Path) -> None:
    mapping = tmp_path / "live.toml"
    mapping.write_text('lateness_s = 0.5\n[channels.P_In]\nnode = "ns=2;s=P"\nrate_hz = 20\n')
    with pytest.raises(InputError, match=r"live\.toml.*channels") as info:
        load_tag_map(mapping)
    assert "columns" in str(info.value)
    parsed = load_tag_map(mapping, live=True)
    assert parsed.columns == ()
    assert [(t.channel, t.tag, t.node, t.rate_hz, t.unit) for t in parsed.live] == [
        ("P_In", "P_In", "ns=2;s=P", 20.0, None)
    ]
    assert parsed.lateness_s == 0.5
    data = _files(tmp_path)[0]
    with pytest.raises(InputError, match=r"live\.toml.*\[columns\]"):
        read_mapped(data, parsed)
