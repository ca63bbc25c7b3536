"""Issue 35: the decay and friction physics against measured data (CC0), and its fixture.

Not a benchmark (``run.py`` skips it). Reads the closed-chamber pressure decays and the
O-ring friction runs of ``../shared/data/real/evazillen-3d-printed-actuator`` (or the
decimated copy in ``tests/data/real``), fits

* each decay curve with the orifice leak of eq. 4.3 in an isothermal and an adiabatic
  chamber (:func:`pneufdd.identification.decay.fit_pressure_decay`), over the whole
  curve and over its first bar of fall;
* the friction runs with the twin's friction (eq. 4.14, Coulomb force independent of
  pressure) and with a Coulomb force linear in pressure
  (:func:`pneufdd.identification.seal_friction.fit_seal_friction`), and the breakaway
  force at every start of motion (eq. 4.15),

prints the tables of ``docs/physics-validation.md`` and, with ``--figures DIR``, draws
its figures. ``--fixture DIR`` writes the decimated copy the tests use.

    python benchmarks/physics_validation.py [--data DIR] [--figures docs/figures]
        [--fixture tests/data/real]
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from pneufdd.identification.decay import decay_start, fit_pressure_decay
from pneufdd.identification.seal_friction import (
    SealFrictionRun,
    breakaway_forces,
    fit_seal_friction,
)
from pneufdd.physics.constants import P_ATM

SOURCE = Path(__file__).parents[1] / ".." / "shared" / "data" / "real"
SET = "evazillen-3d-printed-actuator"
FAST = ("Ultimaker_015", "Ultimaker_020")
"""The two chambers that empty within the recording (the others lose < 0.1 bar)."""
LEVELS = (1, 3, 5, 7)
FIXTURE_FRICTION_S = 12.0
"""Seconds of each friction file kept in the fixture (two of its ten runs)."""


def read_decays(data: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each curve: time [s], absolute pressure [Pa] (the source's bar are gauge)."""
    fixture = data / "chamber-decay.csv"
    out: dict[str, tuple[list[float], list[float]]] = {}
    if fixture.exists():
        with fixture.open() as fh:
            for row in csv.DictReader(line for line in fh if not line.startswith("#")):
                t, p = out.setdefault(row["chamber"], ([], []))
                t.append(float(row["time_s"]))
                p.append(float(row["pressure_bar_g"]))
    else:
        for path in sorted((data / SET / "chamber-decay").glob("*.csv")):
            t, p = out.setdefault(path.stem, ([], []))
            for line in path.read_text().splitlines():
                micro, _volt, bar = line.split(";")
                t.append(int(micro.replace(".", "")) * 1e-6)  # 1.003.000 us = 1.003 s
                p.append(float(bar))
    return {k: (np.array(t), np.array(p) * 1e5 + P_ATM) for k, (t, p) in out.items()}


def read_friction(data: Path) -> dict[int, SealFrictionRun]:
    """Each pressure level's runs: time [s], position [m], pressure [Pa abs], force [N]."""
    fixture = data / "friction.csv"
    columns: dict[int, list[list[float]]] = {}
    if fixture.exists():
        with fixture.open() as fh:
            for row in csv.DictReader(line for line in fh if not line.startswith("#")):
                columns.setdefault(int(row["level_bar"]), []).append(
                    [float(row[k]) for k in ("time_s", "position_mm", "pressure_bar_g", "force_n")]
                )
    else:
        for level in LEVELS:
            d = np.loadtxt(data / SET / "friction" / f"O-ring257_{level}bar.csv")
            columns[level] = np.c_[d[:, 0] / 1e3, d[:, 4], d[:, 5], d[:, 6]].tolist()
    runs = {}
    for level, rows in sorted(columns.items()):
        a = np.array(rows)
        runs[level] = SealFrictionRun(a[:, 0], a[:, 1] / 1e3, a[:, 2] * 1e5 + P_ATM, a[:, 3])
    return runs


def decay_table(decays: dict[str, tuple[np.ndarray, np.ndarray]]) -> list[dict[str, object]]:
    """One row per curve and thermal model: fitted Cd A / V and the residuals [bar]."""
    rows: list[dict[str, object]] = []
    for name, (t, p) in decays.items():
        k = decay_start(t, p)
        t, p = t[k:], p[k:]
        fall = np.nonzero(p < p[0] - 1e5)[0]
        first_bar = int(fall[0]) if fall.size else p.size
        for model in ("isothermal", "adiabatic"):
            whole = fit_pressure_decay(t, p, model=model)
            row: dict[str, object] = {
                "chamber": name,
                "model": model,
                "start_s": round(float(t[0]), 2),
                "from_bar_g": round((p[0] - P_ATM) / 1e5, 3),
                "to_bar_g": round((p[-1] - P_ATM) / 1e5, 3),
                "cda_per_v_1_m": whole.conductance_per_volume,
                "rms_bar": whole.residual_rms_pa / 1e5,
                "max_bar": whole.residual_max_pa / 1e5,
            }
            if name in FAST:
                head = fit_pressure_decay(t[: first_bar + 1], p[: first_bar + 1], model=model)
                row["first_bar_cda_per_v_1_m"] = head.conductance_per_volume
                row["first_bar_rms_bar"] = head.residual_rms_pa / 1e5
                row["first_bar_max_bar"] = head.residual_max_pa / 1e5
            rows.append(row)
    return rows


