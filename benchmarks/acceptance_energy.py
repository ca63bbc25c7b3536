"""Issue 37 acceptance: the energy analysis of a calibrated twin, judged on the plant itself.

Not a benchmark (``run.py`` skips it). For each built-in machine and plant scale: a
plant drawn with ``vary_machine`` (the truth), two leak-free recordings of 8 cycles and
a run of 12 cycles with a 20 SLPM supply leak (all as a real export: no description),
then the user's commands::

    pneufdd machine calibrate MACHINE free1.parquet free2.parquet --out calibrated.toml
    pneufdd reference build free1.parquet free2.parquet --machine calibrated.toml \\
        --out ref.pnref [--uncertainty-plants 1 --signature-cycles 1]
    pneufdd energy run.parquet --reference ref.pnref --json energy.json --report energy.html

and judges the answers on the plant (the plant's own twin run, with its true leak and
its friction scatter, over ``JUDGE_CYCLES`` cycles):

* breakdown: the components' sum against the metered supply air (3 %), each actuator's
  air against the plant's own bookkeeping of the same run (10 %);
* set point (set on the plant until its ``P_In`` reads it, as a user would: the twin's
  pressures are the readings it was calibrated to): the plant at the set point found
  keeps every step within the tolerance
  + 1 % of the cycle time, saves air within 15 % of the prediction, and the plant's
  own lowest feasible set point (bisection on the plant) is within 0.2 bar;
* what-ifs: each measure's changes made on the plant: air saved within 15 % of the
  prediction, step-time changes within 10 ms; air off at standstill: the plant's
  standby flow within 15 %.

    python benchmarks/acceptance_energy.py OUT_DIR --seed 830000000 [--machines a,b]
        [--scales 1,2] [--quick]

Seeds: plant ``S + 1000 k + 100 scale`` (k: the machine's place in ``MACHINES``), its
recordings and runs following; the plant's judging runs use the plant seed + 5.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

MACHINES = ("festo-dsd", "press-fit-cell", "carton-sorter")
LEAK = {"supply": "20slpm"}
TOLERANCE = 0.02
MARGIN = 0.01  # acceptance: steps within the tolerance + 1 % of the cycle time
AIR_REL = 0.15
STEP_MS = 10.0
SET_POINT_BAR = 0.2
QUICK_REFERENCE = ["--uncertainty-plants", "1", "--signature-cycles", "1"]
JUDGE_CYCLES = 12
"""Cycles of every judging run on the plant (the first left out): the plant keeps its
friction scatter, and its mean step durations at low pressure need them. With 3 (2
measured) one step of press-fit-cell moved 30 ms from cycle to cycle, and the plant's
own lowest set point 4 psi from one seed to another (46.1 to 50.3 psig)."""


def _rel(predicted: float, actual: float) -> float:
    return abs(predicted - actual) / abs(actual) if actual else math.inf


def _breakdown(data: dict[str, Any], truth: Any, run_supply: float) -> dict[str, Any]:
    b = data["breakdown"]
    air = b["air_per_cycle_kg"]
    per = {}
    for actuator, value in b["by_actuator_kg"].items():
        if actuator.startswith(("leak.", "vacuum", "storage")):
            continue
        true = truth.actuator_kg(actuator)
        per[actuator] = {"reported_g": 1e3 * value, "plant_g": 1e3 * true, "rel": _rel(value, true)}
    leak = b["by_group_kg"].get("leak.supply", 0.0)
    return {
        "measured_g": 1e3 * air["measured"],
        "explained_g": 1e3 * air["explained"],
        "twin_g": 1e3 * air["twin"],
        "plant_true_supply_g": 1e3 * run_supply,
        "sum_rel": _rel(air["explained"], air["measured"]),
        "twin_rel": _rel(air["twin"], air["measured"]),
        "leak_reported_g": 1e3 * leak,
        "leak_plant_g": 1e3 * truth.per_cycle_kg.get("leak.supply", 0.0),
        "actuators": per,
        "worst_actuator_rel": max((v["rel"] for v in per.values()), default=0.0),
    }


def _through_gauge(plant: Any, psig: float) -> float:
    """The plant's true set point when its regulator is set until ``P_In`` reads ``psig``.

    The calibrated twin's set point is what the plant's supply pressure sensor reads
    (calibration fits the twin to the readings, zero error included), so the user sets
    the regulator by that reading: true = (reading - offset) / gain.
    """
    from pneufdd.physics.units import bar_gauge_to_pa, pa_to_bar_gauge, pa_to_psig, psig_to_pa

    sensor = next(s for s in plant.sensors if s.channel == "P_In")
    reading = float(pa_to_bar_gauge(psig_to_pa(psig)))
    return float(pa_to_psig(bar_gauge_to_pa((reading - sensor.offset) / sensor.gain)))


def _on_plant(plant: Any, changes: list[Any]) -> list[Any]:
    """``changes`` as made on the plant: set points through its ``P_In`` gauge."""
    from pneufdd.energy.changes import Change

    return [
        Change(c.kind, c.actuator, {"psig": _through_gauge(plant, c.values["psig"])})
        if c.kind == "set_point"
        else c
        for c in changes
    ]


def _judge_measure(measure: dict[str, Any], plant: Any, base: Any, leaks: Any, seed: int) -> dict:
    from pneufdd.energy.changes import Change, apply_changes
    from pneufdd.energy.standby import twin_standby
    from pneufdd.energy.twin import run_twin
    from pneufdd.energy.whatifs import BOOSTER_DRIVE_RATIO

    row: dict[str, Any] = {"name": measure["name"], "feasible": measure["feasible"]}
    if measure["kind"] == "air_off":
        predicted = measure["extra"]["standby_flow_kg_s"]
        actual = twin_standby(plant, leaks, seed).flow_kg_s
        row.update(standby_pred_slpm=predicted * 46367.0, standby_plant_slpm=actual * 46367.0)
        row["air_rel"] = _rel(predicted, actual)
        return row
    changes = [Change(c["kind"], c["actuator"], c["values"]) for c in measure["changes"]]
    if not changes:
        row["skipped"] = "no change"
        return row
    changed = run_twin(
        apply_changes(plant, _on_plant(plant, changes)),
        leaks,
        JUDGE_CYCLES,
        seed,
        3 * base.cycle_time_s,
    )
    if changed.air is None:
        row["plant_stalled"] = changed.stalled[:120]
        return row
    drive = 0.0
    if measure["kind"] == "booster":
        drive = BOOSTER_DRIVE_RATIO * changed.actuator_air(measure["remedy_for"])
    predicted = measure["air_per_cycle_kg"]["now"] - measure["air_per_cycle_kg"]["after"]
    actual = base.supply_kg - (changed.supply_kg + drive)
    step_pred = np.asarray(measure["step_duration_change_s"])
    step_true = changed.duration_s - base.duration_s
    row.update(
        saved_pred_g=1e3 * predicted,
        saved_plant_g=1e3 * actual,
        air_rel=_rel(predicted, actual),
        step_err_ms=float(1e3 * np.max(np.abs(step_pred - step_true))),
        cycle_pred_s=measure["cycle_time_s"]["after"] - measure["cycle_time_s"]["now"],
        cycle_plant_s=changed.cycle_time_s - base.cycle_time_s,
    )
    return row


def _one(machine: str, scale: float, seed: int, out: Path, quick: bool) -> dict[str, Any]:
    from pneufdd.cli.app import main
    from pneufdd.energy.bookkeeping import twin_air
    from pneufdd.energy.changes import Change, apply_changes, bar_g
    from pneufdd.energy.pressure import lowest_set_point
    from pneufdd.energy.settings import EnergySettings
    from pneufdd.energy.twin import run_twin
    from pneufdd.physics.leaks import SHARP_EDGE_CD
    from pneufdd.sim import as_exported, load_machine, run_simulation, simulate, vary_machine
    from pneufdd.sim.leaks import Leak
    from pneufdd.sim.variation import write_machine

    out.mkdir(parents=True, exist_ok=True)
    plant = vary_machine(load_machine(machine), scale=scale, seed=seed)
    write_machine(plant, out / "plant.toml", overwrite=True)
    free = []
    for k in (1, 2):
        path = out / f"free{k}.parquet"
        as_exported(simulate(plant, cycles=8, seed=seed + k)).write(path, overwrite=True)
        free.append(str(path))
    result = run_simulation(plant, cycles=12, leaks=LEAK, seed=seed + 3)
    run = out / "run.parquet"
    as_exported(result.recording).write(run, overwrite=True)
    calibrated, ref, energy = out / "calibrated.toml", out / "ref.pnref", out / "energy.json"
    timing = {}
    steps = [
        ("calibrate", ["machine", "calibrate", machine, *free, "--out", str(calibrated),
                       "--overwrite"]),
        ("reference", ["reference", "build", *free, "--machine", str(calibrated), "--out",
                       str(ref), "--overwrite",
                       *QUICK_REFERENCE * quick]),
        ("energy", ["energy", str(run), "--reference", str(ref), "--json", str(energy),
                    "--report", str(out / "energy.html"), "--overwrite"]),
    ]  # fmt: skip
    for name, args in steps:
        began = time.perf_counter()
        code = main(args)
        timing[name] = round(time.perf_counter() - began, 1)
        if code != 0:
            return {"machine": machine, "scale": scale, "failed": name, "exit": code}
    data = json.loads(energy.read_text())
    truth = twin_air(result)
    supply = float(truth.supply_kg.sum())
    row: dict[str, Any] = {"machine": machine, "scale": scale, "plant_seed": seed, "s": timing}
    row["breakdown"] = _breakdown(data, truth, supply)
    # the set point, on the plant with its true leak
    # the plant's true leaks as the holes they are (an SLPM size would mean another hole
    # at another set point)
    leaks = [
        Leak(spec.location, 1e3 * math.sqrt(4.0 * spec.area_m2 / (math.pi * SHARP_EDGE_CD)), "mm")
        for spec in result.leaks
    ]
    judge_seed = seed + 5
    base = run_twin(plant, leaks, JUDGE_CYCLES, judge_seed)
    found_psig = next(m for m in data["measures"] if m["kind"] == "set_point")["changes"][0]
    psig = found_psig["values"]["psig"]
    true_psig = _through_gauge(plant, psig)
    at = run_twin(
        apply_changes(plant, [Change("set_point", "", {"psig": true_psig})]),
        leaks,
        JUDGE_CYCLES,
        judge_seed,
    )
    settings = EnergySettings(seed=judge_seed, cycles=JUDGE_CYCLES)
    own = lowest_set_point(plant, leaks, settings, base=base)
    sp = next(m for m in data["measures"] if m["kind"] == "set_point")
    predicted = sp["air_per_cycle_kg"]["now"] - sp["air_per_cycle_kg"]["after"]
    actual = base.supply_kg - at.supply_kg
    worst = float(np.max(at.duration_s - base.duration_s)) if at.air is not None else math.inf
    row["set_point"] = {
        "found_bar_g": bar_g(psig),
        "found_on_plant_bar_g": bar_g(true_psig),
        "plant_now_bar_g": bar_g(plant.supply.regulator_set_psig),
        "plant_min_bar_g": bar_g(own.min_psig),
        "diff_bar": bar_g(true_psig) - bar_g(own.min_psig),
        "diff_bar_as_read": bar_g(psig) - bar_g(own.min_psig),
        "limiting_twin": data["limiting_actuator"],
        "limiting_plant": own.limiting_actuator,
        "worst_step_slower_ms": 1e3 * worst,
        "allowed_ms": 1e3 * (TOLERANCE + MARGIN) * base.cycle_time_s,
        "saved_pred_g": 1e3 * predicted,
        "saved_plant_g": 1e3 * actual,
        "air_rel": _rel(predicted, actual),
        "cycle_plant_s": [base.cycle_time_s, at.cycle_time_s],
    }
    row["measures"] = [
        _judge_measure(m, plant, base, leaks, judge_seed)
        for m in data["measures"]
        if m["kind"] != "set_point"
    ]
    return row


def _verdicts(row: dict[str, Any]) -> dict[str, Any]:
    b, s = row["breakdown"], row["set_point"]
    measures = [m for m in row["measures"] if "air_rel" in m]
    return {
        "machine": row["machine"],
        "scale": row["scale"],
        "sum_within_3pct": b["sum_rel"] <= 0.03,
        "actuators_within_10pct": b["worst_actuator_rel"] <= 0.10,
        "steps_within_tolerance": s["worst_step_slower_ms"] <= s["allowed_ms"],
        "saving_within_15pct": s["air_rel"] <= AIR_REL,
        "set_point_within_0.2bar": abs(s["diff_bar"]) <= SET_POINT_BAR,
        "measures_air_within_15pct": f"{sum(m['air_rel'] <= AIR_REL for m in measures)} of "
        f"{len(measures)}",
        "measures_steps_within_10ms": f"{sum(m.get('step_err_ms', 0) <= STEP_MS for m in measures)}"
        f" of {len(measures)}",
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--seed", type=int, default=830_000_000)
    parser.add_argument("--machines", default=",".join(MACHINES))
    parser.add_argument("--scales", default="1,2")
    parser.add_argument("--quick", action="store_true", help="reference: 1 plausible plant")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "rows.jsonl", "a", encoding="utf-8") as log:
        for machine in args.machines.split(","):
            for scale in (float(s) for s in args.scales.split(",")):
                seed = args.seed + 1000 * MACHINES.index(machine) + 100 * int(scale)
                row = _one(machine, scale, seed, args.out / f"{machine}-{scale:g}", args.quick)
                log.write(json.dumps(row) + "\n")
                log.flush()
                print(json.dumps(row), flush=True)
                if "failed" not in row:
                    print(json.dumps(_verdicts(row)), flush=True)


if __name__ == "__main__":
    main()
