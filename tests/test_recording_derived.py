"""Channels a tag map derives (issue 33): end switches from a position, a flow from two meters."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import ChannelError, InputError
from pneufdd.features.step_summaries import build_step_table, machine_sequence, segment_cycles
from pneufdd.physics.constants import ANR
from pneufdd.recording import Recording
from pneufdd.recording.tag_map import load_tag_map, parse_tag_map, read_mapped
from pneufdd.sim import as_exported, load_machine, simulate

RIG = Path(__file__).parent / "data" / "triggered-rig.toml"
EDGE_TOLERANCE_S = 0.010
"""Derived switch edges against the twin's switches: one PLC sample (100 Hz) [s]."""


@pytest.fixture(scope="module")
def rig_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Recording, Path]:
    """A 6-cycle rig run as exported, and the same run saved without its end switches."""
    rec = as_exported(simulate(load_machine(RIG), cycles=6, seed=2_600_001))
    path = tmp_path_factory.mktemp("derived") / "no-switches.parquet"
    rec.select([c for c in rec.channels if not c.startswith("S_")]).write(path)
    return rec, path


def _rig_map(rec: Recording, switches: dict[str, dict[str, object]]) -> dict[str, object]:
    columns: dict[str, object] = {}
    for name in rec.channels:
        if name.startswith("S_"):
            continue
        info = rec.info(name)
        columns[name] = {"role": name, **({"unit": info.unit} if info.kind == "analog" else {})}
    return {"columns": columns, "switches": switches}


def _edges(rec: Recording, name: str) -> np.ndarray:
    t, v = rec.channel(name)
    return t[1:][np.diff(v.astype(np.int8)) != 0]


def test_learned_switches_segment_like_the_real_ones(rig_run: tuple[Recording, Path]) -> None:
    rec, path = rig_run
    learned = {"S_CYL_A": {"position": "X_CYL"}, "S_CYL_B": {"position": "X_CYL"}}
    derived = read_mapped(path, parse_tag_map(_rig_map(rec, learned), "rig.toml"))
    how = derived.metadata["derived_switches"]
    # the rule: plateau +- tol, tol = max(4 sigma, 0.5 % of the travel, one step); the
    # rig's 200 mm travel makes it 1.0 mm, the twin's own switch window
    assert how["S_CYL_A"]["plateau_m"] == pytest.approx(0.0, abs=2e-4)
    assert how["S_CYL_B"]["plateau_m"] == pytest.approx(0.200, abs=2e-4)
    assert how["S_CYL_A"]["on_m"] == pytest.approx(how["S_CYL_A"]["plateau_m"] + 1.0e-3, rel=0.01)
    assert how["S_CYL_B"]["off_m"] == pytest.approx(how["S_CYL_B"]["plateau_m"] - 2.0e-3, rel=0.01)
    assert derived.rate("S_CYL_A") == rec.rate("U_CYL_A")  # on the PLC's clock
    for name in ("S_CYL_A", "S_CYL_B"):
        real, made = _edges(rec, name), _edges(derived, name)
        assert real.size == made.size == 12
        assert np.max(np.abs(real - made)) <= EDGE_TOLERANCE_S + 1e-9
    sequence = machine_sequence(load_machine(RIG))
    cycles_real, _, _ = segment_cycles(rec, sequence, "real")
    cycles_made, _, _ = segment_cycles(derived, sequence, "derived")
    assert [c.complete for c in cycles_made] == [c.complete for c in cycles_real]
    good_real = [c for c in cycles_real if c.complete]
    good_made = [c for c in cycles_made if c.complete]
    assert len(good_made) == 5
    real = build_step_table(rec, good_real, "triggered-rig")
    made = build_step_table(derived, good_made, "triggered-rig")
    # steps start at valve firings: identical; the step table to the last bit
    np.testing.assert_array_equal(made.step_start, real.step_start)
    np.testing.assert_array_equal(made.step_end, real.step_end)
    np.testing.assert_array_equal(made.features(), real.features())


