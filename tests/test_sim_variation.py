"""Plant variation: reproducible plants, documented spreads, valid and simulable plants."""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.errors import FileExistsInputError, InputError, MachineError
from pneufdd.sim import (
    builtin_machines,
    load_machine,
    machine_to_toml,
    parse_description,
    simulate,
    vary_machine,
    write_machine,
)
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.variation import SPREADS, TRUNCATION, parameter_changes, truncated_sd

DOCS = Path(__file__).resolve().parents[1] / "docs" / "plant-variation.md"

# a small machine unlike festo-dsd: no vacuum, a 5/2 monostable valve, a rotary drive
# given by angle and lever, one throttle for both lines, one on the B line only, no
# throttle at all, sensors without gain/offset keys
TWO_AXIS = """
[machine]
name = "two-axis"

[supply]
house_psig = 90.0
regulator_set_psig = 87.0
regulator_cv = 1.0
reservoir_volume_l = 1.0
line_cv = 0.5
manifold_volume_l = 0.05

[[actuator]]
id = "LIFT"
kind = "linear"
bore_mm = 20.0
rod_mm = 8.0
stroke_mm = 50.0
moving_mass_kg = 0.5
static_friction_n = 20.0
coulomb_friction_n = 15.0
viscous_friction_n_s_m = 30.0
dead_volume_a_cm3 = 1.0
dead_volume_b_cm3 = 1.0
tube_length_m = 1.0
tube_inner_diameter_mm = 4.0
meter_out_cv = 0.05
valve = { kind = "5/2-monostable", cv = 0.2 }

[[actuator]]
id = "TURN"
kind = "rotary"
bore_mm = 16.0
angle_deg = 90.0
lever_mm = 10.0
moving_mass_kg = 1.0
static_friction_n = 10.0
coulomb_friction_n = 8.0
viscous_friction_n_s_m = 50.0
dead_volume_a_cm3 = 1.0
dead_volume_b_cm3 = 1.0
tube_length_m = 1.0
tube_inner_diameter_mm = 2.9
meter_out_cv_b = 0.03
valve = { kind = "5/2-bistable", cv = 0.16 }

[[actuator]]
id = "PUSH"
kind = "linear"
bore_mm = 12.0
rod_mm = 6.0
stroke_mm = 25.0
moving_mass_kg = 0.1
static_friction_n = 5.0
coulomb_friction_n = 4.0
viscous_friction_n_s_m = 10.0
dead_volume_a_cm3 = 0.5
dead_volume_b_cm3 = 0.5
tube_length_m = 0.5
tube_inner_diameter_mm = 2.9
valve = { kind = "5/2-bistable", cv = 0.1 }

[[sensor]]
channel = "P_In"
kind = "pressure"
location = "supply"
range = [0.0, 10.0]

[[sensor]]
channel = "Q_In"
kind = "flow"
location = "supply"
range = [0.0, 200.0]

[[step]]
do = [{ set = "U_LIFT_A" }]
wait = ["S_LIFT_B"]

[[step]]
do = [{ set = "U_TURN_A", until = "S_TURN_B" }, { set = "U_PUSH_A", until = "S_PUSH_B" }]

[[step]]
do = [{ reset = "U_LIFT_A" }]
wait = ["S_LIFT_A"]

[[step]]
do = [{ set = "U_TURN_B", until = "S_TURN_A" }, { set = "U_PUSH_B", until = "S_PUSH_A" }]
"""


@pytest.fixture(scope="module")
def two_axis() -> MachineDescription:
    return parse_description(tomllib.loads(TWO_AXIS), "two-axis.toml")


def _same_values(a: MachineDescription, b: MachineDescription) -> bool:
    return replace(a, raw={}, source="") == replace(b, raw={}, source="")


def test_same_seed_same_bytes_different_seed_different_plant() -> None:
    one = machine_to_toml(vary_machine("festo-dsd", 1.0, 7))
    assert machine_to_toml(vary_machine("festo-dsd", 1.0, 7)).encode() == one.encode()
    assert machine_to_toml(vary_machine(load_machine("festo-dsd"), 1, 7)) == one
    assert machine_to_toml(vary_machine("festo-dsd", 1.0, 8)) != one
    assert machine_to_toml(vary_machine("festo-dsd", 1.5, 7)) != one


