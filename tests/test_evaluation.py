"""Campaigns on plants that differ from their twin, and their scoring."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from pneufdd.cli.app import main
from pneufdd.diagnosis.reference.file import load_reference
from pneufdd.errors import InputError
from pneufdd.evaluation import CampaignDesign, RunOutcome, Tally, rescore, run_campaign
from pneufdd.evaluation.scoring import ReportedLeak


def _leak(location, group, flows, confidence):
    return ReportedLeak(location, tuple(group), tuple(flows), confidence)


def test_tally_counts_what_the_issue_asks():
    t = Tally()
    # a single leak found in a group of two, 10 % too large
    t.add(
        RunOutcome(
            "single",
            {"X_A": 1e-3},
            True,
            10,
            10,
            (_leak("X_B", ["X_B", "X_A"], [1.2e-3, 1.1e-3], 0.95),),
            (),
            0.1,
            False,
        )
    )
    # a single leak with a spurious second one
    t.add(
        RunOutcome(
            "single",
            {"Y_B": 2e-3},
            True,
            10,
            9,
            (_leak("Y_B", ["Y_B"], [1.5e-3], 0.92), _leak("supply", ["supply"], [1e-4], 0.91)),
            (),
            0.3,
            True,
        )
    )
    # a missed single leak
    t.add(RunOutcome("single", {"Z_A": 1e-4}, False, 10, 1, (), (), 0.05, False))
    t.add(RunOutcome("free", {}, True, 10, 2, (), (), 0.02, False))
    t.add(RunOutcome("free", {}, False, 10, 0, (), (), 0.02, False))
    t.add(
        RunOutcome(
            "pair",
            {"X_A": 1e-3, "supply": 1e-3},
            True,
            10,
            10,
            (_leak("X_A", ["X_A"], [1e-3], 0.99),),
            (("X_A", "supply"),),
            0.5,
            False,
        )
    )
    # both lines of one actuator, read as a supply leak (listed as the alternative)
    t.add(
        RunOutcome(
            "pair",
            {"X_A": 1e-3, "X_B": 2e-3},
            True,
            10,
            10,
            (_leak("supply", ["supply"], [2e-3], 0.97),),
            (("X_A", "X_B"),),
            0.5,
            False,
        )
    )
    f = t.figures()
    assert f["detected"] == pytest.approx(2 / 3)
    assert f["in_group"] == pytest.approx(2 / 3)
    assert f["mean_group"] == pytest.approx(1.5)
    assert f["size_error_median"] == pytest.approx(0.175)  # 10 % and 25 %
    assert f["spurious_second_leak"] == pytest.approx(1 / 3)
    assert f["leak_free_flagged"] == pytest.approx(0.5)
    assert f["cycle_free_flagged"] == pytest.approx(0.1)
    assert f["pairs_both"] == 0.0
    assert f["pairs_both_or_alternative"] == 1.0  # one alternative holds both
    assert f["pair_runs_one_actuator"] == 1  # X_A + X_B; X_A + supply is not
    assert f["pairs_one_actuator_both"] == 0.0
    assert "pairs on both lines of one actuator, both found: 0.00 % (0/1)" in "\n".join(t.lines())
    # reliability: 5 reported leaks, the spurious supply one and the pair's are false
    assert f["confident_true"] == pytest.approx(3 / 5)
    rows = {round(low, 2): (n, share) for low, _, n, share, _ in t.reliability()}
    assert rows[0.9] == (2, 0.5)  # 0.92 true, 0.91 false
    assert rows[0.95] == (3, 2 / 3)  # 0.95, 0.99 true; 0.97 false
    checks = t.checks({"in_group": 0.98, "size_error_p90": 0.25})
    assert checks == {"in_group >= 0.98": False, "size_error_p90 <= 0.25": True}


def test_design_is_validated():
    with pytest.raises(InputError, match="sensor sets"):
        CampaignDesign(machines=("festo-dsd",), sensor_sets=("everything",))
    with pytest.raises(InputError, match="leak size"):
        CampaignDesign(machines=("festo-dsd",), leak_sizes=("big",))
    with pytest.raises(InputError, match="plant scales"):
        CampaignDesign(machines=("festo-dsd",), plant_scales=(7.0,))


TINY = CampaignDesign(
    machines=("press-fit-cell",),
    plants=1,
    leak_sizes=("60slpm",),
    leak_free_runs=2,
    pairs=1,
    run_cycles=4,
    reference_cycles=14,
    reference_recordings=2,
    uncertainty_plants=1,
    seed_offset=9_000_000,  # a test's seeds (below the development and campaign ranges)
    leaks_per_run=(3,),
    multi_leak_runs=1,
)


def test_a_tiny_campaign_judges_a_plant(tmp_path):
    seen = []
    result = run_campaign(TINY, tmp_path / "c", workers=1, progress=lambda *a: seen.append(a))
    runs = [json.loads(x) for x in (tmp_path / "c" / "runs.jsonl").read_text().splitlines()]
    manifest = json.loads((tmp_path / "c" / "manifest.json").read_text())
    (plant,) = manifest["machines"][0]["plants"]
    assert plant["plant_seed"] == 9_000_000
    # 9 locations, 2 leak-free runs, 1 pair, 1 run with 3 leaks
    assert len(plant["runs"]) == 9 + 2 + 1 + 1
    assert len({r["seed"] for r in plant["runs"]}) == 13  # every run its own seed
    (multi,) = [r for r in plant["runs"] if r["kind"] == "multi"]
    assert len(multi["leaks"]) == 3
    assert set(multi["leaks"].values()) == {"60slpm"}
    assert {r["sensors"] for r in runs if not r.get("stalled")} == {"full", "supply-only"}
    # the plant differs from its twin but keeps the machine's name
    assert "press-fit-cell" in (tmp_path / "c" / "plants" / "press-fit-cell-s1-p1.toml").read_text()
    tally = result.tallies[("press-fit-cell", 1.0, "full")]
    assert tally.leak_runs == 9
    assert tally.detected == 9
    assert tally.inside >= 8
    assert seen[-1] == ("diagnosing campaign runs", 13, 13)
    assert tally.multi[3].runs == 1  # the 3-leak run is scored on its own
    record = next(r for r in runs if r["kind"] == "multi" and r["sensors"] == "full")
    assert {"total_flow", "total_flow_interval", "more_leaks", "hidden"} <= set(record)
    again = rescore(tmp_path / "c")
    assert again.tallies[("press-fit-cell", 1.0, "full")].figures() == tally.figures()
    assert again.tallies[("press-fit-cell", 1.0, "full")].multi_figures() == tally.multi_figures()
    with pytest.raises(InputError, match="holds a campaign"):
        run_campaign(TINY, tmp_path / "c", workers=1)


def test_a_calibrated_campaign_takes_each_plants_signatures_from_its_calibrated_twin(tmp_path):
    design = dataclasses.replace(
        TINY, sensor_sets=("supply-only",), plant_scales=(2.0,), pairs=0, leak_free_runs=1
    )
    design = dataclasses.replace(design, calibrate=True)
    result = run_campaign(design, tmp_path / "c", workers=1)
    manifest = json.loads((tmp_path / "c" / "manifest.json").read_text())
    (plant,) = manifest["machines"][0]["plants"]
    calibration = plant["calibration"]
    # the twin was brought to the plant: per-step supply air within issue 10's 5 %
    # and its weighted misfit (what the fit minimises) at most half of before; step
    # durations better (medians over steps). The air's median alone is no measure of
    # the fit: on this plant the unvaried description starts at 2.34 % with two steps
    # at 7.6 and 9.3 %; after, every step is within 4.2 % and the median is 2.82 %.
    fit = calibration["fit"]
    assert fit["air_error_pct_median_after"] <= 5.0
    misfit = calibration["weighted_misfit"]
    assert misfit["air_after"] <= 0.5 * misfit["air_before"]
    assert fit["duration_error_ms_median_after"] < fit["duration_error_ms_median_before"]
    text = Path(calibration["file"]).read_text()
    assert "calibrated to 2 leak-free recordings of the plant" in text
    reference = load_reference(plant["references"]["supply-only"])
    assert "calibrated" in reference.description.title
    tally = result.tallies[("press-fit-cell", 2.0, "supply-only")]
    assert tally.leak_runs == 9
    assert tally.detected == 9


def test_campaign_command(tmp_path, capsys):
    code = main(
        [
            "campaign", "--machine", "carton-sorter", "--plants", "1", "--sizes", "80slpm",
            "--leak-free-runs", "1", "--pairs", "0", "--run-cycles", "3",
            "--reference-cycles", "12", "--reference-recordings", "2",
            "--uncertainty-plants", "1", "--workers", "2",
            "--seed-offset", "9100000", "--out", str(tmp_path / "c"),
        ]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    assert "=== carton-sorter, plant scale 1, sensor set supply-only ===" in out
    assert "reliability" in out
    assert "full" not in out.split("sensor set")[1].split("\n")[0]  # supply sensors only


def test_a_run_whose_leaks_leave_no_complete_cycle_is_not_judged(tmp_path):
    # Found by an acceptance campaign (which then stopped with an error): on this
    # festo-dsd plant, 5-turn leaks on HMPL_V_B and DGPL_A keep the vacuum switch
    # S_VAC from falling in step 8, so the PLC sequence never completes a cycle.
    from pneufdd.diagnosis.recordings import build_reference_from_recordings
    from pneufdd.diagnosis.reference.file import save_reference
    from pneufdd.evaluation.campaign import Job, run_job
    from pneufdd.sim import load_machine, simulate
    from pneufdd.sim.variation import machine_to_toml, vary_machine

    plant = vary_machine(load_machine("festo-dsd"), 1.0, 240_020_000)
    plant_file = tmp_path / "plant.toml"
    plant_file.write_text(machine_to_toml(plant))
    free = [simulate(plant, cycles=7, seed=5 + i) for i in range(2)]
    reference = build_reference_from_recordings(free, [], with_signatures=False)
    ref_file = save_reference(reference, tmp_path / "digital.pnref")
    leaks = {"HMPL_V_B": "5", "DGPL_A": "5"}
    job = Job(
        "festo-dsd",
        1.0,
        3,
        "pair",
        leaks,
        240_020_284,
        str(plant_file),
        {"digital-only": str(ref_file)},
        6.0e5,
        10,
    )
    (record,) = run_job(job)
    assert record["stalled"] is True
    assert record["leaks"] == leaks
    assert "S_VAC did not fall" in record["reason"]


def test_a_campaign_on_triggered_captures_with_the_sensor_sets_without_a_supply_meter(
    tmp_path, capsys
):
    code = main(
        [
            "campaign", "--machine", "press-fit-cell", "--plants", "1", "--sizes", "80slpm",
            "--leak-free-runs", "1", "--pairs", "0", "--reference-recordings", "2",
            "--sensor-sets", "line-flows,pressure-only,P_In+X_PRESS",
            "--capture", "triggered", "--captures-per-reference", "10",
            "--captures-per-run", "3", "--pre-trigger-s", "0.2",
            "--uncertainty-plants", "1", "--workers", "1",
            "--seed-offset", "9300000", "--out", str(tmp_path / "c"),
        ]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    manifest = json.loads((tmp_path / "c" / "manifest.json").read_text())
    assert manifest["design"]["capture"] == {
        "captures_per_reference": 10,
        "captures_per_run": 3,
        "cycles_per_file": 1,
        "pre_trigger_s": 0.2,
    }
    (plant,) = manifest["machines"][0]["plants"]
    line = load_reference(plant["references"]["line-flows"])
    assert "Q_In" not in line.channels
    assert "Q_PRESS_A" in line.channels
    assert load_reference(plant["references"]["pressure-only"]).channels == ("P_In",)
    assert load_reference(plant["references"]["P_In+X_PRESS"]).channels == ("P_In", "X_PRESS")
    # 10 one-cycle captures, each a recording of its own, none left out as start-up
    assert line.n_cycles == 10
    assert len(set(line.sources)) == 10
    runs = [json.loads(x) for x in (tmp_path / "c" / "runs.jsonl").read_text().splitlines()]
    judged = [r for r in runs if not r.get("stalled")]
    assert {r["sensors"] for r in judged} == {"line-flows", "pressure-only", "P_In+X_PRESS"}
    assert {r["cycles"] for r in judged} == {3}  # three captures pooled per run
    assert "sensor set line-flows ===" in out


def test_evaluate_refuses_a_campaign_of_captures(tmp_path):
    from pneufdd.evaluation.labelled import read_manifest

    design = {"capture": {"captures_per_reference": 20}, "reps": 1}
    (tmp_path / "manifest.json").write_text(json.dumps({"design": design, "machines": []}))
    with pytest.raises(InputError, match="triggered captures"):
        read_manifest(tmp_path)


def test_many_leak_designs_keep_the_other_runs_seeds():
    from pneufdd.evaluation.campaign import _plan_runs
    from pneufdd.sim import load_machine

    machine = load_machine("press-fit-cell")
    plain = _plan_runs(TINY_PLAIN, machine, 0, 0, 0)
    many = _plan_runs(dataclasses.replace(TINY_PLAIN, leaks_per_run=(3, 4, 6)), machine, 0, 0, 0)
    assert many[: len(plain)] == plain  # the single leaks, leak-free runs and pairs
    extra = many[len(plain) :]
    assert [len(leaks) for _, leaks, _ in extra] == [3, 4, 6]
    assert all(kind == "multi" for kind, _, _ in extra)
    seeds = [seed for _, _, seed in many]
    assert len(set(seeds)) == len(seeds)
    again = _plan_runs(dataclasses.replace(TINY_PLAIN, leaks_per_run=(3, 4, 6)), machine, 0, 0, 0)
    assert again == many  # drawn from the plant's own seed
    with pytest.raises(InputError, match="leak locations"):
        _plan_runs(dataclasses.replace(TINY_PLAIN, leaks_per_run=(10,)), machine, 0, 0, 0)
    with pytest.raises(InputError, match="leaks per run"):
        dataclasses.replace(TINY_PLAIN, leaks_per_run=(2,))


TINY_PLAIN = dataclasses.replace(TINY, leaks_per_run=())


def test_many_leak_runs_are_scored_against_the_remainder_they_state():
    from pneufdd.evaluation.scoring import MultiTally

    truth = {"X_A": 1e-3, "Y_B": 2e-3, "supply": 5e-4}
    tally = MultiTally()
    # all three found, the total 10 % low, its interval holding the truth
    tally.add(
        RunOutcome(
            "multi",
            truth,
            True,
            10,
            10,
            (
                _leak("X_A", ["X_A"], [1e-3], 0.9),
                _leak("Y_B", ["Y_B", "Y_A"], [1.8e-3], 0.9),
                _leak("supply", ["supply"], [3.5e-4], 0.8),
            ),
            (),
            2.0,
            True,
            total_flow=3.15e-3,
            total_interval=(3.0e-3, 3.6e-3),
        )
    )
    # the supply leak missed, but within the bound stated there
    tally.add(
        RunOutcome(
            "multi",
            truth,
            True,
            10,
            10,
            (_leak("X_A", ["X_A"], [1e-3], 0.9), _leak("Y_B", ["Y_B"], [2e-3], 0.9)),
            (),
            3.0,
            True,
            total_flow=3.0e-3,
            total_interval=(2.9e-3, 3.1e-3),
            more_leaks=False,
            hidden={"supply": 6e-4},
        )
    )
    # a missed leak beyond its bound, no remainder stated: not covered
    tally.add(
        RunOutcome(
            "multi",
            truth,
            True,
            10,
            10,
            (_leak("X_A", ["X_A"], [1e-3], 0.9), _leak("Q_B", ["Q_B"], [2e-3], 0.9)),
            (),
            4.0,
            True,
            total_flow=3.0e-3,
            total_interval=(2.9e-3, 3.1e-3),
            hidden={"supply": 1e-4, "Y_B": 1e-3},
        )
    )
    f = tally.figures()
    assert f["all_in_group"] == pytest.approx(1 / 3)
    assert f["leaks_found"] == pytest.approx(6 / 9)
    assert f["total_flow_error_median"] == pytest.approx(1.0 - 3.0 / 3.5, rel=1e-9)
    assert f["total_interval_covers"] == pytest.approx(1 / 3)
    assert f["runs_missing_a_leak"] == 2
    assert f["remainder_stated"] == pytest.approx(1 / 2)
    assert f["missed_within_bound"] == pytest.approx(1 / 3)
    assert f["spurious_per_run"] == pytest.approx(1 / 3)
    lines = "\n".join(tally.lines(3, {"all_in_group": 0.85, "remainder_stated": 1.0}))
    assert "all_in_group >= 0.85: FAIL" in lines
    assert "remainder_stated >= 1: FAIL" in lines


@pytest.mark.parametrize("value", ["-nan", "inf", "11", "-0.5"])
def test_a_capture_option_is_checked_without_triggered_captures(tmp_path, capsys, value):
    # found by make fuzz (seed 97,000,310): a continuous campaign ignored the value, so
    # --pre-trigger-s -nan ran to exit 0 instead of naming the option
    out = tmp_path / "c"
    args = ["campaign", "--machine", "press-fit-cell", "--pre-trigger-s", value]
    code = main([*args, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert "--pre-trigger-s" in err
    assert "0 to 10 s" in err
    assert not out.exists()
