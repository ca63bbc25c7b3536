"""``make bench`` for a diagnosis that needs the check by simulation (issue 13).

Two large leaks on festo-dsd (5 turns on the supply, 3 on HGD2_A) against a
supply-only reference with the signatures of all 19 locations (four sizes each, one
plausible plant for the model error): the signature model misfits, so the diagnosis
sizes its best explanations with the digital twin (about 50 simulations).
The figure is diagnoses per second on two threads (the twin's kernel releases the GIL)
against one thread, measured in the same run; both must give the same diagnosis. The
wall time on two threads is printed against issue 13's target of at most 1 s.
"""

from __future__ import annotations

import json
from typing import Any

from common import BenchResult, best_time

SEED = 9_500_000  # this benchmark's seeds (below the development and campaign ranges)


def _case() -> tuple[Any, Any]:
    """A supply-only reference with every location's signatures, and the leaky run."""
    from pneufdd.diagnosis.recordings import build_reference_from_recordings, run_table
    from pneufdd.physics.units import slpm_to_kg_s
    from pneufdd.sim import simulate

    model = build_reference_from_recordings(
        [simulate("festo-dsd", cycles=14, seed=SEED + 1)],
        channels=("P_In", "Q_In"),
        signature_mass_flows=[slpm_to_kg_s(x) for x in (15.0, 50.0, 120.0, 230.0)],
        uncertainty_plants=1,
        workers=2,
    )
    run = simulate("festo-dsd", cycles=8, leaks={"supply": 5.0, "HGD2_A": 3.0}, seed=SEED + 2)
    return model, run_table(model, run)


def run() -> list[BenchResult]:
    from pneufdd.diagnosis.engine import diagnose

    model, table = _case()
    out: dict[int, str] = {}

    def on(threads: int) -> None:
        result = diagnose(model, table, threads=threads)
        if result.localisation is None or not result.localisation.checked_by_simulation:
            raise RuntimeError("the benchmark's run was not checked by simulation")
        out[threads] = json.dumps(result.to_dict(), sort_keys=True)

    on(1)  # warm-up: the reference's detector, numba's cache
    one = best_time(lambda: on(1), repeat=2)
    two = best_time(lambda: on(2), repeat=2)
    print(
        f"diagnosis checked by simulation: 1 thread {one:.2f} s, 2 threads {two:.2f} s "
        f"(target <= 1 s); same diagnosis: {out[1] == out[2]}",
        flush=True,
    )
    return [
        BenchResult(
            "diagnosis checked by simulation, 2 threads",
            1.0 / two,
            "runs/s",
            "1 thread",
            1.0 / one,
        )
    ]


if __name__ == "__main__":
    for r in run():
        print(r.line())
