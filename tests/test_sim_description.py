"""Machine description: loading, validation messages, the built-in festo-dsd rig."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from pneufdd.errors import InputError, MachineError
from pneufdd.sim import builtin_machines, load_machine, parse_description, parse_leak_size
from pneufdd.sim.compile import series_cv, tube_cv
from pneufdd.sim.leaks import resolve_leaks


def _raw() -> dict[str, Any]:
    text = (resources.files("pneufdd.sim") / "machines" / "festo-dsd.toml").read_text("utf-8")
    return tomllib.loads(text)


def test_festo_dsd_matches_the_dissertation() -> None:
    m = load_machine("festo-dsd")
    assert m.actuator_ids == (
        "DNC", "DRQD", "DGPL", "SLT", "HMPL_H", "HMPL_HZ", "HMPL_V", "HMPL_VS", "HGD2",
    )  # fmt: skip
    assert len(m.steps) == 58
    dnc = m.actuators[0]
    assert (dnc.bore_mm, dnc.rod_mm, dnc.stroke_mm) == (32.0, 12.0, 200.0)  # Fig. 4.10
    assert dnc.moving_mass_kg == pytest.approx(1.3 * 0.45359237, abs=1e-3)
    assert dnc.valve.kind == "5/3-closed-centre"
    assert (dnc.valve.on_delay_s, dnc.valve.off_delay_s) == (0.020, 0.042)  # Fig. 4.3
    assert m.supply.regulator_set_psig < 80.0
    assert m.supply.reservoir_volume_l == 2.0  # CRVZS-2
    # Fig. 3.4: DNC retracts in step 2 and extends in step 58
    assert [a.solenoid for a in m.steps[1].actions][:1] == ["U_DNC_B"]
    assert "U_DNC_A" in [a.solenoid for a in m.steps[57].actions]
    assert [a.solenoid for a in m.steps[53].actions] == ["U_HMPL_V_A"]
    assert [a.solenoid for a in m.steps[54].actions] == ["U_HGD2_B"]
    assert [a.solenoid for a in m.steps[56].actions] == ["U_HMPL_VS_B"]
    channels = {s.channel for s in m.sensors}
    assert channels == {
        "P_In", "Q_In", "P_DNC_A", "P_DNC_B", "Q_DNC_A", "Q_DNC_B",
        "P_HMPL_V_A", "P_HMPL_V_B", "Q_HMPL_V_A", "Q_HMPL_V_B", "X_DNC",
    }  # fmt: skip
    assert "U_VAC" in m.solenoids
    assert "S_VAC" in m.switches
    assert builtin_machines() == ("carton-sorter", "festo-dsd", "press-fit-cell")


def test_load_from_path(tmp_path: Path) -> None:
    src = resources.files("pneufdd.sim") / "machines" / "festo-dsd.toml"
    path = tmp_path / "rig.toml"
    path.write_text(src.read_text("utf-8"), "utf-8")
    assert load_machine(path).name == "festo-dsd"
    assert load_machine(str(path)).source == str(path)


def test_error_names_file_key_value_and_allowed(tmp_path: Path) -> None:
    raw = _raw()
    raw["actuator"][0]["valve"]["kind"] = "4/2"
    with pytest.raises(MachineError) as err:
        parse_description(raw, "rig.toml")
    msg = str(err.value)
    assert "rig.toml" in msg
    assert "actuator[0].valve.kind" in msg
    assert "'4/2'" in msg
    assert "5/3-closed-centre" in msg


@pytest.mark.parametrize(
    ("edit", "fragment"),
    [
        (lambda r: r["supply"].__setitem__("regulator_set_psig", 96.0), "only reduces pressure"),
        (lambda r: r["supply"].__setitem__("regulator_set_psig", 150.0), "regulator_set_psig"),
        (lambda r: r["actuator"][0].__setitem__("rod_mm", 40.0), "rod_mm"),
        (lambda r: r["actuator"][0].__setitem__("bore_mm", "big"), "a number"),
        (lambda r: r["actuator"][1].__setitem__("id", "DNC"), "unique"),
        (lambda r: r["step"][0]["do"][0].__setitem__("until", "S_NOPE"), "S_NOPE"),
        (lambda r: r["supply"].__setitem__("colour", "blue"), "colour"),
        (lambda r: r["step"][0]["do"][0].__setitem__("until", "S_DRQD_A"), "S_DRQD_B"),
        (lambda r: r["sensor"][0].__setitem__("location", "DNC_C"), "DNC_C"),
    ],
)
def test_invalid_fields_are_rejected(edit: Any, fragment: str) -> None:
    raw = _raw()
    edit(raw)
    with pytest.raises(MachineError, match=fragment):
        parse_description(raw, "x.toml")


def test_unknown_machine_and_bad_toml(tmp_path: Path) -> None:
    with pytest.raises(MachineError, match="festo-dsd"):
        load_machine("no-such-rig")
    bad = tmp_path / "bad.toml"
    bad.write_text("[machine\n", "utf-8")
    with pytest.raises(MachineError, match=r"bad\.toml"):
        load_machine(bad)


def test_leak_sizes_and_locations() -> None:
    m = load_machine("festo-dsd")
    assert parse_leak_size(2.5) == (2.5, "turns")
    assert parse_leak_size("2.5mm") == (2.5, "mm")
    assert parse_leak_size("30slpm") == (30.0, "SLPM")
    for bad in ("7", "-1", "big", True):
        with pytest.raises(InputError):
            parse_leak_size(bad)
    with pytest.raises(InputError, match="HMPL_V_B"):
        resolve_leaks(m, {"DNC_C": 2})
    specs = resolve_leaks(m, {"supply": "30slpm", "DNC_B": 4, "HGD2_A": "1.0mm"})
    by = {s.location: s for s in specs}
    assert by["supply"].nominal_slpm == pytest.approx(30.0, rel=1e-6)
    assert by["DNC_B"].area_m2 > 0
    assert by["DNC_B"].nominal_slpm > by["supply"].nominal_slpm  # 4 turns > 30 SLPM
    turns = [resolve_leaks(m, {"DNC_A": n})[0].nominal_slpm for n in (1, 2, 4, 6)]
    assert turns == sorted(turns)
    assert 5.0 < turns[0] < 20.0
    assert 150.0 < turns[-1] < 260.0


def test_series_restrictions() -> None:
    # Crane TP-410 tube formula; series combination never exceeds the smallest element
    assert tube_cv(2.0, 4.0) < tube_cv(1.0, 4.0) < tube_cv(1.0, 6.0)
    assert series_cv(0.4, 0.3, 0.1) < 0.1
    assert series_cv(0.4, 0.4) == pytest.approx(0.4 / 2**0.5)


def test_six_bar_machine_is_described() -> None:
    # the 80 psig limit was the rig's flow meter, not a property of machines
    raw = _raw()
    raw["supply"]["house_psig"] = 110.0
    raw["supply"]["regulator_set_psig"] = 87.0  # 6 bar(g)
    assert parse_description(raw, "six-bar.toml").nominal_supply_psig == 87.0


def _monostable(raw: dict[str, Any], ident: str) -> None:
    index = [a["id"] for a in raw["actuator"]].index(ident)
    raw["actuator"][index]["valve"]["kind"] = "5/2-monostable"
    raw["actuator"][index]["valve"].pop("catalogue", None)  # its code names a bistable valve


def test_monostable_valve_has_one_solenoid() -> None:
    raw = _raw()
    _monostable(raw, "DGPL")
    # steps 6 and 10 drive DGPL out and back with both solenoids: refused, with the fix
    with pytest.raises(MachineError, match=r"U_DGPL_B.*reset = \"U_DGPL_A\""):
        parse_description(raw, "x.toml")
    for step in raw["step"]:
        for action in step.get("do", []):
            if action.get("set") == "U_DGPL_A":
                action.pop("until")
            if action.get("set") == "U_DGPL_B":
                del action["set"], action["until"]
                action["reset"] = "U_DGPL_A"
                step["wait"] = ["S_DGPL_A"]
            elif action.get("set") == "U_DGPL_A" or action.get("reset") == "U_DGPL_A":
                step["wait"] = ["S_DGPL_B"]
    m = parse_description(raw, "x.toml")
    assert "U_DGPL_A" in m.solenoids
    assert "U_DGPL_B" not in m.solenoids
    assert {"S_DGPL_A", "S_DGPL_B"} <= set(m.switches)


def test_monostable_actuator_rests_retracted() -> None:
    raw = _raw()
    _monostable(raw, "DNC")  # DNC starts extended on the rig
    with pytest.raises(MachineError, match="spring"):
        parse_description(raw, "x.toml")
