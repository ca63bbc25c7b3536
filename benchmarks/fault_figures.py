"""Issue 34: the figures each fault and nuisance moves in the twin (``docs/faults.md``).

Not a benchmark (``run.py`` skips it). For each machine, a healthy run and one run per
fault kind at its two catalogue sizes (and per nuisance), same seed, so the runs share
every random draw (scan jitter, friction scatter). The house air is held constant (its
compressor band and drift set to 0): with them, any change of a stroke's timing moves
every later step against the compressor's cycle, and the table would mix that in
(about 3 ms and 0.005 SL in single steps, 20-40 ms per cycle). Compared over cycles 2
to N (the first is the start from rest), from the twin's true states (not the
sensors): per step its duration, the air it takes from the supply line (standard
litres, 0 degC / 1013 mbar) and the lowest supply (manifold) pressure; per cycle its
duration and air; the faulty actuator's mean chamber pressures and its strokes
(sustained travel to the end stop). Each row lists those and the three steps whose
duration or air moved most (``step k: +dt ms (+%), +air SL (+%)``; moves under 2 ms
and 0.005 SL are not listed).

    python benchmarks/fault_figures.py [--cycles 4] [--seed 34]
        [--machines festo-dsd,press-fit-cell]
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from typing import Any

import numpy as np

from pneufdd.physics.units import psig_to_pa
from pneufdd.sim import MachineStalledError, load_machine, parse_description, run_simulation
from pneufdd.sim.faults import FAULT_KINDS
from pneufdd.sim.nuisances import (
    Nuisances,
    PayloadChange,
    parse_header_dips,
    parse_temperature_profile,
)

SL_PER_KG = 1000.0 / 1.294  # standard litres (0 degC, 1013 mbar) per kg of air
MAX_CYCLE_S = 30.0  # a stopped machine is reported after 20 s + 30 s of simulated time

LOCATIONS = {
    "festo-dsd": {"actuator": "DNC", "line": "DNC_B", "switch": "S_DNC_B"},
    "press-fit-cell": {"actuator": "PRESS", "line": "PRESS_B", "switch": "S_PRESS_B"},
}
"""Where each fault sits: the machine's largest cylinder, its line B (exhausted while it
extends: throttle, cushion at the extended end), its extended-end switch."""


def _quiet(name: str) -> Any:
    """The built-in machine with its house air held at its mean (no compressor cycle or drift)."""
    desc = load_machine(name)
    supply = {**desc.raw["supply"], "compressor_band_psi": 0.0, "house_drift_psi": 0.0}
    return parse_description({**desc.raw, "supply": supply}, f"{name} (house air constant)")


def _sizes(kind: str, machine: Any) -> list[str]:
    """The two sizes of ``kind`` as written after ``KIND:``: the catalogue's, a pilot's
    1.0 and 0.4 bar below the machine's set point."""
    spec = FAULT_KINDS[kind]
    if not spec.unit:
        return [""]
    if kind == "valve-pilot":
        set_bar = (psig_to_pa(machine.supply.regulator_set_psig) - 101325.0) / 1e5
        return [f"{set_bar - 1.0:.2f}bar", f"{set_bar - 0.4:.2f}bar"]
    sign = "+" if spec.unit == "%" else ""
    return [f"{size:{sign}g}{spec.unit}" for size in spec.sizes]


def _cases(machine: Any, name: str) -> list[tuple[str, dict[str, Any]]]:
    loc = {**LOCATIONS[name], "supply": "supply"}
    cases: list[tuple[str, dict[str, Any]]] = []
    for kind, spec in FAULT_KINDS.items():
        for size in _sizes(kind, machine):
            text = f"{loc[spec.target]}={kind}" + (f":{size}" if size else "")
            cases.append((f"`{text}`", {"faults": [text]}))
    for c in (15, 35):
        ambient = Nuisances(ambient=parse_temperature_profile(f"{c}C"))
        cases.append((f"ambient {c} degC (described at 20)", {"nuisances": ambient}))
    for kg in (1.0, 3.0):
        payload = Nuisances(payloads=(PayloadChange(loc["actuator"], kg),))
        cases.append((f"payload {loc['actuator']} +{kg:g} kg", {"nuisances": payload}))
    dips = "depth=1bar,duration=2s,rate=120/h,seed=1"
    nuisance = Nuisances(header_dips=parse_header_dips(dips))
    cases.append((f"header dips {dips}", {"nuisances": nuisance}))
    return cases


def _figures(result: Any, first: int) -> dict[str, np.ndarray]:
    """Per step of cycles ``first``..N-1: duration [s], air [SL], lowest manifold pressure [Pa]."""
    starts = result.step_start
    t = result.time
    out = result.outputs
    edges = np.append(starts.reshape(-1), t[-1])
    n_cycles, n_steps = starts.shape
    dur = np.diff(edges).reshape(n_cycles, n_steps)[first:-1]
    k = np.minimum(np.searchsorted(t, edges), t.size - 1)
    air = (np.diff(out["mass_supplied"][k]) * SL_PER_KG).reshape(n_cycles, n_steps)[first:-1]
    lowest = [out["p_manifold"][a : max(b, a + 1)].min() for a, b in itertools.pairwise(k)]
    pmin = np.array(lowest).reshape(n_cycles, n_steps)[first:-1]
    return {"dur": dur.mean(axis=0), "air": air.mean(axis=0), "pmin": pmin.mean(axis=0)}


