"""Issue 10 acceptance: chapter 4 identification on simulated data with unseen seeds.

Valve points from the Fig. 4.6 bench of ``tests/test_identification.py`` (three supply
pressures, a zero-flow drop, 1 % flow noise) for five valves, and the DNC strokes of the
festo-dsd twin at three supply pressures (sensor noise as recorded).

    python benchmarks/acceptance_identification.py [--seed S]
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
    seed = parser.parse_args().seed
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


if __name__ == "__main__":
    main()
