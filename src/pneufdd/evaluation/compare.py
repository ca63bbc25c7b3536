"""One table comparing the dissertation's classifiers, the residual detector and the engine.

Every method is judged on the same runs of the same simulated plants (a campaign,
:mod:`pneufdd.evaluation.campaign`, and its labelled rows,
:mod:`pneufdd.evaluation.labelled`), per machine, plant scale and sensor set. The
difference of kind matters and is in the table's ``training`` column:

* the **classifiers** learn from labelled leak runs of the machine - leaks
  introduced on purpose at every location and size (the dissertation's procedure);
* the **residual detector** and the **engine** need only leak-free runs of the
  plant and the twin (the description); the engine also locates and sizes.

Splits keep whole runs together (a run's cycles are never split between training
and test):

* ``within-plant``: the dissertation's setting. Each plant's runs of every class
  (location and size; leak-free) are dealt round-robin, in seed order, into
  ``reps`` folds; each fold is tested with a model trained on the other folds of the
  same plant plus its reference recordings (leak-free);
* ``across-plants``: leave one plant out of the same machine and scale; trained on
  the other plants' runs (a fleet of "identical" machines).

A run's answer is the majority of its cycles' answers (ties: the first label in
sorted order). Figures, over the test runs: ``location_acc`` (single-leak runs
whose location is right), ``level_acc`` (location and size right; for the engine:
its flow estimate nearest, in log, to the true size's flow among the campaign's
sizes), ``size_err_median`` (median relative error of the flow of the predicted
level against the true flow, runs with the right location), ``detected``
(single-leak runs called leaking), ``false_alarm`` (leak-free runs called leaking),
``group_size`` (mean size of the answer's ambiguity group). Times per diagnosis
are measured, not reproducible, and written apart (``evaluation_times.csv``).
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from sklearn.base import BaseEstimator
from sklearn.decomposition import PCA
from sklearn.impute import SimpleImputer
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import StandardScaler

from pneufdd.classifiers import (
    GaussianBayesClassifier,
    MinimumDistanceClassifier,
    NearestNeighbourClassifier,
    SignTableClassifier,
    VectorizedMap,
    VoronoiNeighbourClassifier,
)
from pneufdd.diagnosis.detection.residuals import ResidualDetector
from pneufdd.errors import InputError, describe
from pneufdd.evaluation.campaign import channel_sets
from pneufdd.evaluation.labelled import LABEL_COLUMNS, feature_channels, read_manifest
from pneufdd.files import safe_name
from pneufdd.sim import load_machine

__all__ = ["METHODS", "Comparison", "compare", "confusion_figures"]


def _classifier(clf: BaseEstimator, scale: bool = True) -> Pipeline:
    steps: list[Any] = [SimpleImputer(strategy="median")]
    if scale:
        steps.append(StandardScaler())
    return make_pipeline(*steps, clf)


METHODS: dict[str, Callable[[], Pipeline]] = {
    "min-distance (eq. 5.20)": lambda: _classifier(MinimumDistanceClassifier()),
    "min-distance Mahalanobis (eq. 5.19)": lambda: _classifier(
        MinimumDistanceClassifier(metric="mahalanobis")
    ),
    "1-NN Euclidean (5.3.2)": lambda: _classifier(NearestNeighbourClassifier()),
    "5-NN Mahalanobis (5.3.2)": lambda: _classifier(
        NearestNeighbourClassifier(n_neighbors=5, metric="mahalanobis")
    ),
    "Gaussian Bayes diagonal (5.18)": lambda: _classifier(
        GaussianBayesClassifier(covariance="diagonal")
    ),
    "Gaussian Bayes pooled (5.18)": lambda: _classifier(
        GaussianBayesClassifier(covariance="pooled")
    ),
    "sign table (Table 4.5)": lambda: _classifier(SignTableClassifier(), scale=False),
    "vectorized map (5.3.4)": lambda: _classifier(VectorizedMap(), scale=False),
    "Voronoi 1-NN, 3 PCA axes (5.3.5)": lambda: _classifier(
        make_pipeline(PCA(n_components=3, random_state=0), VoronoiNeighbourClassifier())
    ),
}
"""Classifiers compared: name -> a fresh pipeline (imputer, scaler, estimator)."""

LOCATION_ONLY = ("sign table (Table 4.5)",)
AIR_ONLY = ("vectorized map (5.3.4)",)
RUN_MEANS = ("Voronoi 1-NN, 3 PCA axes (5.3.5)",)
ENGINE = "engine (leak-free runs + twin)"
RESIDUALS = "physics residuals (eq. 4.1, 4.21)"


@dataclass
class Comparison:
    """The comparison table and the measured times.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per machine, scale, sensor set, split and method (reproducible).
    times : pandas.DataFrame
        Time per diagnosis (one run) of each row [s] (measured).
    confusions : dict
        (machine, scale, sensors, split, method) -> (labels, matrix) of locations.
    """

    table: pd.DataFrame
    times: pd.DataFrame
    confusions: dict[tuple[Any, ...], tuple[list[str], npt.NDArray[np.int64]]]

    def markdown(self) -> str:
        """The table as Markdown (one section per split)."""
        out = []
        cols = [
            "machine",
            "scale",
            "sensors",
            "method",
            "location_acc",
            "level_acc",
            "size_err_median",
            "detected",
            "false_alarm",
            "group_size",
            "ms_per_run",
            "training",
        ]
        merged = self.table.merge(self.times, on=["machine", "scale", "sensors", "split", "method"])
        merged["ms_per_run"] = 1e3 * merged["seconds_per_run"]
        for split, part in merged.groupby("split", sort=True):
            out.append(f"\n### split: {split}\n")
            out.append("| " + " | ".join(cols) + " |")
            out.append("|" + "---|" * len(cols))
            for _, row in part.iterrows():
                out.append("| " + " | ".join(_fmt(row[c]) for c in cols) + " |")
        return "\n".join(out) + "\n"


def _fmt(v: object) -> str:
    if isinstance(v, float | np.floating):
        return "n/a" if not np.isfinite(v) else f"{float(v):.3g}"
    return str(v)


def _vote(labels: Iterable[Any]) -> str:
    values, counts = np.unique(np.asarray(list(labels), dtype=str), return_counts=True)
    return str(values[int(np.argmax(counts))])


def _location(level: str) -> str:
    return level.split("@")[0]


def _columns(frame: pd.DataFrame, channels: tuple[str, ...]) -> list[str]:
    allowed = set(channels)
    cols = []
    for c in frame.columns:
        if c in LABEL_COLUMNS or c.startswith("res_"):
            continue
        need = [n for n in feature_channels(c) if n[:2] in ("P_", "Q_", "X_")]
        if all(n in allowed for n in need):
            cols.append(c)
    keep = [c for c in cols if frame[c].notna().mean() >= 0.9 and frame[c].nunique() > 1]
    return keep


def _folds(test_frame: pd.DataFrame, reps: int) -> dict[int, int]:
    """Run seed -> fold: each class's runs dealt round-robin in seed order."""
    fold: dict[int, int] = {}
    runs = test_frame[["seed", "level"]].drop_duplicates().sort_values(["level", "seed"])
    for _, group in runs.groupby("level", sort=True):
        for i, seed in enumerate(group["seed"].tolist()):
            fold[int(seed)] = i % reps
    return fold


