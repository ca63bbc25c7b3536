"""The snippets of docs/recording.md run as written, in order, in one namespace."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "recording.md"


def test_recording_doc_snippets_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(tempfile, "mkdtemp", lambda: str(tmp_path))  # keep /tmp clean
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.DOTALL)
    assert len(blocks) >= 6
    namespace: dict[str, object] = {}
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), namespace)
    assert "refusing to overwrite" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["daq.csv", "daq.tdms", "run.parquet"]
