"""The compiled integrator against scipy's BDF on the same equations (oracle test)."""

from __future__ import annotations

import tomllib
from importlib import resources

import numpy as np
import pytest

from pneufdd.sim import parse_description, run_simulation
from pneufdd.sim.compile import compile_plant, initial_state
from pneufdd.sim.rhs import plant_derivatives, solve_segment


def _segment() -> object:
    raw = tomllib.loads(
        (resources.files("pneufdd.sim") / "machines" / "festo-dsd.toml").read_text("utf-8")
    )
    raw["machine"].update(friction_scatter=0.0, scan_time_s=0.0)
    raw["supply"].update(house_drift_psi=0.0, compressor_band_psi=0.0)
    raw["actuator"][0]["initial"] = "retracted"
    raw["step"] = [{"do": [{"set": "U_DNC_A", "until": "S_DNC_B"}], "dwell_s": 0.1}]
    return parse_description(raw, "segment")


def _extension_start(desc: object, plant: object) -> tuple[np.ndarray, np.ndarray]:
    """Valve connections of the DNC extension (its valve to A, the others as at rest)
    and the initial state vector of :func:`plant_derivatives`."""
    st = initial_state(desc, plant)  # type: ignore[arg-type]
    na = len(st["x"])
    conn = np.zeros(2 * na, dtype=np.int64)
    for i in range(na):
        spool = 1 if i == 0 else int(st["spool"][i])
        conn[2 * i : 2 * i + 2] = (1, 2) if spool == 1 else ((2, 1) if spool == -1 else (0, 0))
    return conn, np.concatenate([st["m"], st["temp"], st["x"], st["v"]])


def test_dnc_extension_matches_bdf() -> None:
    desc = _segment()
    res = run_simulation(desc, cycles=1, seed=0)
    t_compiled = res.strokes_of("DNC", +1)[0].end - 0.020  # valve on-delay
    plant = compile_plant(desc, [])  # type: ignore[arg-type]
    conn, y0 = _extension_start(desc, plant)
    na = plant.ap.shape[0]
    # at rest and in equilibrium, nothing but the DNC changes
    dy = plant_derivatives(y0, plant.sp, plant.ap, plant.cp, conn, plant.sp[5], np.ones(na))
    nn = 2 + 2 * na
    assert np.all(np.abs(dy[nn + 4 : 2 * nn]) < 1e-6)
    assert dy[2] > 0.0  # chamber A of the DNC fills
    sol = solve_segment(plant, y0, conn, 0, 1.0, method="BDF", rtol=1e-5)
    assert sol.t_end == pytest.approx(t_compiled, rel=0.02)


def test_dnc_extension_with_internal_faults_and_a_cushion_matches_bdf() -> None:
    # issue 34: the kernel's coupled solution of chambers A and B across a leaking
    # piston seal, the spool leaks beside the valve paths and the cushion's throttled
    # exhaust, against scipy's BDF on the same equations (plant_derivatives)
    from pneufdd.sim.conditions import RunConditions
    from pneufdd.sim.faults import FaultSchedule

    desc = _segment()
    faults = [
        "DNC=piston-leak:10slpm",
        "DNC_B=valve-leak-in:5slpm",
        "DNC_A=valve-leak-out:10slpm",
        "DNC_B=cushion:0.03cv",
    ]
    res = run_simulation(desc, cycles=1, seed=0, faults=faults)
    healthy = run_simulation(desc, cycles=1, seed=0)
    t_compiled = res.strokes_of("DNC", +1)[0].end - 0.020  # valve on-delay
    t_healthy = healthy.strokes_of("DNC", +1)[0].end - 0.020
    plant = compile_plant(desc, [])  # type: ignore[arg-type]
    RunConditions(desc, plant, FaultSchedule(faults), None, 0).apply(0, 0.0, None)  # type: ignore[arg-type]
    conn, y0 = _extension_start(desc, plant)
    sol = solve_segment(plant, y0, conn, 0, 2.0, method="BDF", rtol=1e-5)
    assert t_compiled > 1.2 * t_healthy  # the faults matter
    assert sol.t_end == pytest.approx(t_compiled, rel=0.01)  # measured: 0.3 %