def _judge(
    runs: pd.DataFrame,
    answers: dict[int, str],
    level_flow: dict[str, float],
    groups: dict[int, int] | None = None,
) -> dict[str, float]:
    """Figures of one method over the runs (one row per run: seed, kind, level, truth)."""
    single = runs[runs["kind"] == "single"]
    free = runs[runs["kind"] == "free"]
    loc_ok, lvl_ok, det, errs = [], [], [], []
    for _, r in single.iterrows():
        a = answers[int(r["seed"])]
        loc_ok.append(_location(a) == r["location"])
        lvl_ok.append(a == r["level"])
        det.append(a != "none")
        if _location(a) == r["location"] and a in level_flow and r["truth_kg_s"] > 0:
            errs.append(abs(level_flow[a] - r["truth_kg_s"]) / r["truth_kg_s"])
    fa = [answers[int(s)] != "none" for s in free["seed"]]
    return {
        "location_acc": float(np.mean(loc_ok)) if loc_ok else np.nan,
        "level_acc": float(np.mean(lvl_ok)) if lvl_ok else np.nan,
        "size_err_median": float(np.median(errs)) if errs else np.nan,
        "detected": float(np.mean(det)) if det else np.nan,
        "false_alarm": float(np.mean(fa)) if fa else np.nan,
        "group_size": float(np.mean(list(groups.values()))) if groups else 1.0,
        "test_runs": float(len(single) + len(free)),
    }


