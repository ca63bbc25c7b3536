"""Why combined extend + retract leaks miss eq. 5.23's vector sum (docs/classifiers.md).

    python benchmarks/vector_sum_analysis.py [--scale S] [--seed N] [--machine FILE]

Simulates festo-dsd's DNC (or the same actuator of ``--machine``) leak-free, with
single A-line and B-line leaks of 2, 4 and 6 turns and all 9 pairs, 10 cycles per run
(the 8 inner cycles judged), and prints for every pair the distance of the combined
leak from the vector sum of the single leaks, relative to the sum (eq. 5.23), for two
windows of the line air:

* the stroke's step (Fig. 5.18: ``air_extend_SL``, ``air_retract_SL``);
* the whole cycle (positive flow of ``Q_DNC_A`` and ``Q_DNC_B``);

and the mean stroke times, which show why: a line is fed only during its own
stroke, and the other line's leak changes that time. Not part of ``make bench``.
"""

from __future__ import annotations

import argparse

import numpy as np
import numpy.typing as npt

SIZES = ("2", "4", "6")
SL_PER_KG = 1.0 / 1.294e-3  # standard litres per kg (0 degC, 1013 mbar)


def _runs() -> list[tuple[str, dict[str, str]]]:
    runs: list[tuple[str, dict[str, str]]] = [("none", {}), ("none", {})]
    for s in SIZES:
        runs += [(f"A{s}", {"DNC_A": s}), (f"B{s}", {"DNC_B": s})]
    for s in SIZES:
        for t in SIZES:
            runs.append((f"A{s}+B{t}", {"DNC_A": s, "DNC_B": t}))
    return runs


def _cycle_air(rec: object, starts: npt.NDArray[np.float64], cycles: range) -> list[list[float]]:
    rows = []
    for i in cycles:
        row = []
        for channel in ("Q_DNC_A", "Q_DNC_B"):
            t, q = rec.channel(channel)  # type: ignore[attr-defined]
            inside = (t >= starts[i]) & (t < starts[i + 1])
            row.append(float(np.trapezoid(np.clip(q[inside], 0.0, None), t[inside])) * SL_PER_KG)
        rows.append(row)
    return rows


def _errors(means: dict[str, npt.NDArray[np.float64]]) -> dict[str, float]:
    origin = means["none"]
    out = {}
    for s in SIZES:
        for t in SIZES:
            total = (means[f"A{s}"] - origin) + (means[f"B{t}"] - origin)
            miss = (means[f"A{s}+B{t}"] - origin) - total
            out[f"A{s}+B{t}"] = float(np.linalg.norm(miss) / np.linalg.norm(total))
    return out


def main() -> None:
    from pneufdd.features import feature_matrix
    from pneufdd.signals.segmentation import sequence_from_machine
    from pneufdd.sim import as_exported, load_machine, simulate, vary_machine

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=0.0, help="plant variation scale")
    parser.add_argument("--seed", type=int, default=97_300_000, help="first seed")
    parser.add_argument("--machine", default="festo-dsd", help="built-in name or TOML path")
    args = parser.parse_args()
    desc = load_machine(args.machine)
    plant = desc if args.scale == 0 else vary_machine(desc, args.scale, args.seed)
    sequence = sequence_from_machine(desc)
    stroke: dict[str, list[npt.NDArray[np.float64]]] = {}
    cycle: dict[str, list[list[float]]] = {}
    times: dict[str, list[npt.NDArray[np.float64]]] = {}
    for k, (label, leaks) in enumerate(_runs()):
        rec = as_exported(simulate(plant, cycles=10, leaks=leaks, seed=args.seed + 1 + k))
        feats = feature_matrix(rec, ("DNC",), ("air", "table44"), sequence=sequence).iloc[:8]
        stroke.setdefault(label, []).append(
            feats[["DNC.air_extend_SL", "DNC.air_retract_SL"]].to_numpy()
        )
        times.setdefault(label, []).append(
            feats[["DNC.t44_12_t_s_extend_s", "DNC.t44_13_t_s_retract_s"]].to_numpy()
        )
        starts = np.asarray(rec.metadata["cycle_start_s"], dtype=np.float64)
        cycle.setdefault(label, []).extend(_cycle_air(rec, starts, range(1, 9)))
    by_stroke = _errors({k: np.concatenate(v).mean(axis=0) for k, v in stroke.items()})
    by_cycle = _errors({k: np.asarray(v).mean(axis=0) for k, v in cycle.items()})
    print(f"{args.machine}, plant scale {args.scale:g}, seeds {args.seed + 1}..")
    print("eq. 5.23 error |centre(A+B) - (v_A + v_B)| / |v_A + v_B|: stroke step | whole cycle")
    for key, value in by_stroke.items():
        print(f"  {key}: {100 * value:6.1f} % | {100 * by_cycle[key]:6.1f} %")
    print(
        f"  median: {100 * np.median(list(by_stroke.values())):.1f} % | "
        f"{100 * np.median(list(by_cycle.values())):.1f} %"
    )
    print("mean stroke times [s] and stroke air [SL], extend / retract:")
    for key, value in times.items():
        mean = np.concatenate(value).mean(axis=0)
        air = np.concatenate(stroke[key]).mean(axis=0)
        print(f"  {key}: {mean[0]:.3f} / {mean[1]:.3f} s, {air[0]:.3f} / {air[1]:.3f} SL")


if __name__ == "__main__":
    main()