def test_scale_zero_is_the_description(two_axis: MachineDescription) -> None:
    for twin in (load_machine("festo-dsd"), two_axis):
        plant = vary_machine(twin, 0.0, 123)
        assert _same_values(plant, twin)
        assert plant.raw == twin.raw  # not even defaults written out
        assert parameter_changes(twin, plant) == ()


def test_plant_keeps_what_the_order_code_and_the_plc_say(two_axis: MachineDescription) -> None:
    for twin in (load_machine("festo-dsd"), two_axis):
        plant = vary_machine(twin, 2.0, 11)
        assert (plant.name, plant.title, plant.source) == (twin.name, twin.title, twin.source)
        assert plant.steps == twin.steps
        assert plant.leak_locations == twin.leak_locations
        assert plant.solenoids == twin.solenoids
        assert plant.switches == twin.switches
        assert plant.scan_time_s == twin.scan_time_s
        assert plant.friction_scatter == twin.friction_scatter
        assert plant.temperature_c == twin.temperature_c
        for a, b in zip(twin.actuators, plant.actuators, strict=True):
            assert (b.id, b.kind, b.model, b.initial) == (a.id, a.kind, a.model, a.initial)
            assert (b.bore_mm, b.rod_mm, b.stroke_mm) == (a.bore_mm, a.rod_mm, a.stroke_mm)
            assert b.tube_inner_diameter_mm == a.tube_inner_diameter_mm
            assert b.valve.kind == a.valve.kind
            assert b.valve.cv != a.valve.cv
        for s, t in zip(twin.sensors, plant.sensors, strict=True):
            keep = ("channel", "kind", "location", "range_low", "range_high", "noise", "bits")
            assert [getattr(t, k) for k in keep] == [getattr(s, k) for k in keep]
            assert (t.time_constant_s, t.direction) == (s.time_constant_s, s.direction)
            assert (t.gain, t.offset) != (s.gain, s.offset)
        assert len(parameter_changes(twin, plant)) > 10


def _log_ratios(
    name_or_machine: str | MachineDescription, scale: float, seeds: range
) -> np.ndarray:
    twin = load_machine(name_or_machine)
    cv0 = np.array([a.valve.cv for a in twin.actuators])
    rows = [[a.valve.cv for a in vary_machine(twin, scale, seed).actuators] for seed in seeds]
    return np.log(np.array(rows) / cv0)


def test_valve_cv_spread_is_the_iso_6358_tolerance() -> None:
    """400 plants: every valve Cv within +-15 % at scale 1, spread as documented."""
    seeds = range(400)
    spread = SPREADS["valve.cv"]
    assert spread.kind == "relative"
    assert spread.bound == 0.15
    one = _log_ratios("festo-dsd", 1.0, seeds)  # 400 plants x 9 valves
    two = _log_ratios("festo-dsd", 2.0, seeds)
    bound = math.log(1.15)
    rounding = 1e-4  # 5 significant digits
    assert np.all(np.abs(one) <= bound + rounding)
    assert np.all(np.exp(one) >= 0.85)
    assert np.all(np.exp(one) <= 1.15 + rounding)
    assert np.abs(one).max() > 0.95 * bound  # the tolerance is used, not a narrower one
    documented = spread.sigma * truncated_sd()  # 0.0615 in ln(Cv)
    assert documented == pytest.approx(math.log(1.15) / 2 * 0.8796, rel=1e-3)
    for column in one.T:  # each valve on its own: 400 draws
        assert column.std() == pytest.approx(documented, rel=0.10)
        assert abs(column.mean()) < 3 * documented / math.sqrt(400)  # median = catalogue
    # scale 2: the same plants, twice as far from the catalogue (twice the spread)
    np.testing.assert_allclose(two, 2 * one, atol=2 * rounding)
    assert np.all(np.abs(two) <= 2 * bound + rounding)
    for column in two.T:
        assert column.std() == pytest.approx(2 * documented, rel=0.10)
    # different valves of one plant are drawn independently
    corr = np.corrcoef(one.T)[np.triu_indices(one.shape[1], 1)]
    assert np.abs(corr).max() < 0.2