def _run_table(frame: pd.DataFrame) -> pd.DataFrame:
    return (
        frame[frame["kind"] != "reference"]
        .groupby("seed", sort=True)
        .first()[["kind", "location", "level", "truth_kg_s", "plant"]]
        .reset_index()
    )


def _fit_predict(
    name: str, train: pd.DataFrame, test: pd.DataFrame, cols: list[str]
) -> tuple[dict[int, str], dict[int, int], float]:
    pipe = METHODS[name]()
    air = [c for c in cols if c.endswith("_SL")] if name in AIR_ONLY else cols
    target = "location" if name in LOCATION_ONLY else "level"
    if name in RUN_MEANS:
        means = train.groupby("seed", sort=True)
        x_train = means[air].mean().to_numpy()
        y_train = means[target].first().to_numpy()
        n_none = train[train["level"] == "none"]
        if len(n_none):  # reference recordings: split into runs of 10 cycles
            blocks = n_none.copy()
            blocks["block"] = np.arange(len(n_none)) // 10
            ref = blocks[blocks["kind"] == "reference"].groupby(["seed", "block"])[air].mean()
            x_train = np.vstack([x_train, ref.to_numpy()])
            y_train = np.concatenate([y_train, ["none"] * len(ref)])
    else:
        x_train, y_train = train[air].to_numpy(), train[target].to_numpy()
    with warnings.catch_warnings():
        # run-mean templates: a handful per class, which scikit-learn's target check
        # takes for a regression target
        warnings.filterwarnings("ignore", message="The number of unique classes")
        pipe.fit(x_train, y_train)
    answers: dict[int, str] = {}
    groups: dict[int, int] = {}
    seeds = test["seed"].to_numpy()
    start = time.perf_counter()  # all test cycles at once; the time is shared per run
    x = test[air].to_numpy()
    if name in AIR_ONLY:
        vmap: VectorizedMap = pipe[-1]
        label, reach, _ = vmap.locate(pipe[:-1].transform(x))
    else:
        label, reach = pipe.predict(x), np.ones(len(x), dtype=np.int64)
    for seed in np.unique(seeds):
        here = seeds == seed
        answers[int(seed)] = _vote(label[here])
        groups[int(seed)] = int(np.round(np.mean(reach[here])))
    seconds = (time.perf_counter() - start) / max(len(answers), 1)
    return answers, (groups if name in AIR_ONLY else {}), seconds


