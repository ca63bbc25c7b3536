"""Eq. 5.23 on a machine: do combined extend + retract leaks add up as vectors?

Fig. 5.18 plots the air consumed by the extend and the retract stroke of the DNC,
each normalised by its leak-free value; single leaks on either line form clusters
along the axes, and a combined leak lands near the vector sum of its single leaks
(eq. 5.23). :func:`vector_sum_check` simulates that experiment on a plant: leak-free
runs, single extend-line and retract-line leaks, both lines together, and the
supply line, then

* fits a :class:`~pneufdd.classifiers.VectorizedMap` on the consumed-air axes and
  measures ``|centre(A+B) - (v_A + v_B)| / |v_A + v_B|`` for every size pair;
* learns the sign table of the 13 Table 4.4 features (rows extend, retract, both,
  supply), to be set beside Table 4.5.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pneufdd.classifiers import SignTableClassifier, VectorizedMap
from pneufdd.errors import InputError, describe
from pneufdd.features import feature_matrix
from pneufdd.features.table44 import TABLE_44_NAMES
from pneufdd.signals.segmentation import plc_sequence
from pneufdd.sim import as_exported, load_machine, simulate, vary_machine

__all__ = ["VectorSumCheck", "vector_sum_check"]


@dataclass
class VectorSumCheck:
    """Result of :func:`vector_sum_check`.

    Attributes
    ----------
    axes : tuple of str
        Feature columns of the map (extend-stroke air, retract-stroke air) [SL].
    normalised : pandas.DataFrame
        Every cycle: the two axes normalised by the leak-free mean, and its label.
    vmap : VectorizedMap
        Fitted on leak-free and single-leak cycles.
    errors : dict
        ``"DNC_A@a+DNC_B@b"`` -> relative distance between the combined cluster's
        centre and the vector sum of the single leaks [-].
    learned_table : dict
        Row name (extend, retract, both, supply) -> learned ``+-0`` string.
    """

    axes: tuple[str, str]
    normalised: pd.DataFrame
    vmap: VectorizedMap
    errors: dict[str, float] = field(default_factory=dict)
    learned_table: dict[str, str] = field(default_factory=dict)


def vector_sum_check(
    machine: str = "festo-dsd",
    actuator: str = "DNC",
    scale: float = 1.0,
    sizes: tuple[str, ...] = ("2", "4", "6"),
    cycles: int = 8,
    seed: int = 96_200_000,
) -> VectorSumCheck:
    """Simulate Fig. 5.18's experiment on a plant and measure eq. 5.23.

    Parameters
    ----------
    machine : str
        Built-in name or TOML path.
    actuator : str
        Actuator whose lines leak (with line flow sensors).
    scale : float
        Plant variation scale (0: the twin itself) [-].
    sizes : tuple of str
        Leak-valve turns (or sizes the simulator takes) of each single leak.
    cycles : int
        Cycles per run [-].
    seed : int
        First seed; the plant uses ``seed``, runs ``seed + 1, seed + 2, ...``.

    Returns
    -------
    VectorSumCheck
    """
    desc = load_machine(machine)
    plant = desc if scale == 0 else vary_machine(desc, scale, seed)
    sequence = plc_sequence(machine=desc)
    a, b = f"{actuator}_A", f"{actuator}_B"
    runs: list[tuple[str, str, dict[str, str]]] = [("none", "none", {})] * 2
    for s in sizes:
        runs += [(f"{a}@{s}", "extend", {a: s}), (f"{b}@{s}", "retract", {b: s})]
        runs += [(f"supply@{s}", "supply", {"supply": s})]
    for s in sizes:
        for t in sizes:
            runs.append((f"{a}@{s}+{b}@{t}", "both", {a: s, b: t}))
    frames = []
    for k, (label, row, leaks) in enumerate(runs):
        rec = as_exported(simulate(plant, cycles=cycles + 2, leaks=leaks, seed=seed + 1 + k))
        feats = feature_matrix(rec, (actuator,), ("air", "table44"), sequence=sequence)
        feats = feats.iloc[:cycles].reset_index(drop=True)
        feats["label"], feats["row"] = label, row
        frames.append(feats)
    data = pd.concat(frames, ignore_index=True)
    axes = (f"{actuator}.air_extend_SL", f"{actuator}.air_retract_SL")
    singles = data[~data["label"].str.contains(r"\+") & (data["row"] != "supply")]
    measured = singles[list(axes)].to_numpy()
    unmeasured = int((~np.isfinite(measured)).any(axis=1).sum())
    if unmeasured:
        raise InputError(
            describe(
                f"actuator {actuator!r} of {desc.name} (--actuator)",
                f"extend/retract air not measured in {unmeasured} of {len(measured)} cycles",
                "an actuator whose air per stroke the machine's flow sensors give",
            )
        )
    vmap = VectorizedMap().fit(measured, singles["label"].to_numpy())
    norm = data[list(axes)].to_numpy() / vmap.scale_
    normalised = pd.DataFrame(norm, columns=list(axes))
    normalised["label"] = data["label"].to_numpy()
    errors: dict[str, float] = {}
    for label in sorted(set(data["label"])):
        if "+" not in label:
            continue
        centre = normalised.loc[normalised["label"] == label, list(axes)].mean().to_numpy()
        origin = vmap.centres_[list(vmap.classes_).index("none")]
        total = vmap.combined_vector(label.split("+"))
        errors[label] = float(np.linalg.norm(centre - origin - total) / np.linalg.norm(total))
    cols = [f"{actuator}.{n}" for n in TABLE_44_NAMES]
    # a feature the sensors cannot give (a one-way flow meter) is "?" in the table
    valid = [c for c in cols if data[c].notna().any()]
    table = data[valid].fillna(data[valid].median())  # a feature missing in a few cycles
    signs = SignTableClassifier(normal_class="none").fit(table.to_numpy(), data["row"].to_numpy())
    learned: dict[str, str] = {}
    for row, text in signs.table_strings().items():
        if row == "none":
            continue
        chars = iter(text)
        learned[str(row)] = "".join(next(chars) if c in valid else "?" for c in cols)
    return VectorSumCheck(axes, normalised, vmap, errors, learned)


def check_lines(result: VectorSumCheck, published: dict[str, str]) -> list[str]:
    """Printable summary: eq. 5.23 errors and the learned table beside Table 4.5."""
    out = ["eq. 5.23: |centre(A+B) - (v_A + v_B)| / |v_A + v_B|"]
    out += [f"  {k}: {100 * v:.1f} %" for k, v in result.errors.items()]
    out.append("sign table (Table 4.4 features 1-13): learned | Table 4.5 | agreeing")
    for row, text in published.items():
        mine = result.learned_table.get(row, "?" * len(text))
        same = sum(x == y for x, y in zip(mine, text, strict=False))
        out.append(f"  {row:8s} {mine} | {text} | {same}/{len(text)}")
    return out