def test_sensor_calibration_within_class_accuracy(two_axis: MachineDescription) -> None:
    twin = load_machine("festo-dsd")
    plants = [vary_machine(twin, 1.0, seed) for seed in range(100)]
    for kind, gain_bound, offset_fs in (("pressure", 0.01, 0.01), ("flow", 0.03, 0.003)):
        gains = np.array([s.gain for p in plants for s in p.sensors if s.kind == kind])
        offsets = np.array(
            [s.offset / (s.range_high - s.range_low) for p in plants for s in p.sensors]
        )[[s.kind == kind for p in plants for s in p.sensors]]
        assert np.all(np.abs(gains - 1.0) <= gain_bound + 1e-5)
        assert np.abs(gains - 1.0).max() > 0.9 * gain_bound
        assert np.all(np.abs(offsets) <= offset_fs + 1e-6)
        assert (gains - 1).std() == pytest.approx(gain_bound / 2 * truncated_sd(), rel=0.1)
    # absent gain/offset keys are varied from 1 and 0 and written out
    plant = vary_machine(two_axis, 1.0, 5)
    for table in plant.raw["sensor"]:
        assert table["gain"] != 1.0
        assert table["offset"] != 0.0
    assert "gain" not in two_axis.raw["sensor"][0]


def test_supply_set_point_friction_and_throttles(two_axis: MachineDescription) -> None:
    twin = load_machine("festo-dsd")
    set_bound = 0.16e5 / 6894.757293168361  # 0.16 bar in psi
    for seed in range(60):
        p = vary_machine(twin, 1.0, seed)
        assert abs(p.supply.regulator_set_psig - 72.0) <= set_bound + 1e-3
        for a, b in zip(twin.actuators, p.actuators, strict=True):
            # one seal, one draw: the breakaway/Coulomb ratio is kept
            assert b.static_friction_n / b.coulomb_friction_n == pytest.approx(
                a.static_friction_n / a.coulomb_friction_n, rel=1e-4
            )
            assert b.valve.xt <= 1.0
            for side in "ab":
                ratio = getattr(b, f"meter_out_cv_{side}") / getattr(a, f"meter_out_cv_{side}")
                assert 1 / 1.5 - 1e-4 <= ratio <= 1.5 + 1e-4
        # the small machine: set point 3 psi below the house air stays below it at scale 5
        q = vary_machine(two_axis, 5.0, seed)
        assert q.supply.regulator_set_psig < q.supply.house_psig
    plant = vary_machine(two_axis, 1.0, 3)
    lift, turn, push = (plant.raw["actuator"][i] for i in range(3))
    # one throttle for both lines becomes two needle valves, in the same place
    assert "meter_out_cv" not in lift
    assert lift["meter_out_cv_a"] != lift["meter_out_cv_b"]
    assert list(lift).index("meter_out_cv_a") == list(two_axis.raw["actuator"][0]).index(
        "meter_out_cv"
    )
    # a throttle on B only stays on B only; no throttle stays none (free exhaust)
    assert "meter_out_cv_a" not in turn
    assert turn["meter_out_cv_b"] != 0.03
    assert "meter_out_cv_a" not in push
    assert "meter_out_cv_b" not in push
    assert (turn["angle_deg"], turn["lever_mm"]) == (90.0, 10.0)
    # defaults absent from the file are varied from their default and written out
    # (xt only when drawn below its default 1.0: above it is clipped to 1.0, unchanged)
    assert lift["valve"].get("xt", 1.0) <= 1.0
    assert "xt" in push["valve"] or "xt" in turn["valve"] or "xt" in lift["valve"]
    assert lift["valve"]["on_delay_s"] != 0.020