def _residual_answers(
    train: pd.DataFrame, test: pd.DataFrame
) -> tuple[dict[int, str], dict[str, float], float]:
    ref = train[train["kind"] == "reference"]
    # a step whose mean is missing in a reference cycle (a zero-length step) is left out;
    # flow columns first, then the pressure columns of the same steps
    steps = [
        c[6:]
        for c in train.columns
        if c.startswith("res_Q_") and ref[c].notna().all() and ref[f"res_P_{c[6:]}"].notna().all()
    ]
    cols = [f"res_Q_{s}" for s in steps] + [f"res_P_{s}" for s in steps]
    fill = ref[cols].mean()
    det = ResidualDetector().fit(ref[cols].to_numpy())
    answers: dict[int, str] = {}
    flagged_free: list[int] = []
    flagged_leak: list[int] = []
    start = time.perf_counter()
    for key, rows in test.groupby("seed", sort=True):
        flags = det.predict(rows[cols].fillna(fill).to_numpy())
        answers[int(str(key))] = "leak" if flags.mean() > 0.5 else "none"
        (flagged_free if rows["kind"].iloc[0] == "free" else flagged_leak).extend(flags.tolist())
    seconds = (time.perf_counter() - start) / max(len(answers), 1)
    cycles = {
        "cycle_false_alarm": float(np.mean(flagged_free)) if flagged_free else np.nan,
        "cycle_detected": float(np.mean(flagged_leak)) if flagged_leak else np.nan,
    }
    return answers, cycles, seconds


def _engine(
    folder: Path, machine: str, scale: float, sensors: str, runs: pd.DataFrame, sizes: list[str]
) -> tuple[dict[str, float], float, dict[int, str]]:
    path = folder / "runs.jsonl"
    records = {}
    for line in path.read_text("utf-8").splitlines():
        rec = json.loads(line)
        if rec.get("stalled") or rec["machine"] != machine or rec["sensors"] != sensors:
            continue
        if float(rec["scale"]) != scale:
            continue
        records[int(rec["seed"])] = rec
    size_flow = (
        runs[runs["kind"] == "single"].groupby(runs["level"].str.split("@").str[1])["truth_kg_s"]
    ).mean()
    loc_ok, lvl_ok, det, errs, fa, groups, secs = [], [], [], [], [], [], []
    answers: dict[int, str] = {}
    for _, r in runs.iterrows():
        rec = records.get(int(r["seed"]))
        if rec is None:
            continue
        secs.append(float(rec["seconds"]))
        leaks = rec["leaks"]
        top = leaks[0] if leaks else None
        answers[int(r["seed"])] = top["location"] if (top and rec["detected"]) else "none"
        if r["kind"] == "free":
            fa.append(bool(rec["detected"]))
            continue
        det.append(bool(rec["detected"]))
        if top is None or not rec["detected"]:
            loc_ok.append(False)
            lvl_ok.append(False)
            continue
        groups.append(len(top["group"]))
        loc_ok.append(top["location"] == r["location"])
        if r["location"] in top["group"]:
            est = float(top["group_flows"][top["group"].index(r["location"])])
            if top["location"] == r["location"]:
                errs.append(abs(est - r["truth_kg_s"]) / r["truth_kg_s"])
            nearest = min(
                size_flow.index, key=lambda s: abs(np.log(max(est, 1e-12) / size_flow[s]))
            )
            true_size = str(r["level"]).split("@")[1]
            lvl_ok.append(top["location"] == r["location"] and nearest == true_size)
        else:
            lvl_ok.append(False)
    figures = {
        "location_acc": float(np.mean(loc_ok)) if loc_ok else np.nan,
        "level_acc": float(np.mean(lvl_ok)) if lvl_ok else np.nan,
        "size_err_median": float(np.median(errs)) if errs else np.nan,
        "detected": float(np.mean(det)) if det else np.nan,
        "false_alarm": float(np.mean(fa)) if fa else np.nan,
        "group_size": float(np.mean(groups)) if groups else np.nan,
        "test_runs": float(len(det) + len(fa)),
    }
    return figures, float(np.mean(secs)) if secs else np.nan, answers


def _confusion(
    runs: pd.DataFrame, answers: dict[int, str]
) -> tuple[list[str], npt.NDArray[np.int64]]:
    truth = [str(x) for x in runs["location"]]
    pred = [_location(answers.get(int(s), "none")) for s in runs["seed"]]
    labels = sorted(set(truth) | set(pred), key=lambda x: (x != "none", x))
    index = {lab: i for i, lab in enumerate(labels)}
    m = np.zeros((len(labels), len(labels)), dtype=np.int64)
    for t, p in zip(truth, pred, strict=True):
        m[index[t], index[p]] += 1
    return labels, m


