"""The README's Python example runs as written (docs that run)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README has no python example"
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    assert (tmp_path / "run.parquet").is_file()
    assert (tmp_path / "press-fit-cell.pnref").is_file()
    assert namespace["q_in"].size == namespace["t"].size  # type: ignore[attr-defined]
    result = namespace["result"]
    assert [str(leak.location) for leak in result.leaks] == ["FEED_A"]  # type: ignore[attr-defined]
    assert result.leaks[0].flow_slpm == pytest.approx(40.0, rel=0.15)  # type: ignore[attr-defined]
    leak = result.leaks[0]  # type: ignore[attr-defined]
    assert leak.mass_flow == pytest.approx(40.0 * 1.294 / 60_000.0, rel=0.15)  # [kg/s]
    assert leak.orifice_mm == 1e3 * leak.orifice_diameter