def test_draws_do_not_depend_on_other_parameters(two_axis: MachineDescription) -> None:
    """Removing an actuator leaves every other parameter's draw as it was."""
    raw = tomllib.loads(TWO_AXIS)
    del raw["actuator"][2]
    raw["step"][1]["do"] = raw["step"][1]["do"][:1]
    raw["step"][3]["do"] = raw["step"][3]["do"][:1]
    smaller = parse_description(raw, "smaller.toml")
    full, part = vary_machine(two_axis, 1.0, 9), vary_machine(smaller, 1.0, 9)
    assert full.actuators[:2] == part.actuators
    assert full.supply == part.supply
    assert full.sensors == part.sensors


@pytest.mark.parametrize("scale", [1.0, 2.0, 5.0])
def test_every_plant_is_valid(scale: float, two_axis: MachineDescription) -> None:
    for name in (*builtin_machines(), two_axis):
        for seed in range(40):
            plant = vary_machine(name, scale, seed)
            # valid like any description: it parses again from its own TOML
            again = parse_description(tomllib.loads(machine_to_toml(plant)))
            assert _same_values(again, plant)


def test_varied_plants_simulate(two_axis: MachineDescription) -> None:
    for name in builtin_machines():
        for scale, seed in ((1.0, 1), (1.0, 2), (2.0, 3)):
            rec = simulate(vary_machine(name, scale, seed), cycles=1, seed=1)
            assert rec.duration > 1.0
            assert rec.metadata["machine"]["name"] == name
    for scale, seed in ((1.0, 1), (2.0, 2)):
        rec = simulate(vary_machine(two_axis, scale, seed), cycles=1, seed=1)
        assert rec.duration > 0.1


def test_toml_round_trip(two_axis: MachineDescription) -> None:
    for m in (load_machine("festo-dsd"), vary_machine("festo-dsd", 1.0, 7), two_axis):
        text = machine_to_toml(m, header="line one\nline two")
        assert text.startswith("# line one\n# line two\n\n[machine]")
        assert _same_values(parse_description(tomllib.loads(text), "x.toml"), m)
    edited = replace(two_axis, name="other")
    with pytest.raises(MachineError, match="parse_description"):
        machine_to_toml(edited)


