"""The issue-33 rig end to end from the CLI, with what a real DAQ does that the twin does not.

The rig: a DSNU-20-200 on a 5/2 double-solenoid valve, every channel recorded at 1 kHz
in 10 s triggered captures holding one cycle and the idle time after it (the machine
waits for the next part), the retract solenoid on at t = 0, the supply pressure
quantised in 0.19 bar steps, the flows into and out of chamber A as two unsigned
meters, both solenoids, both end switches, the position, no supply flow meter. On
top of the twin: sensor offsets, switch bounce, trigger jitter. Exported as the PLC's
tools write CSV (each preset), read through a tag map, never edited by hand
(``docs/captures.md``, "A real rig, step by step").
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.physics.constants import ANR
from pneufdd.physics.leaks import leak_mass_flow
from pneufdd.physics.units import kg_s_to_slpm, psig_to_pa
from pneufdd.recording import Recording
from pneufdd.recording.field_export import EXPORT_FORMATS, write_field_export
from pneufdd.recording.model import DIGITAL, Channel
from pneufdd.sim import as_exported, load_machine
from pneufdd.sim.captures import crop, quantize, simulate_captures
from pneufdd.sim.variation import vary_machine

RIG = Path(__file__).parent / "data" / "triggered-rig.toml"
CAPTURE_S = 10.0
PRE_TRIGGER_S = 0.22
JITTER_S = 0.020
P_QUANTUM = 19_000.0  # 0.19 bar [Pa]
ZERO_OFFSET = 0.02e-3 / 60 * ANR.density  # each one-direction meter reads 0.02 l/min at rest
TAGS = {  # channel -> the rig's tag and the unit its tool exports
    "P_In": ("B_P1", "bar(g)"),
    "Q_CYL_A.in": ("FT1_in", "l/min (ANR)"),
    "Q_CYL_A.out": ("FT1_out", "l/min (ANR)"),
    "X_CYL": ("B_X1", "mm"),
    "U_CYL_A": ("Y1", "1"),
    "U_CYL_B": ("Y2", "1"),
    "S_CYL_A": ("B1", "1"),
    "S_CYL_B": ("B2", "1"),
}
PREFIX = {"tia-trace": '"DB_Pneu".', "codesys-trace": "PLC_PRG."}


def _plant(tmp: Path) -> object:
    """The real rig: its PLC waits ~9 s for the next part after the retract stroke
    (the description as written knows only its 0.5 s timer), parameters off the
    catalogue (plant scale 1)."""
    text = RIG.read_text().replace(
        'wait = ["S_CYL_A"]\ndwell_s = 0.5', 'wait = ["S_CYL_A"]\ndwell_s = 9.0'
    )
    assert "dwell_s = 9.0" in text
    (tmp / "idle.toml").write_text(text)
    return vary_machine(load_machine(tmp / "idle.toml"), 1.0, 2_610_000)


def _bounce(values: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    out = values.copy()
    for edge in np.flatnonzero(np.diff(values.astype(np.int8))):
        for k in (1, 2, 3):  # contacts chatter for up to 3 ms after each edge
            if edge + k < out.size and rng.random() < 0.7:
                out[edge + k] = 1 - out[edge + k]
    return out


def field_capture(capture: Recording, rng: np.random.Generator) -> Recording:
    """A twin capture as the rig's DAQ records it (see the module docstring)."""
    late = rng.integers(0, round(JITTER_S * 1000) + 1) / 1000.0  # trigger jitter
    capture = crop(capture, late, late + CAPTURE_S)
    clock = capture.info("X_CYL")  # the DAQ's 1 kHz clock
    channels = []
    for name in capture.channels:
        info = capture.info(name)
        if info.kind == DIGITAL:  # the PLC's 100 Hz outputs sampled on the DAQ's clock
            last = np.floor((clock.time - info.t0) * info.rate_hz + 1e-9).astype(np.int64)
            values = info.values[np.clip(last, 0, info.values.size - 1)]
            if name.startswith("S_"):
                values = _bounce(values, rng)
            channels.append(Channel(name, values, clock.rate_hz, "1", DIGITAL, clock.t0))
        elif name == "Q_CYL_A":  # two unsigned meters, each with its zero offset
            q = np.asarray(info.values, dtype=np.float64)
            for part, flow in (("in", q), ("out", -q)):
                values = np.clip(flow, 0.0, None) + ZERO_OFFSET
                channels.append(Channel(f"Q_CYL_A.{part}", values, 1000.0, "kg/s", t0=info.t0))
        elif name == "P_In":  # a transducer reading 0.03 bar high
            values = np.asarray(info.values, dtype=np.float64) + 3000.0
            channels.append(Channel(name, values, 1000.0, "Pa", t0=info.t0))
        elif name != "Q_CYL_B":  # no meter on chamber B
            channels.append(info)
    return quantize(Recording(channels, start_time=capture.start_time), {"P_In": P_QUANTUM})