def compare(
    folder: str | Path,
    frame: pd.DataFrame,
    methods: Iterable[str] | None = None,
    log: Callable[[str], None] | None = None,
) -> Comparison:
    """Cross-validate every method on a campaign's labelled rows; judge the engine too.

    Parameters
    ----------
    folder : str or Path
        The campaign folder (``manifest.json``, ``runs.jsonl``).
    frame : pandas.DataFrame
        Its labelled rows (:func:`pneufdd.evaluation.labelled.labelled_frames`).
    methods : iterable of str, optional
        Classifier names of :data:`METHODS` (all by default).
    log : callable, optional
        Receives one line per machine, scale and sensor set.

    Returns
    -------
    Comparison
    """
    chosen = list(METHODS) if methods is None else list(methods)
    unknown = [m for m in chosen if m not in METHODS]
    if unknown:
        raise InputError(describe("methods", unknown, list(METHODS)))
    manifest = read_manifest(folder)
    design = manifest["design"]
    reps = int(design["reps"])
    say = log or (lambda _line: None)
    rows: list[dict[str, Any]] = []
    times: list[dict[str, Any]] = []
    confusions: dict[tuple[Any, ...], tuple[list[str], npt.NDArray[np.int64]]] = {}
    for entry in manifest["machines"]:
        machine = load_machine(entry["source"])
        sets = channel_sets(machine, design["sensor_sets"])
        for scale in sorted({float(p["scale"]) for p in entry["plants"]}):
            part = frame[(frame["machine"] == machine.name) & (frame["scale"] == scale)]
            if part.empty:
                continue
            runs = _run_table(part)
            level_flow = {
                str(k): float(v)
                for k, v in part[part["kind"] == "single"]
                .groupby("level", sort=True)["truth_kg_s"]
                .mean()
                .items()
            }
            n_loc = part.loc[part["kind"] == "single", "location"].nunique()
            n_size = part.loc[part["kind"] == "single", "size"].nunique()
            for sensors, channels in sets.items():
                cols = _columns(part, channels)
                base = {"machine": machine.name, "scale": scale, "sensors": sensors}
                figures, secs, eng = _engine(Path(folder), machine.name, scale, sensors, runs, [])
                for split in ("within-plant", "across-plants"):
                    key = {**base, "split": split}
                    rows.append(
                        {
                            **key,
                            "method": ENGINE,
                            **figures,
                            "training": f"{int(design['reference_cycles'])} leak-free cycles "
                            "a plant + description",
                        }
                    )
                    times.append({**key, "method": ENGINE, "seconds_per_run": secs})
                    confusions[(*key.values(), ENGINE)] = _confusion(runs, eng)
                for split in ("within-plant", "across-plants"):
                    if split == "within-plant" and reps < 2:
                        continue  # one run per class: a held-out run's class is unseen
                    answers_by: dict[str, dict[int, str]] = {m: {} for m in chosen}
                    groups_by: dict[str, dict[int, int]] = {m: {} for m in chosen}
                    secs_by: dict[str, list[float]] = {m: [] for m in chosen}
                    res_answers: dict[int, str] = {}
                    res_cycles: list[dict[str, float]] = []
                    res_secs: list[float] = []
                    train_runs: list[int] = []
                    for plant in sorted(part["plant"].unique()):
                        here = part[part["plant"] == plant]
                        labelled = here[here["kind"] != "reference"]
                        if split == "within-plant":
                            fold = _folds(labelled, reps)
                            splits = []
                            for f in range(reps):
                                test = labelled[labelled["seed"].map(fold) == f]
                                train = here[
                                    (here["kind"] == "reference")
                                    | (labelled["seed"].map(fold).reindex(here.index) != f)
                                ]
                                splits.append((train, test))
                        else:
                            others = part[part["plant"] != plant]
                            if others.empty:
                                continue
                            splits = [(others, labelled)]
                        for train, test in splits:
                            train_runs.append(
                                int(train.loc[train["kind"] == "single", "seed"].nunique())
                            )
                            for name in chosen:
                                a, g, s = _fit_predict(name, train, test, cols)
                                answers_by[name].update(a)
                                groups_by[name].update(g)
                                secs_by[name].append(s)
                        if sensors == next(iter(sets)):
                            a, c, s = _residual_answers(here, labelled)
                            res_answers.update(a)
                            res_cycles.append(c)
                            res_secs.append(s)
                    if not train_runs:
                        continue
                    training = (
                        f"{int(np.mean(train_runs))} labelled leak runs ({n_loc} locations x "
                        f"{n_size} sizes) + leak-free"
                    )
                    tested = (
                        runs[runs["seed"].isin(list(answers_by[chosen[0]]))] if chosen else runs
                    )
                    for name in chosen:
                        key = {**base, "split": split, "method": name}
                        figs = _judge(tested, answers_by[name], level_flow, groups_by[name])
                        if name in LOCATION_ONLY:
                            figs["level_acc"] = np.nan
                            figs["size_err_median"] = np.nan
                        rows.append({**key, **figs, "training": training})
                        times.append({**key, "seconds_per_run": float(np.mean(secs_by[name]))})
                        confusions[tuple(key.values())] = _confusion(tested, answers_by[name])
                    if res_answers and split == "within-plant":
                        key = {**base, "split": split, "method": RESIDUALS}
                        figs = _judge(runs, res_answers, {}, None)
                        figs["location_acc"] = figs["level_acc"] = np.nan
                        figs["group_size"] = np.nan
                        figs["cycle_false_alarm"] = float(
                            np.nanmean([c["cycle_false_alarm"] for c in res_cycles])
                        )
                        figs["cycle_detected"] = float(
                            np.nanmean([c["cycle_detected"] for c in res_cycles])
                        )
                        rows.append(
                            {**key, **figs, "training": "reference leak-free cycles + description"}
                        )
                        times.append({**key, "seconds_per_run": float(np.mean(res_secs))})
                say(f"{machine.name}, scale {scale:g}, {sensors}: {len(cols)} features")
    table = pd.DataFrame(rows)
    return Comparison(table, pd.DataFrame(times), confusions)


