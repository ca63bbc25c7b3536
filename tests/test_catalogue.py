"""Order codes and the catalogue tables (issue 35, item 1)."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pneufdd.calibration.parameters import machine_parameters
from pneufdd.catalogue import (
    actuator_from_code,
    parse_actuator_code,
    parse_valve_code,
    valve_from_code,
)
from pneufdd.catalogue.tables import families, ports, sizes, sources, valve_rows
from pneufdd.cli.app import main
from pneufdd.errors import InputError, MachineError
from pneufdd.physics.flow import isa_mass_flow
from pneufdd.physics.units import bar_gauge_to_pa, kg_s_to_l_min_anr
from pneufdd.physics.valve_rating import (
    cv_from_nominal_flow,
    isa_from_sonic_conductance,
    nominal_flow_from_sonic_conductance,
)
from pneufdd.sim import load_machine, parse_description, simulate, vary_machine
from pneufdd.sim.variation import machine_to_toml

SEED = 53_000  # this file's seeds (development seeds, not acceptance)
STATUS_WORDS = ("verified", "standard value", "unverified", "assumption", "as the festo-dsd twin")


def test_every_row_cites_a_known_source_and_a_status() -> None:
    known = sources()
    for row in sizes().values():
        assert row.source in known, row
        assert row.family in families()
        assert row.port in ports()
        assert row.status.startswith(STATUS_WORDS), row
    for row in valve_rows().values():
        assert row.source in known, row
        assert row.status.startswith((*STATUS_WORDS, "not found")), row
        # a row either has flow data or says it was not found
        has_flow = row.nominal_flow_l_min_anr is not None or row.sonic_conductance_dm3_s_bar
        assert bool(has_flow) != row.status.startswith("not found"), row
    for fam in families().values():
        assert any(f == fam.family for f, _ in sizes()), fam


def test_every_family_the_issue_names_parses() -> None:
    actuators = {
        "DSBC-63-100-PPVA-N3": ("linear", 63.0, 20.0, 100.0),
        "DNC-32-200-PPV-A": ("linear", 32.0, 12.0, 200.0),  # Table 3.1, Fig. 4.10
        "DSNU-20-50-PPV-A": ("linear", 20.0, 8.0, 50.0),
        "ADN-25-15-A-P-A": ("linear", 25.0, 10.0, 15.0),
        "DFM-25-100-P-A-GF": ("slide", 25.0, 10.0, 100.0),
        "DHPS-16-A": ("gripper", 16.0, 0.0, 6.0),
        "C96SDB50-200": ("linear", 50.0, 20.0, 200.0),
        "CP96SDB32-100C": ("linear", 32.0, 12.0, 100.0),
        "CDQ2B32-50DZ": ("linear", 32.0, 16.0, 50.0),
        "MGPM20-100Z": ("slide", 20.0, 10.0, 100.0),
        "ISO 15552 40x250": ("linear", 40.0, 16.0, 250.0),
        "ISO6432-16-40": ("linear", 16.0, 6.0, 40.0),
        "iso 21287 25x15": ("linear", 25.0, 10.0, 15.0),
    }
    for code, (kind, bore, rod, stroke) in actuators.items():
        a = actuator_from_code(code)
        assert (a.kind, a.bore_mm, a.rod_mm, a.stroke_mm) == (kind, bore, rod, stroke), code
    drive = actuator_from_code("DRQD-16-90")  # twin 16 mm pistons, festo-dsd's lever
    assert drive.bore_mm == pytest.approx(16.0 * math.sqrt(2.0))
    assert drive.stroke_mm == pytest.approx(math.pi / 2 * 10.0)
    valves = {
        "VUVG-L14-M52-MT-G18": "5/2-monostable",
        "VUVG-L10-B52-T-M5": "5/2-bistable",
        "VUVG-L18-P53C-T-G14": "5/3-closed-centre",
        "CPE14-M1BH-5/3G-1/8": "5/3-closed-centre",
        "CPE10-M1BH-5J-M7": "5/2-bistable",
        "VUVS-L20-M52-MD-G18-F7": "5/2-monostable",
        "SY5120-5LZD-01": "5/2-monostable",
        "SY3320-5LZD-M5": "5/3-closed-centre",
    }
    for code, kind in valves.items():
        assert valve_from_code(code).kind == kind, code
    assert valve_from_code("VUVS-L20-M52-MD-G18-F7").cv is None  # no flow data found


def test_options_through_rod_and_twin_pistons() -> None:
    plain, through = actuator_from_code("DNC-32-200-PPV-A"), actuator_from_code("DNC-32-200-S2")
    assert parse_actuator_code("DNC-32-200-PPV-A").options == ("PPV", "A")
    # the annulus on both sides: both chambers of the equivalent piston have it
    annulus = math.pi / 4 * (32.0**2 - 12.0**2)
    assert through.piston_area_mm2 == pytest.approx(annulus)
    assert through.rod_mm == 0.0
    assert plain.piston_area_mm2 > through.piston_area_mm2
    slide = actuator_from_code("SLT-10-80-A-CC-B")  # festo-dsd's twin 10 mm pistons
    assert slide.bore_mm == pytest.approx(14.142, abs=1e-3)
    assert slide.rod_mm == pytest.approx(5.657, abs=1e-3)


def test_published_valve_ratings() -> None:
    # SMC CAT.EUS11-83B: Q [l/min (ANR)] of the SY series from its C and b
    for c, b, q in ((1.1, 0.28, 276), (2.8, 0.37, 746), (4.5, 0.28, 1130), (10.0, 0.29, 2527)):
        assert nominal_flow_from_sonic_conductance(c, b) == pytest.approx(q, rel=0.002)
        cv, xt = isa_from_sonic_conductance(c, b)
        assert xt == pytest.approx(1.0 - b)
        passed = isa_mass_flow(bar_gauge_to_pa(6.0), bar_gauge_to_pa(5.0), cv, xt)
        assert kg_s_to_l_min_anr(passed) == pytest.approx(q, rel=0.002)
    # the dissertation's CPE14: 410 l/min, Cv 0.3971 at xT 1.0 on the ISA basis (the
    # catalogue's litres are ANR: 2.3 % less air per litre than the ISA standard's)
    cpe = valve_from_code("CPE14-M1BH-5/3G-1/8")
    assert cpe.cv == pytest.approx(0.3971, rel=0.03)
    # docs/machines.md: 1050 l/min (ANR) per Cv at xT 0.9
    assert 560.0 / cv_from_nominal_flow(560.0) == pytest.approx(1051.25, abs=0.1)


@pytest.mark.parametrize(
    ("code", "part"),
    [
        ("DSBC-33-100", "size"),
        ("DSBC-63-abc", "stroke"),
        ("XYZ-1-2", "family"),
        ("DRQD-16-400", "swivel angle"),
        ("", "actuator order code"),
    ],
)
def test_a_bad_actuator_code_names_its_part(code: str, part: str) -> None:
    with pytest.raises(InputError) as err:
        actuator_from_code(code)
    text = str(err.value)
    assert part in text
    if code:
        assert code.upper() in text


def test_a_valve_function_the_twin_has_not_is_refused() -> None:
    with pytest.raises(InputError, match=r"P53E.*5/3 closed centre"):
        valve_from_code("VUVG-L14-P53E")
    with pytest.raises(InputError, match="family of valve order code 'FOO-1'"):
        parse_valve_code("FOO-1")


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=40))
def test_any_text_parses_or_is_refused_by_name(text: str) -> None:
    for lookup in (actuator_from_code, valve_from_code):
        try:
            lookup(text)
        except InputError as exc:
            message = str(exc)
        else:
            message = "order code resolved"
        assert "order code" in message


def test_a_description_takes_its_geometry_from_the_codes() -> None:
    twin = load_machine("press-fit-cell")
    raw = copy.deepcopy(twin.raw)
    press = raw["actuator"][2]
    for key in ("kind", "bore_mm", "rod_mm", "stroke_mm", "dead_volume_a_cm3"):
        del press[key]
    press["valve"] = {"catalogue": "VUVG-L18-P53C-T-G14"}
    coded = parse_description(raw, "coded.toml")
    ram, built_in = coded.actuators[2], twin.actuators[2]
    assert (ram.bore_mm, ram.rod_mm, ram.stroke_mm) == (63.0, 20.0, 80.0)
    assert ram.dead_volume_a_cm3 == pytest.approx(12.469, abs=1e-3)  # 4 mm of bore
    assert ram.dead_volume_b_cm3 == built_in.dead_volume_b_cm3  # given: the table's wins
    assert ram.valve.kind == "5/3-closed-centre"
    assert ram.valve.cv == pytest.approx(built_in.valve.cv, rel=0.01)  # 0.9 x 870 l/min
    # the raw mapping states every value, so TOML, plants and calibration see them
    assert coded.raw["actuator"][2]["bore_mm"] == 63.0
    assert "bore_mm" not in raw["actuator"][2]  # the caller's mapping is not changed
    again = parse_description(tomllib.loads(machine_to_toml(coded)), "again.toml")
    assert again.actuators == coded.actuators
    plant = vary_machine(coded, scale=2.0, seed=SEED)
    assert plant.actuators[2].bore_mm == 63.0  # the code states it: never varied
    assert plant.actuators[2].valve.catalogue == "VUVG-L18-P53C-T-G14"


def test_a_description_refuses_a_code_that_contradicts_it() -> None:
    raw = copy.deepcopy(load_machine("press-fit-cell").raw)
    raw["actuator"][1]["valve"]["catalogue"] = "VUVG-L14-B52-T-G18"  # CLAMP is monostable
    with pytest.raises(MachineError, match=r"actuator\[1\]\.valve\.kind"):
        parse_description(raw, "x.toml")
    raw = copy.deepcopy(load_machine("press-fit-cell").raw)
    raw["actuator"][0]["catalogue"] = "DFM-26-100"
    with pytest.raises(MachineError, match=r"x\.toml: actuator\[0\]\.catalogue: size"):
        parse_description(raw, "x.toml")
    raw["actuator"][0]["catalogue"] = 25
    with pytest.raises(MachineError, match=r"actuator\[0\]\.catalogue"):
        parse_description(raw, "x.toml")


def test_the_built_in_machines_name_their_parts() -> None:
    for name in ("festo-dsd", "press-fit-cell", "carton-sorter"):
        machine = load_machine(name)
        for a in machine.actuators:
            assert a.catalogue, (name, a.id)
            assert a.valve.catalogue, (name, a.id)
            found = actuator_from_code(a.catalogue)
            assert found.kind == a.kind
            assert found.stroke_mm == pytest.approx(a.stroke_mm, rel=1e-6)
            assert found.bore_mm == pytest.approx(a.bore_mm, rel=0.01)
            assert valve_from_code(a.valve.catalogue).kind == a.valve.kind


@pytest.fixture(scope="module")
def press_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    plant = vary_machine(load_machine("press-fit-cell"), scale=2.0, seed=SEED + 1)
    path = tmp_path_factory.mktemp("codes") / "press.parquet"
    simulate(plant, cycles=3, seed=SEED + 2).write(path)
    return path


def test_machine_draft_with_codes(press_recording: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "draft.toml"
    code = main(
        ["machine", "draft", str(press_recording), "--out", str(out),
         "--actuator", "PRESS=DSBC-63-80-PPVA-N3", "--valve", "PRESS=VUVG-L18-P53C-T-G14",
         "--actuator", "clamp=ADN-25-15-A-P-A"]
    )  # fmt: skip
    assert code == 0
    err = capsys.readouterr().err
    assert "actuators found: FEED (no order code), CLAMP (code ADN-25-15-A-P-A)" in err
    assert "--actuator FEED=<order code>" in err
    assert "--valve CLAMP=<order code>" in err
    assert "--actuator PRESS" not in err.split("add the codes")[1]
    text = out.read_text()
    drafted = load_machine(out)
    ram = drafted.actuators[2]
    assert (ram.bore_mm, ram.rod_mm, ram.stroke_mm, ram.valve.kind) == (
        63.0, 20.0, 80.0, "5/3-closed-centre"
    )  # fmt: skip
    assert ram.code_drafted
    assert not ram.drafted
    assert drafted.actuators[0].drafted  # FEED: no code, geometry assumed
    line = next(x for x in text.splitlines() if x.startswith("bore_mm = 63.0"))
    assert "# from catalogue DSBC-63-80-PPVA-N3 [iso15552:" in line
    assert any(x.startswith("tube_inner_diameter_mm = 7.0") and "G3/8 port" in x
               for x in text.splitlines())  # fmt: skip
    # the CLAMP's valve: sized to its M5 port (no valve code), VUVG-L10's 220 l/min
    assert drafted.actuators[1].valve.cv == pytest.approx(cv_from_nominal_flow(220.0), rel=1e-3)
    # calibration: a code makes the geometry described, the rest stays assumed
    priors = {p.name: p.prior_sigma for p in machine_parameters(drafted)}
    assert priors["PRESS.volume"] == 0.3
    assert priors["PRESS.valve_cv"] == 0.3  # its valve has a code
    assert priors["PRESS.meter_out_cv_a"] == 1.0  # throttles set by hand, assumed
    assert "CLAMP.valve_cv" not in priors  # sized to its port, not fitted to durations
    assert priors["FEED.volume"] == 1.0  # no code: the drafted size


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("--actuator=PRESS=DSBC-66-80", "--actuator PRESS=DSBC-66-80: size of order code"),
        ("--actuator=PRESS", "ID=CODE"),
        ("--valve=CLAMP=VUVG-L14-B52-T-G18", "show a 5/2-monostable valve for CLAMP"),
        ("--actuator=NOPE=DSBC-63-80", "--actuator actuator id: received 'NOPE'"),
    ],
)
def test_machine_draft_refuses_bad_codes(
    press_recording: Path, tmp_path: Path, capsys, option: str, message: str
) -> None:
    out = tmp_path / "draft.toml"
    code = main(["machine", "draft", str(press_recording), "--out", str(out), option])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