def test_given_thresholds_and_hysteresis(rig_run: tuple[Recording, Path]) -> None:
    rec, path = rig_run
    given = {
        "S_CYL_A": {"position": "X_CYL", "below": 1.0, "unit": "mm", "hysteresis": 0.5},
        "S_CYL_B": {"position": "X_CYL", "above": 0.199},  # the position column's unit, m
    }
    derived = read_mapped(path, parse_tag_map(_rig_map(rec, given), "rig.toml"))
    how = derived.metadata["derived_switches"]
    assert (how["S_CYL_A"]["on_m"], how["S_CYL_A"]["off_m"]) == pytest.approx((1e-3, 1.5e-3))
    assert how["S_CYL_B"]["on_m"] == pytest.approx(0.199)
    assert how["S_CYL_B"]["rule"] == "given: above the threshold"
    x_t, x = rec.channel("X_CYL")
    _, s_b = derived.channel("S_CYL_B")
    t_b = derived.channel("S_CYL_B")[0]
    # wherever the PLC saw the switch on, the last position sample was within the band
    k = np.searchsorted(x_t, t_b, side="right") - 1
    off_at = how["S_CYL_B"]["off_m"]
    assert np.all(x[k[s_b == 1]] >= off_at)
    assert np.all(x[k[s_b == 0]] < 0.199)


