"""Issue 39, item 5: calibration and drafting follow diagnose's gap rule.

One ``Q_In`` sample set to inf made ``machine calibrate`` report "supply air 986.50 %"
and leave every volume uninformed (exit 0, a silent wrong answer). Now a short gap is
interpolated, a cycle a long gap touches is left out and reported, and a recording
with gaps in most of its cycles is refused naming the file and the channel.
"""

from __future__ import annotations

import dataclasses
import functools
import re

import numpy as np
import pytest

from pneufdd.calibration import draft_machine
from pneufdd.calibration.calibrate import measure_evidence
from pneufdd.cli.app import main
from pneufdd.errors import NoCompleteCycleError
from pneufdd.recording import Recording
from pneufdd.sim import load_machine, simulate

SEED = 52_000  # this file's seeds


@functools.cache
def _run() -> Recording:
    return simulate("press-fit-cell", cycles=10, seed=SEED)


def _damaged(rec: Recording, channel: str, start_s: float, length_s: float, value: float):
    ch = rec.info(channel)
    values = np.array(ch.values, dtype=np.float64)
    i0 = round((start_s - ch.t0) * ch.rate_hz)
    values[i0 : i0 + max(1, round(length_s * ch.rate_hz))] = value
    channels = [
        dataclasses.replace(ch, values=values) if c == channel else rec.info(c)
        for c in rec.channels
    ]
    return Recording(channels, start_time=rec.start_time, metadata=rec.metadata)


def _evidence(rec: Recording):
    machine = load_machine("press-fit-cell")
    return measure_evidence([rec], machine, ("P_PRESS_A",), names=["run.parquet"])


def _same(a, b, rtol: float) -> None:
    for name in ("supply_air_kg", "duration_s", "supply_pressure_pa"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=rtol, err_msg=name)
    np.testing.assert_allclose(
        a.line_pressure_pa["P_PRESS_A"], b.line_pressure_pa["P_PRESS_A"], rtol=rtol
    )


def test_one_infinite_sample_is_interpolated() -> None:
    clean = _evidence(_run())
    damaged = _evidence(_damaged(_run(), "Q_In", 15.0, 0.0, np.inf))
    assert damaged.gaps_repaired == 1
    assert damaged.cycles_skipped == ()
    assert damaged.cycles == clean.cycles
    _same(damaged, clean, rtol=1e-3)  # one sample of ~30,000 per step replaced


@pytest.mark.parametrize("value", [np.inf, np.nan, 1e308])
def test_a_long_gap_skips_its_cycle_and_only_it(value) -> None:
    clean = _evidence(_run())
    in_flow = _evidence(_damaged(_run(), "Q_In", 15.0, 0.2, value))
    in_pressure = _evidence(_damaged(_run(), "P_In", 15.0, 0.2, value))
    assert in_flow.cycles == clean.cycles - 1
    (skipped,) = in_flow.cycles_skipped
    assert skipped[0] == 0
    assert skipped[2] == "Q_In"
    assert in_pressure.cycles_skipped == ((0, skipped[1], "P_In"),)
    # the same cycles averaged, whichever channel had the gap: the damaged samples are
    # in no average (exactly the result without the damaged cycle)
    _same(in_flow, in_pressure, rtol=1e-9)
    _same(in_flow, clean, rtol=0.03)  # and close to all cycles


def test_gaps_in_most_cycles_are_refused_naming_file_and_channel() -> None:
    rec = _run()
    for start in np.arange(2.0, rec.duration - 1.0, 1.0):
        rec = _damaged(rec, "Q_In", float(start), 0.2, np.inf)
    with pytest.raises(NoCompleteCycleError, match=r"run\.parquet: usable cycles.*'Q_In'"):
        _evidence(rec)


def test_the_draft_never_sees_an_infinite_sample() -> None:
    clean = draft_machine([_run()], name="cell").data
    damaged = draft_machine([_damaged(_run(), "Q_In", 15.0, 0.0, 1e308)], name="cell").data
    assert damaged["supply"] == pytest.approx(clean["supply"], rel=1e-3)


def test_machine_calibrate_with_an_infinite_sample(tmp_path, capsys) -> None:
    run = _damaged(_run(), "Q_In", 15.0, 0.0, np.inf).write(tmp_path / "run.parquet")
    out = tmp_path / "c.toml"
    assert main(["machine", "calibrate", "press-fit-cell", str(run), "--out", str(out)]) == 0
    err = capsys.readouterr().err.replace("\n", " ")
    air = float(re.search(r"supply air ([0-9.]+) %", err).group(1))
    assert air < 5.0  # was 986.50 %
    assert "data gaps: 0 cycle(s) skipped, 1 short gap(s) interpolated" in err
    assert "FEED.volume" not in err  # the volumes are informed again


def test_machine_calibrate_refuses_a_recording_with_gaps_everywhere(tmp_path, capsys) -> None:
    rec = _run()
    for start in np.arange(2.0, rec.duration - 1.0, 1.0):
        rec = _damaged(rec, "Q_In", float(start), 0.2, np.nan)
    run = rec.write(tmp_path / "run.parquet")
    out = tmp_path / "c.toml"
    assert main(["machine", "calibrate", "press-fit-cell", str(run), "--out", str(out)]) == 2
    err = capsys.readouterr().err.replace("\n", " ")
    assert f"{run}: usable cycles" in err
    assert "'Q_In'" in err
    assert not out.exists()