def _tags(export_format: str) -> dict[str, tuple[str, str]]:
    prefix = PREFIX.get(export_format, "")
    return {name: (prefix + tag, unit) for name, (tag, unit) in TAGS.items()}


def tag_map(export_format: str) -> str:
    """The role map a user writes for the rig's export (the preset gives the layout)."""
    lines = [f'preset = "{export_format}"', "[columns]"]
    for name, (column, unit) in _tags(export_format).items():
        key = '"' + column.replace('"', '\\"') + '"'
        role, _, direction = name.partition(".")
        if unit == "1":
            lines.append(f'{key} = "{role}"')
        elif direction:
            lines.append(
                f'{key} = {{ role = "{role}", unit = "l/min", basis = "ANR", '
                f'direction = "{direction}" }}'
            )
        else:
            lines.append(f'{key} = {{ role = "{role}", unit = "{unit}" }}')
    return "\n".join(lines) + "\n"


def _write(folder: Path, captures: list[Recording], export_format: str) -> None:
    folder.mkdir()
    for k, capture in enumerate(captures):
        write_field_export(capture, folder / f"cap{k:02d}.csv", export_format, _tags(export_format))


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """14 reference, 4 held-out healthy and 4 leaky (CYL_B, 3 turns) captures as
    TIA Portal trace exports, and the field captures they were written from."""
    root = tmp_path_factory.mktemp("field-rig")
    plant = _plant(root)
    rng = np.random.default_rng(2_610_001)
    made: dict[str, list[Recording]] = {}
    truth = 0.0
    for folder, files, seed, leaks in (
        ("ref", 14, 2_610_010, None),
        ("free", 4, 2_610_020, None),
        ("leak", 4, 2_610_030, {"CYL_B": "3"}),
    ):
        caps = simulate_captures(
            plant, files, pre_trigger_s=PRE_TRIGGER_S, capture_s=CAPTURE_S + JITTER_S,
            seed=seed, leaks=leaks,
        )  # fmt: skip
        if leaks:
            (leak,) = caps[0].metadata["leaks"]
            nominal = float(psig_to_pa(load_machine(RIG).nominal_supply_psig))
            truth = float(kg_s_to_slpm(leak_mass_flow(nominal, leak["effective_area_m2"])))
        made[folder] = [field_capture(as_exported(c), rng) for c in caps]
        _write(root / folder, made[folder], "tia-trace")
    (root / "tags.toml").write_text(tag_map("tia-trace"))
    (root / "rig.toml").write_text(RIG.read_text())
    return {"root": root, "captures": made, "truth_slpm": truth}