def test_write_machine(tmp_path: Path) -> None:
    plant = vary_machine("festo-dsd", 1.0, 7)
    out = write_machine(plant, tmp_path / "plant.toml", header="plant")
    assert out == tmp_path / "plant.toml"
    assert out.read_text("utf-8") == machine_to_toml(plant, "plant")
    with pytest.raises(FileExistsInputError, match=r"plant\.toml"):
        write_machine(vary_machine("festo-dsd", 1.0, 8), out)
    assert out.read_text("utf-8") == machine_to_toml(plant, "plant")  # untouched
    other = vary_machine("festo-dsd", 1.0, 8)
    write_machine(other, out, overwrite=True)
    assert _same_values(load_machine(out), other)
    # never onto the description it was made from, even with overwrite
    source = load_machine(out)
    with pytest.raises(InputError, match="made from"):
        write_machine(vary_machine(source, 1.0, 1), out, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plant.toml"]  # no temp files
    with pytest.raises(InputError, match="folder"):
        write_machine(plant, tmp_path / "missing" / "plant.toml")


@pytest.mark.parametrize("scale", [-0.1, math.nan, math.inf, 5.5, "1", True, None])
def test_bad_scale(scale: object) -> None:
    with pytest.raises(InputError, match=r"scale: received .*allowed: a number from 0 to 5"):
        vary_machine("festo-dsd", scale, 1)  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", [-1, 1.5, True, "7", None])
def test_bad_seed(seed: object) -> None:
    with pytest.raises(InputError, match=r"seed: received .*non-negative integer"):
        vary_machine("festo-dsd", 1.0, seed)  # type: ignore[arg-type]


def test_parameter_changes(two_axis: MachineDescription) -> None:
    twin = load_machine("festo-dsd")
    plant = vary_machine(twin, 1.0, 7)
    changes = parameter_changes(twin, plant)
    sizes = [abs(c.relative) for c in changes]
    assert sizes == sorted(sizes, reverse=True)
    cv = next(c for c in changes if c.path == "actuator[DNC].valve.cv")
    assert cv.reference == 0.3971
    assert cv.plant == plant.actuators[0].valve.cv
    assert cv.relative == pytest.approx(cv.plant / 0.3971 - 1)
    offset = next(c for c in changes if c.path == "sensor[Q_In].offset")
    assert offset.basis == "span"
    assert offset.relative == pytest.approx(offset.plant / 200.0)
    assert str(offset).endswith("% of span")
    with pytest.raises(InputError, match="actuators"):
        parameter_changes(twin, two_axis)


def test_docs_table_lists_every_spread() -> None:
    text = DOCS.read_text("utf-8")
    for key, spread in SPREADS.items():
        assert f"`{key}`" in text, key
        assert spread.bound > 0
    assert TRUNCATION == 2.0


def test_cli_vary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plant.toml"
    args = ["machine", "vary", "festo-dsd", "--scale", "1", "--seed", "7", "--out", str(out)]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "plant.toml" in err
    assert "largest" in err
    assert "%" in err
    text = out.read_text("utf-8")
    assert text.startswith("# plant varied from festo-dsd at scale 1, seed 7 by pneufdd")
    assert _same_values(load_machine(out), vary_machine("festo-dsd", 1.0, 7))
    # refuses to overwrite without --overwrite, and leaves the file alone
    assert main([*args[:-2], "--seed", "8", "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert out.read_text("utf-8") == text
    assert main([*args[:-2], "--seed", "8", "--out", str(out), "--overwrite"]) == 0
    assert out.read_text("utf-8") != text
    # a TOML path as DESCRIPTION; never written onto itself
    plant2 = tmp_path / "plant2.toml"
    assert main(["machine", "vary", str(out), "--seed", "1", "--out", str(plant2)]) == 0
    assert main(["machine", "vary", str(out), "--out", str(out), "--overwrite"]) == 2
    capsys.readouterr()


@pytest.mark.parametrize("scale", ["-1", "nan", "6"])
def test_cli_bad_scale(scale: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plant.toml"
    assert main(["machine", "vary", "festo-dsd", "--scale", scale, "--out", str(out)]) == 2
    assert "--scale" in capsys.readouterr().err
    assert not out.exists()


def test_cli_bad_seed_and_machine(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plant.toml"
    assert main(["machine", "vary", "festo-dsd", "--seed", "-1", "--out", str(out)]) == 2
    assert "--seed" in capsys.readouterr().err
    assert main(["machine", "vary", "no-such-rig", "--out", str(out)]) == 2
    assert "no-such-rig" in capsys.readouterr().err
    assert not out.exists()


def test_cushion_screws_vary_where_described_and_leave_other_draws() -> None:
    # issue 34: a described PPV cushioning's two screws are set by hand (+-50 %); a
    # description without cushioning stays without, and adding one moves no other draw
    import copy

    from pneufdd.sim import load_machine, parse_description, vary_machine

    twin = load_machine("festo-dsd")
    raw = copy.deepcopy(twin.raw)
    raw["actuator"][0].update(cushion_length_mm=20.0, cushion_cv=0.03)
    cushioned = parse_description(raw, "festo-dsd with PPV")
    plant = vary_machine(cushioned, scale=1.0, seed=11)
    dnc = plant.actuators[0]
    assert dnc.cushion_length_mm == 20.0
    for cv in (dnc.cushion_cv_a, dnc.cushion_cv_b):
        assert 0.03 / 1.5 <= cv <= 0.03 * 1.5
    assert dnc.cushion_cv_a != dnc.cushion_cv_b
    plain = vary_machine(twin, scale=1.0, seed=11)
    assert plain.actuators[0].cushion_length_mm == 0.0
    assert plain.actuators[1:] == plant.actuators[1:]
    assert plain.actuators[0].valve == dnc.valve
    assert vary_machine(cushioned, scale=0.0, seed=11).actuators[0].cushion_cv_a == 0.03
