"""simulate(): recording contract, metadata, determinism, sensor models, CLI."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import InputError
from pneufdd.physics.units import slpm_to_kg_s
from pneufdd.recording import Recording
from pneufdd.sim import Leak, load_machine, run_simulation, simulate
from pneufdd.sim.buffers import OutputBuffers
from pneufdd.sim.description import Sensor
from pneufdd.sim.sensors import apply_sensor


@pytest.fixture(scope="module")
def one() -> Recording:
    return simulate("festo-dsd", cycles=1, leaks={"DNC_B": 4, "supply": "1.5mm"}, seed=1)


def test_recording_contract(one: Recording) -> None:
    m = load_machine("festo-dsd")
    assert set(one.analog_channels) == {s.channel for s in m.sensors}
    assert set(one.digital_channels) == set(m.solenoids) | set(m.switches)
    assert one.rate("P_In") == 1000.0
    assert one.rate("U_DNC_A") == 100.0
    assert one.unit("P_In") == "Pa"
    assert one.unit("Q_In") == "kg/s"
    assert one.unit("X_DNC") == "m"
    _, u = one.channel("U_DNC_B")
    assert u.dtype == np.uint8
    assert set(np.unique(u)) == {0, 1}
    _, p = one.channel("P_In")
    assert 4.0e5 < p.mean() < 6.5e5  # absolute Pa around 72 psig
    _, q = one.channel("Q_In")
    assert q.min() >= 0.0
    assert q.max() <= slpm_to_kg_s(200.0) + 1e-12
    meta = one.metadata
    assert meta["seed"] == 1
    assert meta["cycles"] == 1
    assert meta["machine"]["name"] == "festo-dsd"
    assert meta["machine"]["description"]["actuator"][0]["id"] == "DNC"
    leaks = {lk["location"]: lk for lk in meta["leaks"]}
    assert leaks["DNC_B"]["size"] == 4.0
    assert leaks["DNC_B"]["unit"] == "turns"
    assert leaks["supply"]["unit"] == "mm"
    assert leaks["supply"]["effective_area_m2"] > 0
    assert "pneufdd.sim" in meta["simulator"]


def test_same_seed_same_data_different_seed_differs(one: Recording) -> None:
    again = simulate("festo-dsd", cycles=1, leaks={"DNC_B": 4, "supply": "1.5mm"}, seed=1)
    assert again.equals(one)
    other = simulate("festo-dsd", cycles=1, leaks={"DNC_B": 4, "supply": "1.5mm"}, seed=2)
    assert not other.equals(one)


def test_leak_objects_and_errors() -> None:
    res = run_simulation("festo-dsd", cycles=1, leaks=[Leak("HMPL_V_A", 30.0, "SLPM")], seed=0)
    assert res.leaks[0].nominal_slpm == pytest.approx(30.0, rel=1e-6)
    # HMPL_V_A is pressurised only while HMPL_V is down: its leak flow comes and goes
    lk = res.outputs["mdot_leak_HMPL_V_A"]
    assert lk.max() > slpm_to_kg_s(20.0)
    assert np.median(lk) < slpm_to_kg_s(1.0)
    with pytest.raises(InputError, match="cycles"):
        simulate("festo-dsd", cycles=0)
    with pytest.raises(InputError, match="seed"):
        simulate("festo-dsd", seed=-3)


def test_outputs_and_dataframe() -> None:
    res = run_simulation("festo-dsd", cycles=1, seed=4)
    df = res.to_pandas()
    assert df.index.name == "time_s"
    assert len(df) == res.time.size
    for col in ("p_manifold", "x_DNC", "mdot_in_DNC_A", "mass_supplied", "stored_mass"):
        assert col in df.columns
    assert res.step_start.shape == (1, 58)
    assert "step_start" not in df.columns
    np.testing.assert_array_equal(res.outputs["step_start"], res.step_start)
    ends = res.outputs["stroke_end_DNC"]
    assert ends.size >= 1
    assert np.all(ends > res.outputs["stroke_start_DNC"])
    assert np.all(np.diff(res.step_start[0]) > 0)
    x = res.outputs["x_DNC"]
    assert x.min() == 0.0
    assert x.max() == pytest.approx(0.2)


def _sensor(**kw: object) -> Sensor:
    base = dict(
        channel="Q", kind="flow", location="supply", range_low=0.0, range_high=200.0,
        noise=0.0, bits=12, time_constant_s=0.0, direction="forward",
    )  # fmt: skip
    base.update(kw)
    return Sensor(**base)  # type: ignore[arg-type]


def test_flow_meter_direction_saturation_and_quantisation() -> None:
    rng = np.random.default_rng(0)
    truth = slpm_to_kg_s(np.array([-50.0, 0.0, 100.0, 250.0]))
    fwd = apply_sensor(_sensor(), truth, rng, 1000.0)
    step = slpm_to_kg_s(200.0 / 4095)
    assert fwd[0] == 0.0
    assert fwd[3] == pytest.approx(slpm_to_kg_s(200.0))
    assert abs(fwd[2] - truth[2]) <= step / 2 + 1e-15
    both = apply_sensor(_sensor(direction="bidirectional"), truth, rng, 1000.0)
    assert both[0] < 0.0
    lag = apply_sensor(_sensor(time_constant_s=0.05), np.full(200, truth[2]), rng, 1000.0)
    assert lag[0] < 0.1 * truth[2]
    assert lag[-1] == pytest.approx(truth[2], rel=0.03)


def test_cli_machines_and_bad_leak(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["machines"]) == 0
    assert "festo-dsd" in capsys.readouterr().out
    code = main(["simulate", "--leak", "DNC_C=2", "--out", str(tmp_path / "r.parquet")])
    assert code != 0
    assert "DNC_C" in capsys.readouterr().err


def test_cli_simulate_writes_identical_files(tmp_path: Path) -> None:
    args = ["simulate", "--cycles", "1", "--leak", "DNC_B=4", "--leak", "supply=2", "--seed", "1"]
    try:
        code = main([*args, "--out", str(tmp_path / "a.parquet")])
    except NotImplementedError:
        pytest.skip("Parquet writer (branch recording) not merged yet")
    assert code == 0
    assert main([*args, "--out", str(tmp_path / "b.parquet")]) == 0
    assert (tmp_path / "a.parquet").read_bytes() == (tmp_path / "b.parquet").read_bytes()
    back = Recording.read(tmp_path / "a.parquet")
    assert back.metadata["leaks"][0]["location"] == "DNC_B"


def test_every_simulated_cycle_segments_as_complete() -> None:
    from pneufdd.signals.segmentation import segment

    rec = simulate("festo-dsd", cycles=2, seed=21)
    seg = segment(rec)
    complete = [c for c in seg.cycles if c.complete]
    assert len(complete) == 2, [c.reason for c in seg.cycles]
    assert all(len(c.steps) == 58 for c in complete)


def _outputs_of(result) -> dict[str, np.ndarray]:  # type: ignore[no-untyped-def]
    out = {k: np.asarray(v) for k, v in result.outputs.items()}
    out["step_start"] = result.step_start
    for name in result.recording.channels:
        out["channel:" + name] = result.recording.channel(name)[1]
    return out


def test_a_run_does_not_depend_on_the_runs_before_or_beside_it() -> None:
    # kernel buffers are kept between runs and shared by threads: a run that follows
    # other machines' runs, or runs beside another, gives exactly what it gives alone
    from concurrent.futures import ThreadPoolExecutor

    def festo() -> dict[str, np.ndarray]:
        return _outputs_of(run_simulation("festo-dsd", cycles=2, leaks={"DNC_B": 4}, seed=3))

    first = festo()
    run_simulation("carton-sorter", cycles=1, seed=4)
    run_simulation("festo-dsd", cycles=1, leaks={"supply": 6}, seed=5)
    run_simulation("festo-dsd", cycles=3, seed=7, channels=["P_In", "Q_In"])
    with ThreadPoolExecutor(3) as pool:
        later = list(pool.map(lambda _: festo(), range(3)))
    for other in later:
        assert other.keys() == first.keys()
        for key, value in first.items():
            assert np.array_equal(other[key], value), key


def test_recording_some_channels_gives_exactly_those_of_a_full_run() -> None:
    machine = load_machine("press-fit-cell")
    names = [s.channel for s in machine.sensors]
    assert len(names) >= 3
    full = run_simulation(machine, cycles=2, seed=4)
    # the first channels only (no noise drawn after them), and one left out between
    for chosen in (names[:2], [names[0], names[2]], [names[-1]], []):
        part = run_simulation(machine, cycles=2, seed=4, channels=chosen)
        assert part.recording.analog_channels == tuple(chosen)
        for name in (*chosen, *part.recording.digital_channels):
            assert np.array_equal(part.recording.channel(name)[1], full.recording.channel(name)[1])
        assert part.step_start.tolist() == full.step_start.tolist()
    with pytest.raises(InputError, match=r"channels to record .*'nope'"):
        run_simulation(machine, cycles=1, channels=[names[0], "nope"])


def test_kept_true_signal_rows_grow_and_keep_what_the_run_wrote() -> None:
    # a run's true signals go to rows kept with the pooled buffers; a later run may
    # record more channels over fewer samples than the rows were made for
    buffers = OutputBuffers(10, 4, 1, 2, 2, 2)
    wide = buffers.truth_store(2, 0, 100, 100)
    wide[:, :100] = 7.0
    rows = buffers.truth_store(5, 30, 50, 60)
    assert rows.shape[0] == 5
    assert rows.shape[1] >= 60
    assert np.all(rows[:2, :30] == 7.0)
    assert buffers.truth_store(3, 40, 60, 60) is rows  # room enough: the same rows


def test_kept_noise_streams_give_each_run_its_own_generators_draws() -> None:
    # runs with one seed reach their sensor noise in one generator state whatever their
    # leaks (a diagnosis's check); the stream kept for it serves shorter and longer runs
    sim = importlib.import_module("pneufdd.sim.simulate")
    # the numpy property the kept streams rely on: normals drawn in pieces or at once
    pieces = np.random.default_rng(11)
    whole = np.random.default_rng(11).standard_normal(5000)
    assert np.array_equal(
        np.concatenate([pieces.standard_normal(1234), pieces.standard_normal(3766)]), whole
    )

    def run(slpm: float) -> Recording:
        leaks = {"DNC_A": f"{slpm}slpm", "supply": "30slpm"}
        return run_simulation("festo-dsd", cycles=2, leaks=leaks, seed=21).recording

    def same(a: Recording, b: Recording) -> bool:
        return all(np.array_equal(a.channel(n)[1], b.channel(n)[1]) for n in a.analog_channels)

    alone = {}
    for slpm in (5.0, 90.0):
        sim._NOISE = sim._NoiseStreams()  # nothing kept: the draws are made anew
        alone[slpm] = run(slpm)
    sizes = {slpm: rec.channel("P_In")[1].size for slpm, rec in alone.items()}
    assert sizes[5.0] != sizes[90.0]  # the leaks change the cycle's length
    shorter, longer = sorted(sizes, key=sizes.__getitem__)
    sim._NOISE = sim._NoiseStreams()
    # the kept stream is extended for the longer run, then sliced for the shorter
    for slpm in (shorter, longer, shorter):
        assert same(run(slpm), alone[slpm]), slpm