def friction_table(runs: dict[int, SealFrictionRun]) -> dict[str, object]:
    """Both friction forms over all levels, the sliding friction per level at 10 mm/s
    and the breakaway forces per level."""
    twin = fit_seal_friction(list(runs.values()), pressure_dependent=False)
    linear = fit_seal_friction(list(runs.values()), pressure_dependent=True)
    levels = []
    for level, run in runs.items():
        one = fit_seal_friction(
            [run], pressure_dependent=False, area_m2=linear.area_m2, offset_n=linear.offset_n
        )
        brk = breakaway_forces(run, linear.area_m2, linear.offset_n)
        pressure = float(np.median(run.pressure))
        levels.append(
            {
                "level_bar": level,
                "pressure_bar_g": (pressure - P_ATM) / 1e5,
                "sliding_at_10mm_s_n": one.coulomb_n + one.viscous_n_s_m * 0.01,
                "linear_model_at_10mm_s_n": linear.coulomb_at(pressure)
                + linear.viscous_n_s_m * 0.01,
                "twin_model_at_10mm_s_n": twin.coulomb_n + twin.viscous_n_s_m * 0.01,
                "breakaway_median_n": float(np.median(brk)),
                "breakaway_iqr_n": [float(x) for x in np.percentile(brk, [25, 75])],
                "starts": int(brk.size),
            }
        )
    return {"twin_form": twin.to_dict(), "linear_form": linear.to_dict(), "levels": levels}


def write_fixture(data: Path, out: Path) -> None:
    """The decimated copy for the tests (CC0, < 100 kB)."""
    out.mkdir(parents=True, exist_ok=True)
    decays = read_decays(data)
    with (out / "chamber-decay.csv").open("w", newline="") as fh:
        fh.write(f"# decimated from {SET}/chamber-decay (CC0 1.0, see README.md)\n")
        w = csv.writer(fh)
        w.writerow(["chamber", "time_s", "pressure_bar_g"])
        for name, (t, p) in decays.items():
            # every sample of a fast fall's first 15 s, every 5th after; a slow one's 20th
            begin = t[decay_start(t, p)]
            index = np.arange(t.size)
            if name in FAST:
                keep = (index % 5 == 0) | ((t >= begin) & (t <= begin + 15.0))
            else:
                keep = index % 20 == 0
            for ti, pi in zip(t[keep], p[keep], strict=True):
                w.writerow([name, f"{ti:.3f}", f"{(pi - P_ATM) / 1e5:.3f}"])
    runs = read_friction(data)
    with (out / "friction.csv").open("w", newline="") as fh:
        fh.write(f"# decimated from {SET}/friction/O-ring257_*bar.csv (CC0 1.0, see README.md)\n")
        w = csv.writer(fh)
        w.writerow(["level_bar", "time_s", "position_mm", "pressure_bar_g", "force_n"])
        for level, run in runs.items():
            keep = np.nonzero(run.time <= FIXTURE_FRICTION_S)[0][::3]
            for k in keep:
                w.writerow(
                    [level, f"{run.time[k]:.3f}", f"{run.position[k] * 1e3:.3f}",
                     f"{(run.pressure[k] - P_ATM) / 1e5:.3f}", f"{run.force[k]:.3f}"]
                )  # fmt: skip


def draw(decays: dict[str, tuple[np.ndarray, np.ndarray]], runs: dict[int, SealFrictionRun],
         friction: dict[str, object], out: Path) -> None:  # fmt: skip
    """The two figures of docs/physics-validation.md."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), dpi=90)
    for ax, name in zip(axes, FAST, strict=True):
        t, p = decays[name]
        k = decay_start(t, p)
        t, p = t[k:] - t[k], p[k:]
        ax.plot(t, (p - P_ATM) / 1e5, ".", ms=2, color="0.4", label="measured")
        for model, style in (("isothermal", "-"), ("adiabatic", "--")):
            fit = fit_pressure_decay(t, p, model=model)
            ax.plot(t, (fit.predict(t) - P_ATM) / 1e5, style, label=f"orifice, {model}")
        ax.set_title(f"{name}: closed chamber", fontsize=9)
        ax.set_xlabel("time from the start of the decay [s]")
        ax.set_ylabel("pressure [bar(g)]")
        ax.set_xlim(0, 60)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "physics-validation-decay.png")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 3.4), dpi=90)
    levels = friction["levels"]
    assert isinstance(levels, list)
    bar = [r["pressure_bar_g"] for r in levels]
    ax.plot(bar, [r["sliding_at_10mm_s_n"] for r in levels], "o", label="sliding, per level")
    ax.plot(bar, [r["breakaway_median_n"] for r in levels], "s", label="breakaway (median)")
    ax.plot(bar, [r["linear_model_at_10mm_s_n"] for r in levels], "-", label="Fcf linear in P")
    ax.plot(bar, [r["twin_model_at_10mm_s_n"] for r in levels], "--", label="twin: Fcf constant")
    ax.set_xlabel("chamber pressure [bar(g)]")
    ax.set_ylabel("friction at 10 mm/s [N]")
    ax.set_ylim(0, None)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "physics-validation-friction.png")
    plt.close(fig)
    del runs


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", type=Path, default=SOURCE)
    parser.add_argument("--figures", type=Path, default=None)
    parser.add_argument("--fixture", type=Path, default=None)
    args = parser.parse_args()
    decays = read_decays(args.data)
    runs = read_friction(args.data)
    for row in decay_table(decays):
        print(json.dumps(row), flush=True)
    friction = friction_table(runs)
    print(json.dumps(friction, indent=1))
    if args.figures is not None:
        draw(decays, runs, friction, args.figures)
    if args.fixture is not None:
        write_fixture(args.data, args.fixture)


if __name__ == "__main__":
    main()