def test_no_plateau_is_a_clear_error(rig_run: tuple[Recording, Path], tmp_path: Path) -> None:
    rec, _ = rig_run
    # the first 1.2 s: the rod leaves home and extends, but is cut before it rests at
    # the extended end long enough to count
    _, x = rec.channel("X_CYL")
    stop = int(np.argmax(x >= 0.1995)) + 20  # 20 ms at the end: less than 50 ms
    cut = Recording.from_arrays(
        {"X_CYL": x[:stop]},
        1000.0,
        units={"X_CYL": "m"},
        digital={"U_CYL_A": rec.channel("U_CYL_A")[1][: stop // 10]},
        digital_rate_hz=100.0,
    )
    path = tmp_path / "cut.parquet"
    cut.write(path)
    tags = {
        "columns": {"X_CYL": {"role": "X_CYL", "unit": "m"}, "U_CYL_A": {"role": "U_CYL_A"}},
        "switches": {"S_CYL_B": {"position": "X_CYL"}},
    }
    with pytest.raises(ChannelError, match=r"no end plateau found at the high end of X_CYL"):
        read_mapped(path, parse_tag_map(tags, "cut.toml"))
    flat = Recording.from_arrays(
        {"X_CYL": np.full(500, 0.05)},
        1000.0,
        units={"X_CYL": "m"},
        digital={"U_CYL_A": np.zeros(50, np.uint8)},
        digital_rate_hz=100.0,
    )
    flat.write(tmp_path / "flat.parquet")
    with pytest.raises(ChannelError, match=r"cannot learn S_CYL_B from X_CYL.*no movement"):
        read_mapped(tmp_path / "flat.parquet", parse_tag_map(tags, "flat.toml"))


@pytest.mark.parametrize(
    ("switches", "words"),
    [
        ({"S_CYL_B": {"position": "X_NONE"}}, "switches.'S_CYL_B'.position"),
        ({"S_CYL_B": {"position": "X_CYL", "above": 1.0, "below": 0.5}}, "one threshold"),
        ({"S_CYL_B": {"position": "X_CYL", "above": True}}, "a number"),
        ({"S_CYL_B": {"position": "X_CYL", "unit": "bar"}}, "unit"),
        ({"S_CYL_B": {"position": "X_CYL", "plateau": "top"}}, "'low' or 'high'"),
        ({"S_CYL_B": {"position": "X_CYL", "hysteresis": -1.0}}, ">= 0"),
        ({"X_CYL_B": {"position": "X_CYL"}}, "S_<ACT>_A or S_<ACT>_B"),
        ({"S_CYL_B": {"position": "X_CYL", "edge": 1}}, "unknown key"),
    ],
)
def test_bad_switch_entries_name_the_key(switches: dict[str, object], words: str) -> None:
    tags = {
        "columns": {"X_CYL": {"role": "X_CYL", "unit": "mm"}, "Y1": {"role": "U_CYL_A"}},
        "switches": switches,
    }
    with pytest.raises(InputError, match=r"rig\.toml") as info:
        parse_tag_map(tags, "rig.toml")
    assert words in str(info.value)


def test_a_recorded_switch_cannot_also_be_derived() -> None:
    tags = {
        "columns": {
            "X": {"role": "X_CYL", "unit": "mm"},
            "Y1": {"role": "U_CYL_A"},
            "B2": {"role": "S_CYL_B"},
        },
        "switches": {"S_CYL_B": {"position": "X_CYL"}},
    }
    with pytest.raises(ChannelError, match="derived or read, not both"):
        parse_tag_map(tags, "rig.toml")


FLOWS = (
    "t;FT1_in;FT1_out;Y1;Y2\n"
    "0.000;10.0;0.0;1;0\n"
    "0.001;12.5;0.0;1;0\n"
    "0.002;0.0;7.5;0;1\n"
    "0.003;0.0;;0;1\n"
)


def test_flows_into_and_out_of_a_chamber_make_one_signed_flow(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "flows.csv"
    data.write_text(FLOWS)
    tags = tmp_path / "flows.toml"
    tags.write_text(
        'delimiter = ";"\n[columns]\n"t" = { role = "time", unit = "s" }\n'
        '"FT1_in" = { role = "Q_CYL_A", unit = "l/min", basis = "ANR", direction = "in" }\n'
        '"FT1_out" = { role = "Q_CYL_A", unit = "l/min", basis = "ANR", direction = "out" }\n'
        '"Y1" = "U_CYL_A"\n"Y2" = "U_CYL_B"\n'
    )
    rec = read_mapped(data, load_tag_map(tags))
    assert rec.channels == ("Q_CYL_A", "U_CYL_A", "U_CYL_B")
    q = rec.channel("Q_CYL_A")[1] / (1e-3 / 60 * ANR.density)
    np.testing.assert_allclose(q[:3], [10.0, 12.5, -7.5])
    assert np.isnan(q[3])  # a blank cell in either part is a gap
    out = tmp_path / "flows.parquet"
    assert main(["import", str(data), "--map", str(tags), "--out", str(out)]) == 0
    assert Recording.read(out).channels == rec.channels
    capsys.readouterr()


@pytest.mark.parametrize(
    ("columns", "words"),
    [
        (
            {"A": {"role": "P_CYL_A", "unit": "bar(g)", "direction": "in"}},
            "'in' or 'out' on a flow role",
        ),
        (
            {"A": {"role": "Q_CYL_A", "unit": "SLPM", "direction": "up"}},
            "'in' or 'out' on a flow role",
        ),
        (
            {
                "A": {"role": "Q_CYL_A", "unit": "SLPM", "direction": "in"},
                "B": {"role": "Q_CYL_A", "unit": "SLPM", "direction": "in"},
            },
            "given to columns 'A' and 'B'",
        ),
        (
            {
                "A": {"role": "Q_CYL_A", "unit": "SLPM"},
                "B": {"role": "Q_CYL_A", "unit": "SLPM", "direction": "out"},
            },
            "one signed column, or an in and an out column",
        ),
    ],
)
def test_bad_flow_directions_are_refused(columns: dict[str, object], words: str) -> None:
    tags = {"columns": {"t": {"role": "time", "unit": "s"}, "Y": "U_CYL_A", **columns}}
    with pytest.raises(InputError, match=r"m\.toml") as info:
        parse_tag_map(tags, "m.toml")
    assert words in str(info.value)
