"""Batch diagnosis (``pneufdd diagnose RUN...``) on a real Dask cluster equals the serial path."""

from __future__ import annotations

import json

import pytest
from distributed import LocalCluster

from pneufdd.cli.app import main
from pneufdd.diagnosis.batch import diagnose_runs, expand_runs
from pneufdd.errors import InputError
from pneufdd.sim import simulate

# Dask's hint that its workers' scratch folders took over a second to create (a busy
# disk): a performance note, not a fault of the cluster under test
pytestmark = pytest.mark.filterwarnings(
    "ignore:Creating scratch directories is taking a surprisingly long time"
)

SEED = 9_300_000  # this file's seeds: SEED + k


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("batch")
    runs = folder / "runs"
    runs.mkdir()
    for name, cycles, leaks, seed in [
        ("ref1", 8, {}, 1),
        ("ref2", 8, {}, 2),
        ("runs/a-free", 5, {}, 3),
        ("runs/b-leaky", 5, {"supply": 4}, 4),
        ("runs/c-free", 5, {}, 5),
    ]:
        simulate("press-fit-cell", cycles=cycles, leaks=leaks, seed=SEED + seed).write(
            folder / f"{name}.parquet"
        )
    ref = folder / "ref.pnref"
    args = ["reference", "build", str(folder / "ref1.parquet"), str(folder / "ref2.parquet")]
    assert main([*args, "--out", str(ref), "--no-signatures"]) == 0
    return folder


def test_expand_runs_reads_folders_and_patterns(files):
    runs = files / "runs"
    by_folder = expand_runs([runs])
    assert [p.name for p in by_folder] == ["a-free.parquet", "b-leaky.parquet", "c-free.parquet"]
    assert expand_runs([str(runs / "*.parquet"), runs / "a-free.parquet"]) == by_folder
    with pytest.raises(InputError, match="matching"):
        expand_runs([str(runs / "*.tdms")])
    with pytest.raises(InputError, match="at least one"):
        expand_runs([])


def test_batch_on_a_dask_cluster_equals_the_serial_batch(files):
    runs = [files / "runs", files / "missing.parquet"]
    serial = list(diagnose_runs(runs, files / "ref.pnref", workers=1))
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        on_dask = list(
            diagnose_runs(runs, files / "ref.pnref", scheduler=cluster.scheduler_address)
        )
    assert on_dask == serial
    assert [r["run"] for r in serial] == [
        str(files / "runs" / "a-free.parquet"),
        str(files / "runs" / "b-leaky.parquet"),
        str(files / "runs" / "c-free.parquet"),
        str(files / "missing.parquet"),
    ]
    assert [r.get("detected") for r in serial] == [False, True, False, None]
    assert "missing.parquet" in serial[3]["error"]
    assert serial[1]["machine"] == "press-fit-cell"
    assert list(diagnose_runs(runs, files / "ref.pnref", workers=1, threads=1)) == serial
    with pytest.raises(InputError, match="threads"):
        list(diagnose_runs(runs, files / "ref.pnref", threads=0))


def test_diagnose_command_prints_one_json_line_per_run(files, capsys):
    pattern = str(files / "runs" / "*-free.parquet")
    code = main(["diagnose", pattern, "--reference", str(files / "ref.pnref"), "--workers", "1"])
    lines = capsys.readouterr().out.splitlines()
    assert code == 0  # no leak in either run
    assert [json.loads(x)["detected"] for x in lines] == [False, False]
    out = files / "all.jsonl"
    runs = [str(files / "runs"), "--reference", str(files / "ref.pnref")]
    assert main(["diagnose", *runs, "--workers", "2", "--json", str(out)]) == 1  # a leak
    records = [json.loads(x) for x in out.read_text().splitlines()]
    assert [r["detected"] for r in records] == [False, True, False]
    assert main(["diagnose", *runs, "--workers", "1", "--json", str(out)]) == 2  # exists
    assert main(["diagnose", *runs, "--report", str(files / "r.html")]) == 2
