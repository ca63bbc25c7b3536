"""Leak history over runs (pneufdd.monitor)."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from _diag_synth import synth_signatures, synth_table
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import FileFormatError
from pneufdd.monitor import append_history, location_trends, read_history


def test_history_round_trip_and_trend(tmp_path):
    ref = ReferenceModel.build(synth_table(40, seed=100), signatures=synth_signatures())
    path = tmp_path / "h.jsonl"
    sizes = [0.0, 4e-4, 8e-4]
    for day, size in enumerate(sizes, start=1):
        leaks = {"X_A": size} if size else {}
        result = diagnose(ref, synth_table(10, leaks, seed=200 + day))
        append_history(path, result, f"day {day}", datetime(2026, 1, day, tzinfo=UTC))
    entries = read_history(path)
    assert [e.run for e in entries] == ["day 1", "day 2", "day 3"]
    assert [e.detected for e in entries] == [False, True, True]
    trend = location_trends(entries)["X_A"]
    flows = [flow for _, flow in trend]
    assert len(flows) == 2
    assert flows[1] == pytest.approx(2 * flows[0], rel=0.1)  # the leak doubled


def test_corrupted_history_names_file_and_line(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text('{"time": "2026-01-01T00:00:00+00:00"}\n')
    with pytest.raises(FileFormatError, match=r"h\.jsonl.*line 1"):
        read_history(path)
