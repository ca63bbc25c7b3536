"""Labelled feature rows of a campaign's runs, for the classifiers (issue 12).

The classifiers of :mod:`pneufdd.classifiers` learn from labelled runs. A campaign
(:func:`pneufdd.evaluation.run_campaign`) keeps only the engine's verdicts, so this
module re-simulates every run from the campaign's manifest - the same plant file and
seed give the same recording the engine judged - and writes one Parquet file per
plant under ``<campaign>/labelled/``:

* one row per complete cycle of every single-leak and leak-free run, and of the
  plant's reference recordings (``kind == "reference"``);
* the feature columns of :func:`pneufdd.features.feature_matrix` (groups ``motion``,
  ``air``, ``table44``, every actuator; NaN where the machine lacks the channels);
* the physics residuals of :class:`pneufdd.diagnosis.detection.residuals.TwinReplay`
  (``res_Q_stepNN`` [kg/s], ``res_P_stepNN`` [Pa]) against the twin - the
  description as written - run leak-free with the machine's ``twin_seed``;
* labels: ``location`` (``none``, ``DNC_A``, ...), ``level`` (``DNC_A@2``), the
  size as the campaign wrote it, and the true flow at the description's nominal
  supply pressure ``truth_kg_s`` (as the campaign scores the engine).

Two-leak runs are left out (the classifiers are trained on single leaks, as in the
dissertation). A plant's file that exists is kept (a re-run resumes), never
overwritten. Wavelet features are not computed here (144 per actuator; the
:class:`~pneufdd.classifiers.WaveletTransformer` is for users with step traces).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pneufdd.diagnosis.detection.residuals import TwinReplay
from pneufdd.errors import InputError, NoCompleteCycleError, describe
from pneufdd.features import feature_matrix
from pneufdd.features.registry import REGISTRY
from pneufdd.features.step_summaries import machine_sequence
from pneufdd.physics.leaks import leak_mass_flow
from pneufdd.physics.units import psig_to_pa
from pneufdd.progress import Progress, counter
from pneufdd.sim import MachineDescription, MachineStalledError, as_exported, load_machine, simulate

__all__ = [
    "FEATURE_GROUPS",
    "LABEL_COLUMNS",
    "feature_channels",
    "labelled_frames",
    "read_manifest",
    "twin_seed",
    "write_labelled",
]

FEATURE_GROUPS = ("motion", "air", "table44")
LABEL_COLUMNS = (
    "machine",
    "scale",
    "plant",
    "kind",
    "seed",
    "cycle",
    "location",
    "level",
    "size",
    "truth_kg_s",
)


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The campaign's ``manifest.json``."""
    path = Path(folder) / "manifest.json"
    if not path.is_file():
        raise InputError(describe("campaign manifest", str(path), "an existing manifest.json"))
    try:
        out = json.loads(path.read_text("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise InputError(f"campaign manifest {str(path)!r} is not valid JSON ({exc})") from exc
    if (
        not isinstance(out, dict)
        or not isinstance(out.get("machines"), list)
        or not isinstance(out.get("design"), dict)
    ):
        raise InputError(
            describe(
                f"campaign manifest {str(path)!r}",
                type(out).__name__ if not isinstance(out, dict) else sorted(out),
                'an object with "design" (an object) and "machines" (a list)',
            )
        )
    if out["design"].get("capture"):  # its runs are pooled captures, not what this re-simulates
        raise InputError(
            describe(
                f"campaign {str(path.parent)!r}",
                "recorded as triggered captures (--capture triggered)",
                "a campaign of continuous recordings (the comparison re-simulates its runs so)",
            )
        )
    return out


def twin_seed(manifest: dict[str, Any], machine_index: int) -> int:
    """Seed of the twin's leak-free replay of machine ``machine_index``.

    It lies in the machine's block of the campaign's seeds, above every plant's
    (plant blocks end below ``offset + 1,000,000 m + 900,000``).
    """
    return int(manifest["design"]["seed_offset"]) + 1_000_000 * machine_index + 999_999


def feature_channels(column: str) -> tuple[str, ...]:
    """Analog channels a feature column needs (empty: digital signals only).

    Examples
    --------
    >>> feature_channels("DNC.t44_06_air_a_extend_SL"), feature_channels("step03.air_SL")
    (('Q_DNC_A',), ('Q_In',))
    """
    head, _, name = column.rpartition(".")
    feature = REGISTRY[name]
    target = head if feature.scope == "actuator" else None
    return feature.channels(target)


def _plant_rows(
    plant_entry: dict[str, Any],
    machine: MachineDescription,
    replay: TwinReplay,
    design: dict[str, Any],
) -> pd.DataFrame:
    plant = load_machine(Path(plant_entry["plant_file"]))
    nominal = float(psig_to_pa(machine.nominal_supply_psig))
    sequence = machine_sequence(machine)
    half = int(design["reference_cycles"]) // 2
    runs: list[tuple[str, dict[str, str], int, int]] = [
        ("reference", {}, int(seed), half + 2) for seed in plant_entry["reference_seeds"]
    ]
    runs += [
        (r["kind"], dict(r["leaks"]), int(r["seed"]), int(design["run_cycles"]) + 2)
        for r in plant_entry["runs"]
        if r["kind"] in ("single", "free")
    ]
    frames = []
    for kind, leaks, seed, cycles in runs:
        try:
            rec = simulate(plant, cycles=cycles, leaks=leaks, seed=seed)
        except MachineStalledError:
            continue
        truth = sum(
            float(leak_mass_flow(nominal, float(leak["effective_area_m2"])))
            for leak in rec.metadata["leaks"]
        )
        rec = as_exported(rec)
        try:
            feats = feature_matrix(
                rec, machine.actuator_ids, FEATURE_GROUPS, sequence=sequence, on_missing="nan"
            )
            residuals = replay.residuals(rec, machine)
        except NoCompleteCycleError:
            # leaks that leave the PLC no complete cycle: the campaign lists the run as
            # not judged, with the reason; it is not labelled either
            continue
        feats = feats[[c for c in feats.columns if not c.startswith("leak_")]]
        n_steps = residuals.shape[1] // 2
        names = [f"res_Q_step{j + 1:02d}" for j in range(n_steps)]
        names += [f"res_P_step{j + 1:02d}" for j in range(n_steps)]
        n = min(len(feats), residuals.shape[0])
        if kind != "reference":
            n = min(n, int(design["run_cycles"]))
        location = next(iter(leaks), "none")
        size = str(leaks[location]) if leaks else ""
        labels = pd.DataFrame(
            {
                "machine": machine.name,
                "scale": float(plant_entry["scale"]),
                "plant": int(plant_entry["plant"]),
                "kind": kind,
                "seed": seed,
                "cycle": np.arange(n),
                "location": location,
                "level": f"{location}@{size}" if leaks else "none",
                "size": size,
                "truth_kg_s": truth,
            }
        )
        body = pd.concat(
            [
                labels,
                feats.iloc[:n].reset_index(drop=True),
                pd.DataFrame(residuals[:n], columns=names),
            ],
            axis=1,
        )
        frames.append(body)
    return pd.concat(frames, ignore_index=True)


def _job(args: tuple[dict[str, Any], str, int, dict[str, Any], str]) -> str:
    plant_entry, source, m, manifest, path = args
    machine = load_machine(source)
    replay = TwinReplay.of(machine, cycles=4, seed=twin_seed(manifest, m))
    frame = _plant_rows(plant_entry, machine, replay, manifest["design"])
    frame.to_parquet(path, index=False)
    return path


def write_labelled(
    folder: str | Path,
    workers: int = 1,
    progress: Progress | None = None,
    log: Callable[[str], None] | None = None,
) -> list[Path]:
    """Simulate the campaign's runs again and write their labelled rows (one file a plant).

    Parameters
    ----------
    folder : str or Path
        A campaign folder (with ``manifest.json`` and ``plants/``).
    workers : int
        Plants processed in parallel [-].
    progress : callable, optional
        ``progress(task, done, total)``.
    log : callable, optional
        Receives one line per plant written.

    Returns
    -------
    list of Path
        The Parquet files, in manifest order.
    """
    manifest = read_manifest(folder)
    out = Path(folder) / "labelled"
    out.mkdir(exist_ok=True)
    todo: list[tuple[dict[str, Any], str, int, dict[str, Any], str]] = []
    paths: list[Path] = []
    for m, entry in enumerate(manifest["machines"]):
        for plant in entry["plants"]:
            path = out / f"{Path(plant['plant_file']).stem}.parquet"
            paths.append(path)
            if not path.exists():
                todo.append((plant, entry["source"], m, manifest, str(path)))
    advance = counter(progress, "labelling campaign runs", len(todo))
    say = log or (lambda _line: None)
    if workers <= 1:
        for job in todo:
            say(f"wrote {_job(job)}")
            advance()
    else:
        with ProcessPoolExecutor(workers) as pool:
            for done in pool.map(_job, todo):
                say(f"wrote {done}")
                advance()
    return paths


def labelled_frames(paths: Sequence[Path]) -> pd.DataFrame:
    """All labelled rows of a campaign, in manifest order."""
    return pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)
