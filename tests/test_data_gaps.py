"""The gap rule (docs/data-quality.md): real DAQ files have gaps and dropouts.

Short gaps (NaN, infinite or out-of-range samples up to 0.05 s) are interpolated;
cycles touched by longer ones are skipped and counted; too few usable cycles are
refused naming the file and the channel. Acceptance (issue 14): a leak-free recording
with 1 % of its samples NaN in short bursts is diagnosed leak-free with the skipped
cycles reported, and a leak run with the same gaps is still located.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.cli.app import main
from pneufdd.recording import Channel, Recording
from pneufdd.signals.quality import MAX_REPAIR_S, PHYSICAL_RANGE, repair_gaps
from pneufdd.sim import as_exported, simulate

SEED = 96_000_300
"""This file's seeds (SEED + k): >= 96,000,000, never used while developing."""


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


@given(
    values=st.lists(st.floats(1e5, 1e6), min_size=3, max_size=300),
    holes=st.lists(st.tuples(st.integers(0, 299), st.integers(1, 12)), max_size=6),
    kind=st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -5.0]),
)
def test_gap_rule_invariants(values, holes, kind) -> None:
    x = np.array(values)
    for start, length in holes:
        x[start : start + length] = kind
    rate = 100.0  # 0.05 s = 5 samples
    repaired, long_gap, n_short, missing = repair_gaps(x, rate, "Pa")
    low, high = PHYSICAL_RANGE["Pa"]
    bad = ~np.isfinite(x) | (x < low) | (x > high)
    assert np.array_equal(missing, bad)
    # valid samples are never touched
    assert np.array_equal(repaired[~bad], x[~bad])
    runs = _runs(bad)
    if bad.all():
        assert np.isnan(repaired).all()
        return
    longest = round(MAX_REPAIR_S * rate)
    assert n_short == sum(b - a <= longest for a, b in runs)
    for a, b in runs:
        if b - a > longest:
            assert long_gap[a:b].all()
            assert np.isnan(repaired[a:b]).all()
        else:
            assert not long_gap[a:b].any()
            # linear between the neighbours (or the nearest value at an edge)
            idx = np.arange(x.size)
            good = ~bad
            expected = np.interp(idx[a:b], idx[good], x[good])
            np.testing.assert_allclose(repaired[a:b], expected, rtol=1e-12)


def test_gap_rule_example_values() -> None:
    x = np.array([1e5, np.nan, 3e5, 1e308, 5e5, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0, 2e5])
    repaired, long_gap, n_short, _ = repair_gaps(x, 100.0, "Pa")
    assert repaired[:5].tolist() == [1e5, 2e5, 3e5, 4e5, 5e5]
    assert n_short == 2
    assert long_gap.tolist() == [False] * 5 + [True] * 6 + [False]


def _gappy(rec: Recording, seed: int, dropout_s: float | None) -> Recording:
    """1 % of every analog channel's samples NaN in bursts of 5-20 samples (5-20 ms),
    plus optionally one dropout of ``dropout_s`` in Q_In in the middle of the run."""
    rng = np.random.default_rng(seed)
    out = []
    for name in rec.channels:
        ch = rec.info(name)
        v = np.array(ch.values, dtype=np.float64) if ch.kind == "analog" else ch.values
        if ch.kind == "analog":
            target = int(0.01 * v.size)
            lost = 0
            while lost < target:
                width = int(rng.integers(5, 21))
                start = int(rng.integers(0, v.size - width))
                v[start : start + width] = np.nan
                lost += width
            if dropout_s is not None and name == "Q_In":
                mid = v.size // 2
                v[mid : mid + int(dropout_s * ch.rate_hz)] = np.nan
        out.append(Channel(name, v, ch.rate_hz, ch.unit, ch.kind, ch.t0))
    return Recording(out, rec.start_time, rec.metadata)


@pytest.mark.slow
def test_gappy_runs_are_diagnosed_as_without_gaps(tmp_path, capsys) -> None:
    machine, location = "press-fit-cell", "supply"
    refs = []
    for k in (1, 2):
        rec = as_exported(simulate(machine, cycles=7, seed=SEED + k))
        refs.append(str(rec.write(tmp_path / f"free{k}.parquet")))
    ref = tmp_path / "ref.pnref"
    options = ["--machine", machine, "--uncertainty-plants", "1", "--channels", "P_In,Q_In"]
    assert main(["reference", "build", *refs, "--out", str(ref), *options]) == 0
    free = as_exported(simulate(machine, cycles=12, seed=SEED + 3))
    leaky = as_exported(simulate(machine, cycles=12, leaks={location: "60slpm"}, seed=SEED + 4))
    results = {}
    for name, rec in (("free", free), ("leaky", leaky)):
        path = _gappy(rec, SEED + 5, dropout_s=0.3).write(tmp_path / f"{name}.parquet")
        out = tmp_path / f"{name}.json"
        code = main(["diagnose", str(path), "--reference", str(ref), "--json", str(out)])
        captured = capsys.readouterr()
        assert code in (0, 1), captured.err
        results[name] = (code, json.loads(out.read_text()), captured.out)
    code, data, console = results["free"]
    assert code == 0
    assert not data["detected"]
    gaps = data["data_gaps"]
    assert gaps["cycles_skipped"] == 1  # the 0.3 s dropout in Q_In
    assert gaps["skipped"][0]["channel"] == "Q_In"
    assert gaps["gaps_repaired"] >= 40  # ~30 bursts of 5-20 samples in each of P_In, Q_In
    assert "1 cycle(s) skipped" in console
    assert "Q_In" in console
    code, data, console = results["leaky"]
    assert code == 1
    assert data["data_gaps"]["cycles_skipped"] == 1
    assert [leak["location"] for leak in data["leaks"]] == [location]
    assert data["leaks"][0]["flow_slpm"] == pytest.approx(60.0, rel=0.25)


def test_too_few_usable_cycles_are_refused_naming_file_and_channel(tmp_path, capsys) -> None:
    rec = as_exported(simulate("press-fit-cell", cycles=3, seed=SEED + 6))
    ch = rec.info("P_In")
    v = np.array(ch.values)
    v[: v.size * 3 // 4] = np.nan  # a DAQ dropout over most of the run
    out = []
    for name in rec.channels:
        c = rec.info(name)
        out.append(Channel(name, v, c.rate_hz, c.unit, c.kind, c.t0) if name == "P_In" else c)
    path = Recording(out, rec.start_time, rec.metadata).write(tmp_path / "gappy.parquet")
    assert (
        main(["features", str(path), "--out", str(tmp_path / "f.csv"), "--actuator", "PRESS"]) == 2
    )
    err = " ".join(capsys.readouterr().err.split())
    assert "gappy.parquet" in err
    assert "'P_In'" in err
    assert not (tmp_path / "f.csv").exists()


def test_repair_without_copy_reads_a_clean_channel_in_place_and_never_writes_it() -> None:

    clean = np.linspace(2e5, 6e5, 50)
    same, _, count, _ = repair_gaps(clean, 100.0, "Pa", copy=False)
    assert same is clean
    assert count == 0
    # a channel with a gap is repaired in a new array; the caller's samples stay as given
    gappy = clean.copy()
    gappy[10] = np.nan
    repaired, _, count, _ = repair_gaps(gappy, 100.0, "Pa", copy=False)
    assert count == 1
    assert not np.shares_memory(repaired, gappy)
    assert np.isnan(gappy[10])
    assert repaired[10] == pytest.approx(clean[10])