def _strokes(result: Any, actuator: str) -> tuple[float, float, float, float]:
    """Mean extend and retract stroke times [s] of ``actuator`` and mean pressures of its
    chambers A and B [Pa], over cycles 2 to N-1."""
    first, last = float(result.step_start[1, 0]), float(result.step_start[-1, 0])
    means = []
    for direction in (+1, -1):
        times = [
            s.duration for s in result.strokes_of(actuator, direction) if first <= s.start < last
        ]
        means.append(float(np.mean(times)) if times else math.nan)
    w = slice(*np.searchsorted(result.time, [first, last]))
    for side in "AB":
        means.append(float(result.outputs[f"p_{actuator}_{side}"][w].mean()))
    return means[0], means[1], means[2], means[3]


def _moved_steps(base: dict[str, np.ndarray], f: dict[str, np.ndarray]) -> str:
    dd = f["dur"] - base["dur"]
    da = f["air"] - base["air"]
    score = np.abs(dd) / np.maximum(base["dur"], 0.05) + np.abs(da) / np.maximum(base["air"], 0.05)
    parts = []
    for s in np.argsort(score)[::-1][:3]:
        if abs(dd[s]) < 2e-3 and abs(da[s]) < 5e-3:
            break
        parts.append(
            f"step {s + 1}: {dd[s] * 1e3:+.0f} ms ({dd[s] / base['dur'][s]:+.0%}), "
            f"{da[s]:+.3f} SL ({da[s] / max(base['air'][s], 1e-9):+.0%})"
        )
    return "; ".join(parts) or "none"


def _row(
    label: str,
    base: dict[str, np.ndarray],
    f: dict[str, np.ndarray],
    strokes: tuple[tuple[float, ...], tuple[float, ...]],
) -> str:
    cyc = f["dur"].sum() - base["dur"].sum()
    cyc_air = f["air"].sum() - base["air"].sum()
    dp = (f["pmin"].min() - base["pmin"].min()) / 1e5
    moves = " / ".join(
        "no stroke" if math.isnan(new) else f"{(new - old) * 1e3:+.0f} ms"
        for old, new in zip(strokes[0][:2], strokes[1][:2], strict=True)
    )
    chambers = " / ".join(
        f"{(new - old) / 1e5:+.3f}" for old, new in zip(strokes[0][2:], strokes[1][2:], strict=True)
    )
    return (
        f"| {label} | {cyc * 1e3:+.0f} ms ({cyc / base['dur'].sum():+.1%}) | "
        f"{cyc_air:+.2f} SL ({cyc_air / base['air'].sum():+.1%}) | {dp:+.3f} | {chambers} | "
        f"{moves} | {_moved_steps(base, f)} |"
    )


def _table(name: str, cycles: int, seed: int) -> None:
    machine = _quiet(name)
    act = LOCATIONS[name]["actuator"]
    # every run with the same max_cycle_s: it sets how many house-air draws a cycle takes
    healthy = run_simulation(machine, cycles=cycles + 1, seed=seed, max_cycle_s=MAX_CYCLE_S)
    base = _figures(healthy, 1)
    base_strokes = _strokes(healthy, act)
    print(f"\n### {name} (seed {seed}, cycles 2-{cycles + 1} of {cycles + 1})\n")
    print(
        f"Healthy: cycle {base['dur'].sum():.3f} s, {base['air'].sum():.2f} SL, lowest "
        f"supply {(base['pmin'].min() - 101325.0) / 1e5:.3f} bar(g); {act} extends in "
        f"{base_strokes[0] * 1e3:.0f} ms, retracts in {base_strokes[1] * 1e3:.0f} ms.\n"
    )
    print(
        f"| fault or nuisance | cycle time | cycle air | lowest supply [bar] | mean {act} A / B "
        f"[bar] | {act} extend / retract | steps that moved most |"
    )
    print("|---|---|---|---|---|---|---|")
    for label, extra in _cases(machine, name):
        try:
            result = run_simulation(
                machine, cycles=cycles + 1, seed=seed, max_cycle_s=MAX_CYCLE_S, **extra
            )
        except MachineStalledError as error:
            text = str(error).split(" longer than")[0].replace(f"machine {machine.name!r} ", "")
            print(f"| {label} | machine stops | | | | | {text.split(' (')[0]}, waiting |")
            continue
        print(_row(label, base, _figures(result, 1), (base_strokes, _strokes(result, act))))


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--cycles", type=int, default=4)
    parser.add_argument("--seed", type=int, default=34)
    parser.add_argument("--machines", default="festo-dsd,press-fit-cell")
    args = parser.parse_args()
    for name in args.machines.split(","):
        started = time.perf_counter()
        _table(name, args.cycles, args.seed)
        print(f"\n({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