def test_each_preset_imports_a_rig_capture_alike(
    rig: dict[str, object], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capture = rig["captures"]["ref"][0]  # type: ignore[index]
    q_in, q_out = capture.channel("Q_CYL_A.in")[1], capture.channel("Q_CYL_A.out")[1]
    for export_format in EXPORT_FORMATS:
        folder = tmp_path / export_format
        folder.mkdir()
        write_field_export(capture, folder / "cap.csv", export_format, _tags(export_format))
        (folder / "tags.toml").write_text(tag_map(export_format))
        out = folder / "cap.parquet"
        args = ["import", str(folder / "cap.csv"), "--map", str(folder / "tags.toml")]
        assert main([*args, "--out", str(out)]) == 0, capsys.readouterr().err
        rec = Recording.read(out)
        assert rec.channels == (
            "P_In",
            "Q_CYL_A",
            "X_CYL",
            "U_CYL_A",
            "U_CYL_B",
            "S_CYL_A",
            "S_CYL_B",
        )
        assert rec.start_time == capture.start_time
        assert {rec.rate(c) for c in rec.channels} == {1000.0}
        for name in ("U_CYL_A", "U_CYL_B", "S_CYL_A", "S_CYL_B"):  # bounce and all
            np.testing.assert_array_equal(rec.channel(name)[1], capture.channel(name)[1])
        # within the export's digits (6 significant for csv-de, the coarsest)
        np.testing.assert_allclose(rec.channel("P_In")[1], capture.channel("P_In")[1], rtol=1e-6)
        np.testing.assert_allclose(rec.channel("Q_CYL_A")[1], q_in - q_out, atol=1e-8)
        np.testing.assert_allclose(rec.channel("X_CYL")[1], capture.channel("X_CYL")[1], atol=1e-6)
    capsys.readouterr()


def test_the_rig_from_the_cli(rig: dict[str, object], capsys: pytest.CaptureFixture[str]) -> None:
    root: Path = rig["root"]  # type: ignore[assignment]
    tags, machine, ref = root / "tags.toml", root / "rig.toml", root / "rig.pnref"
    # import -> steps --machine -> machine draft
    imported = [root / f"c{k}.parquet" for k in range(3)]
    for k, out in enumerate(imported):
        src = root / "ref" / f"cap{k:02d}.csv"
        assert main(["import", str(src), "--map", str(tags), "--out", str(out)]) == 0
    assert main(["steps", str(imported[0]), "--machine", str(machine), "--json"]) == 0
    steps = json.loads(capsys.readouterr().out)
    (cycle,) = steps["cycles"]
    assert cycle["complete"]
    assert len(cycle["steps"]) == 2
    # the trigger after the pre-trigger, less the jitter, on the PLC's 10 ms grid
    start = cycle["steps"][0]["start_s"]
    assert PRE_TRIGGER_S - JITTER_S - 0.01 <= start <= PRE_TRIGGER_S + 0.01
    draft = root / "draft.toml"
    assert main(["machine", "draft", *map(str, imported), "--out", str(draft)]) == 0
    text = draft.read_text()
    assert 'do = [{ set = "U_CYL_A" }, { reset = "U_CYL_B" }]' in text
    assert 'do = [{ reset = "U_CYL_A" }, { set = "U_CYL_B" }]' in text
    # reference build from the folder of exports, read through the map
    args = ["reference", "build", str(root / "ref"), "--map", str(tags), "--machine", str(machine)]
    assert main([*args, "--out", str(ref)]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "14 leak-free cycles" in err
    assert "channels ['P_In', 'Q_CYL_A', 'X_CYL']" in err
    assert "14 of 14 recording(s) start at a cycle start" in err
    assert "P_In is quantised in steps of 1.9e+04 Pa" in err
    assert "(0 of 14 independent cycles in 14 recording(s) of 1 session(s); 95 % interval" in err
    assert "0.00-23.16 %" in err
    assert "come from 1 session(s)" in err  # one acquisition: between sessions unmeasured
    assert "needs at least 100 leak-free cycles in several recordings; this one has 14 in 14" in err
    assert "sensor set line-flows" in err
    # held-out healthy captures: none flagged, alone or pooled
    for capture in sorted((root / "free").glob("*.csv")):
        code = main(["diagnose", str(capture), "--map", str(tags), "--reference", str(ref)])
        assert code == 0, capsys.readouterr().out
    report = root / "free.json"
    pooled = ["--pool", "--map", str(tags), "--reference", str(ref), "--json", str(report)]
    assert main(["diagnose", str(root / "free"), *pooled]) == 0
    assert json.loads(report.read_text())["cycles_analyzed"] == 4
    # the leaky captures: flagged alone; pooled, located on CYL_B and sized
    one = root / "leak" / "cap00.csv"
    assert main(["diagnose", str(one), "--map", str(tags), "--reference", str(ref)]) == 1
    report = root / "leak.json"
    assert main(["diagnose", str(root / "leak"), *pooled[:-1], str(report)]) == 1
    result = json.loads(report.read_text())
    (leak,) = result["leaks"]
    assert leak["location"] == "CYL_B"
    assert leak["ambiguity_group"] == ["CYL_B"]
    assert leak["flow_slpm"] == pytest.approx(rig["truth_slpm"], rel=0.25)
    assert result["sensor_set"]["kind"] == "line-flows"
    capsys.readouterr()
