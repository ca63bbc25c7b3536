"""``pneufdd steps``: tables and the documented JSON."""

from __future__ import annotations

import json

from rich.console import Console

from pneufdd.cli.app import main
from pneufdd.cli.steps import render_steps
from synth import make_recording


def test_steps_json_shape_and_values(capsys) -> None:
    _, truth = make_recording(cycles=3, seed=1)
    rec, _ = make_recording(cycles=3, seed=1, truncate_s=truth.step_starts[2][10] + 0.05)
    render_steps(rec, as_json=True)
    d = json.loads(capsys.readouterr().out)
    assert set(d) == {"cycles", "rejected"}
    assert [c["complete"] for c in d["cycles"]] == [True, True, False]
    assert [len(c["steps"]) for c in d["cycles"]] == [58, 58, 11]
    step = d["cycles"][0]["steps"][1]
    assert set(step) == {"index", "start_s", "duration_s", "actuators"}
    assert step["index"] == 2
    assert step["actuators"] == ["DNC", "DRQD", "HMPL_H"]
    assert abs(step["start_s"] - truth.step_starts[0][1]) <= 0.0100001
    assert d["rejected"] == [
        {
            "index": 3,
            "start_s": d["cycles"][2]["steps"][0]["start_s"],
            "steps_found": 11,
            "reason": "truncated: the recording ends after step 11 of 58",
        }
    ]


def test_steps_tables_list_cycles_and_reasons() -> None:
    _, truth = make_recording(cycles=3, seed=1)
    rec, _ = make_recording(cycles=3, seed=1, truncate_s=truth.step_starts[2][5] + 0.05)
    console = Console(record=True, width=200)
    render_steps(rec, all_steps=True, console=console)
    text = console.export_text()
    assert "Sequence: 58 steps" in text
    assert "2 complete, 1 rejected" in text
    assert "truncated: the recording ends after step 6 of 58" in text
    assert "DNC, DRQD, HMPL_H" in text
    assert "duration [s]" in text  # unit headers are not eaten as rich markup


def test_steps_command_reports_unreadable_file(tmp_path) -> None:
    assert main(["steps", str(tmp_path / "missing.parquet")]) == 2


def test_steps_command_on_a_parquet_file(tmp_path, capsys) -> None:
    rec, truth = make_recording(cycles=3, seed=4)
    path = rec.write(tmp_path / "run.parquet")
    assert main(["steps", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [len(c["steps"]) for c in d["cycles"]] == [58, 58, 58]
    assert d["rejected"] == []
    assert abs(d["cycles"][2]["steps"][57]["start_s"] - truth.step_starts[2][57]) <= 0.0100001
    assert main(["steps", str(path)]) == 0
    assert "3 complete, 0 rejected" in capsys.readouterr().out
