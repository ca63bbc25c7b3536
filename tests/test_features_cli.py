"""``pneufdd features``: CSV output, overwrite protection."""

from __future__ import annotations

import pandas as pd
import pytest

from pneufdd.cli.app import main
from pneufdd.cli.features import write_features
from pneufdd.errors import InputError
from synth import make_recording


def test_write_features_csv_and_refuse_overwrite(tmp_path) -> None:
    rec, _ = make_recording(cycles=3, seed=2, leaks={"DNC_B": 2})
    out = tmp_path / "features.csv"
    df = write_features([rec], out, groups=("table44",))
    back = pd.read_csv(out, index_col=[0, 1])
    assert back.shape == df.shape == (3, 13 + 2)
    assert back["DNC.t44_12_t_s_extend_s"].tolist() == pytest.approx(
        df["DNC.t44_12_t_s_extend_s"].tolist()
    )
    assert back["leak_class"].tolist() == ["DNC_B"] * 3
    before = out.read_bytes()
    with pytest.raises(InputError, match="--overwrite"):
        write_features([rec], out, groups=("table44",))
    assert out.read_bytes() == before
    write_features([rec], out, overwrite=True, groups=("motion",))
    assert pd.read_csv(out, index_col=[0, 1]).shape[1] != back.shape[1]
    assert [p.name for p in tmp_path.iterdir()] == ["features.csv"]


def test_features_command_refuses_existing_output(tmp_path) -> None:
    out = tmp_path / "f.csv"
    out.write_text("keep me")
    assert main(["features", str(tmp_path / "run.parquet"), "--out", str(out)]) == 2
    assert out.read_text() == "keep me"


def test_features_command_on_parquet_files(tmp_path, capsys) -> None:
    ref, _ = make_recording(cycles=3, seed=1)
    leak, _ = make_recording(cycles=3, seed=2, leaks={"supply": 2})
    paths = [ref.write(tmp_path / "ref.parquet"), leak.write(tmp_path / "leak.parquet")]
    out = tmp_path / "features.csv"
    args = ["features", *map(str, paths), "--out", str(out), "--group", "table44"]
    assert main(args) == 0
    df = pd.read_csv(out, index_col=[0, 1])
    assert df.shape == (6, 13 + 2)
    assert df["leak_class"].tolist() == ["none"] * 3 + ["supply"] * 3
    assert "wrote 6 cycles" in capsys.readouterr().out
    assert main(args) == 2  # exists: refused
    assert main([*args, "--overwrite", "--group", "motion"]) == 0
