"""Issue 10 acceptance: chapter 4 identification on simulated data with unseen seeds.

Valve points from the Fig. 4.6 bench of ``tests/test_identification.py`` (three supply
pressures, a zero-flow drop, 1 % flow noise) for five valves, and the DNC strokes of the
festo-dsd twin at three supply pressures (sensor noise as recorded). Then, on plants
varied at scale 2 (sensor gains and zero errors included) from the built-in machines
with line sensors, what the calibration identifies from the machine's own cycle
(stop 25): each cylinder's friction from its strokes (Fsf, and the sliding friction
``Fcf + Cvf v`` at the strokes' speeds, which is what one production speed gives) and
each fill path's Cv (valve and tube in series) from its line flow, against the plant.

    python benchmarks/acceptance_identification.py [--seed S] [--plants N]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from pneufdd.identification import fit_breakaway_friction, fit_sliding_friction, fit_valve
from pneufdd.physics.friction import CVF_DNC, FCF_DNC, FSF_DNC
from test_identification import _dnc_strokes, _valve_points


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seed", type=int, default=96_300_000)
    parser.add_argument("--plants", type=int, default=3)
    args = parser.parse_args()
    seed = args.seed
    valves = [(0.3971, 1.0), (0.16, 0.9), (0.9, 0.5), (0.21, 0.2), (0.53, 0.7)]
    for k, (cv, xt) in enumerate(valves):
        p1, p2, flow, _ = _valve_points(cv, xt, seed=seed + k)
        fit = fit_valve(p1, p2, flow, zero_drop=(5e3, 0.01))
        print(
            f"valve Cv {cv} xT {xt}: Cv {fit.cv:.4f} ({100 * (fit.cv / cv - 1):+.2f} %), "
            f"xT {fit.xt:.3f} ({fit.xt - xt:+.3f}), nominal {fit.nominal_flow_l_min:.1f} l/min"
        )
    strokes, area_a, area_b = _dnc_strokes(seed + 10)
    sliding = fit_sliding_friction(strokes, area_a, area_b, 0.59)
    breakaway = fit_breakaway_friction(strokes, area_a, area_b, noise_m=1.2e-3)
    fcf, cvf = sliding.coulomb_friction_n, sliding.viscous_friction_n_s_m
    fsf = breakaway.static_friction_n
    print(
        f"DNC Fcf {fcf:.2f} N ({100 * (fcf / FCF_DNC - 1):+.2f} %), Cvf {cvf:.3f} N s/m "
        f"({100 * (cvf / CVF_DNC - 1):+.2f} %), Fsf {fsf:.2f} N "
        f"({100 * (fsf / FSF_DNC - 1):+.2f} %)"
    )
    for k in range(args.plants):
        for j, name in enumerate(("festo-dsd", "press-fit-cell")):
            _plant_identification(name, seed + 1000 * (k + 1) + 100 * j)


def _plant_identification(name: str, seed: int) -> None:
    from pneufdd.calibration.friction import actuator_strokes, identify_friction, stroke_speed
    from pneufdd.calibration.valve import identify_paths
    from pneufdd.sim import as_exported, load_machine, simulate, vary_machine
    from pneufdd.sim.compile import series_cv, tube_cv

    start = load_machine(name)
    plant = vary_machine(start, scale=2.0, seed=seed)
    recs = [as_exported(simulate(plant, cycles=3, seed=seed + j)) for j in (1, 2)]
    truth = {a.id: a for a in plant.actuators}
    for ident, f in identify_friction(start, recs).items():
        a = truth[ident]
        model = next(m for m in start.actuators if m.id == ident)
        speeds = sorted({round(stroke_speed(s), 2) for s in actuator_strokes(recs[0], model)})
        errors = [
            100
            * (
                (f.coulomb_friction_n + f.viscous_friction_n_s_m * v)
                / (a.coulomb_friction_n + a.viscous_friction_n_s_m * v)
                - 1
            )
            for v in (speeds[0], speeds[-1])
        ]
        print(
            f"{name} plant {seed} {ident}: Fsf {f.static_friction_n:.1f} N "
            f"({100 * (f.static_friction_n / a.static_friction_n - 1):+.1f} %), sliding "
            f"friction at {speeds[0]:.2f} / {speeds[-1]:.2f} m/s "
            f"{errors[0]:+.1f} / {errors[1]:+.1f} %"
        )
    for ident, p in identify_paths(start, recs).items():
        a = truth[ident]
        true_path = series_cv(a.valve.cv, tube_cv(a.tube_length_m, a.tube_inner_diameter_mm))
        print(
            f"{name} plant {seed} {ident}: fill path Cv {p.path_cv:.4f} "
            f"({100 * (p.path_cv / true_path - 1):+.1f} %, lines {'+'.join(p.lines)})"
        )


if __name__ == "__main__":
    main()