def confusion_figures(comparison: Comparison, out: Path) -> list[Path]:
    """Location confusion matrices: the engine beside the best classifier, per case.

    Names (machine, locations) are drawn as plain text, never as mathtext or LaTeX,
    and file names are made of safe components (:func:`pneufdd.files.safe_name`).
    """
    import matplotlib

    matplotlib.use("Agg")
    with matplotlib.rc_context({"text.parse_math": False, "text.usetex": False}):
        return _confusion_figures(comparison, out)


def _confusion_figures(comparison: Comparison, out: Path) -> list[Path]:
    import matplotlib.pyplot as plt

    paths = []
    table = comparison.table
    for (machine, scale, sensors), part in table[table["split"] == "within-plant"].groupby(
        ["machine", "scale", "sensors"], sort=True
    ):
        clfs = part[part["method"].isin(list(METHODS))]
        if clfs.empty:
            continue
        best = str(
            clfs.sort_values("location_acc", ascending=False, kind="stable")["method"].iloc[0]
        )
        fig, axes = plt.subplots(1, 2, figsize=(13, 6))
        for ax, method in zip(axes, (ENGINE, best), strict=True):
            labels, m = comparison.confusions[(machine, scale, sensors, "within-plant", method)]
            ax.imshow(m, cmap="Blues")
            ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=6)
            ax.set_yticks(range(len(labels)), labels, fontsize=6)
            ax.set_xlabel("answer")
            ax.set_ylabel("true location")
            ax.set_title(method, fontsize=9)
        fig.suptitle(f"{machine}, plant scale {scale:g}, sensors {sensors}: runs by location")
        fig.tight_layout()
        path = out / f"confusion-{safe_name(str(machine))}-s{scale:g}-{safe_name(str(sensors))}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        paths.append(path)
    return paths
