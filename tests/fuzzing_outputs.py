"""Fuzz cases of issue 39's output policy, live outputs, printed names and data gaps.

Part of ``make fuzz`` (:func:`fuzzing.build_corpus`): every case the hardening round
reported beside the resource bounds of :mod:`fuzzing_bounds`:

* ``monitor --alarm-log`` onto the recording, the reference, a symbolic or a hard
  link to either, a folder, a path under a file; ``--history`` onto an input or onto
  the alarm log; every malformed ``--webhook`` (refused at start, exit 2);
* machine names that are rich markup, matplotlib mathtext or path traversal, through
  ``simulate`` and ``machine vary`` (printed as text, never a path component);
* recordings with a non-finite supply-flow sample or gaps in every cycle, through
  ``machine draft`` and ``machine calibrate`` (the gap rule, docs/data-quality.md).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from fuzzing import EXIT_INPUT, EXIT_OK, MACHINE, Case, _case_dir, _put, _with
from pneufdd import Recording

__all__ = ["build_outputs"]

WEBHOOKS = (
    "notaurl",
    "file:///etc/passwd",
    "ftp://host/x",
    "http://",
    "http://host:99999/",
    "http://a b/",
)
"""``--webhook`` values that are no http(s) URL a monitor could post to."""

NAMES = ("cell[/]", "[bold]x[/bold", "$\\undefinedcmd$", "a$b$c [red]", "../../victim", "..")
"""Machine names that are markup, mathtext or path traversal."""


def build_outputs(
    base: dict[str, Path], root: Path, full: bool, wanted: Iterable[str]
) -> list[Case]:
    """The cases of the commands in ``wanted`` (the quick slice: one of each kind)."""
    chosen = set(wanted)
    cases: list[Case] = []
    if "monitor" in chosen and "pnref" in base:
        cases += _monitor_outputs(base, root, full)
    if "simulate" in chosen or "machine vary" in chosen:
        cases += _names(base, root, full, chosen)
    if "machine draft" in chosen or "machine calibrate" in chosen:
        cases += _gaps(base, root, full, chosen)
    return cases


def _monitor(ref: str, run: str, *extra: str) -> list[str]:
    return ["monitor", "--reference", ref, "--source", f"replay:{run}?speed=max", "--once", *extra]


def _monitor_outputs(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "outputs-monitor")
    ref = _put(folder, "ref.pnref", base["pnref"])
    run = _put(folder, "run.parquet", base["run"])
    for link, target in (("run-link.parquet", run), ("ref-link.pnref", ref)):
        if not (folder / link).is_symlink():
            os.symlink(target, folder / link)
    for hard, target in (("run-hard.parquet", run), ("ref-hard.pnref", ref)):
        if not (folder / hard).exists():
            os.link(folder / target, folder / hard)
    (folder / "a-folder").mkdir(exist_ok=True)
    history = "sqlite:///h.db"
    refused: list[tuple[str, list[str], tuple[str, ...]]] = [
        ("alarm_log_recording", ["--alarm-log", run, "--history", history], ("--alarm-log",)),
        ("alarm_log_reference", ["--alarm-log", ref, "--history", history], ("--alarm-log",)),
        ("alarm_log_symlink_recording", ["--alarm-log", "run-link.parquet"], ("--alarm-log",)),
        ("alarm_log_symlink_reference", ["--alarm-log", "ref-link.pnref"], ("--alarm-log",)),
        ("alarm_log_hardlink_recording", ["--alarm-log", "run-hard.parquet"], ("--alarm-log",)),
        ("alarm_log_hardlink_reference", ["--alarm-log", "ref-hard.pnref"], ("--alarm-log",)),
        ("alarm_log_folder", ["--alarm-log", "a-folder"], ("--alarm-log",)),
        ("alarm_log_under_a_file", ["--alarm-log", f"{run}/a.jsonl"], ("--alarm-log",)),
        ("history_onto_recording", ["--history", f"sqlite:///{run}"], ("--history",)),
        ("history_onto_reference", ["--history", f"sqlite:///{ref}"], ("--history",)),
        (
            "history_onto_alarm_log",
            ["--history", "sqlite:///same.db", "--alarm-log", "same.db"],
            ("--history", "--alarm-log"),
        ),
    ]
    hooks = WEBHOOKS if full else WEBHOOKS[:2]
    refused += [
        (f"webhook_{k}", ["--webhook", url, "--history", history], ("--webhook",))
        for k, url in enumerate(hooks)
    ]
    if not full:
        refused = refused[:4] + refused[-len(hooks) :]
    inputs = [ref, run, "run-link.parquet", "ref-link.pnref", "run-hard.parquet", "ref-hard.pnref"]
    return [
        Case(
            f"monitor/{label}",
            "monitor",
            _monitor(ref, run, *extra),
            folder,
            inputs,
            [],
            frozenset({EXIT_INPUT}),
            words,
        )
        for label, extra, words in refused
    ]


def _named_machine(text: str, name: str) -> str:
    """The base description's TOML with its machine ``name`` replaced (TOML-escaped)."""
    escaped = name.replace("\\", "\\\\").replace('"', '\\"')
    return text.replace(f'name = "{MACHINE}"', f'name = "{escaped}"', 1)


def _names(base: dict[str, Path], root: Path, full: bool, chosen: set[str]) -> list[Case]:
    text = base["toml"].read_text("utf-8")
    names = NAMES if full else NAMES[:1]
    cases: list[Case] = []
    for k, name in enumerate(names):
        folder = _case_dir(root, f"outputs-name-{k}")
        toml = _put(folder, "m.toml", _named_machine(text, name).encode("utf-8"))
        if "simulate" in chosen:
            cases.append(
                Case(
                    f"simulate/machine_name_{k}",
                    "simulate",
                    ["simulate", "--machine", toml, "--cycles", "1", "--out", "run.parquet"],
                    folder,
                    [toml],
                    ["run.parquet"],
                    frozenset({EXIT_OK}),
                )
            )
        if "machine vary" in chosen:
            cases.append(
                Case(
                    f"machine vary/machine_name_{k}",
                    "machine vary",
                    ["machine", "vary", toml, "--scale", "1", "--seed", "3", "--out", "v.toml"],
                    folder,
                    [toml],
                    ["v.toml"],
                    frozenset({EXIT_OK}),
                )
            )
    return cases


def _damaged(rec: Recording, every_cycle: bool) -> Recording:
    """``rec`` with one infinite ``Q_In`` sample, or a 0.2 s NaN gap every 2 s."""
    channels = []
    for name in rec.channels:
        ch = rec.info(name)
        if name == "Q_In":
            values = np.array(ch.values, dtype=float)
            if every_cycle:
                step = int(2.0 * ch.rate_hz)
                for start in range(0, values.size, step):
                    values[start : start + int(0.2 * ch.rate_hz)] = np.nan
            else:
                values[values.size // 2] = np.inf
            ch = _with(ch, values.astype(ch.values.dtype))
        channels.append(ch)
    return Recording(channels, rec.start_time, rec.metadata)


def _gaps(base: dict[str, Path], root: Path, full: bool, chosen: set[str]) -> list[Case]:
    rec = Recording.read(base["ref"])
    cases: list[Case] = []
    for every_cycle in (False, True) if full else (True,):
        label = "gaps_every_cycle" if every_cycle else "one_inf_sample"
        folder = _case_dir(root, f"outputs-{label}")
        run = _put(folder, "run.parquet", _damaged(rec, every_cycle))
        if "machine draft" in chosen:
            cases.append(
                Case(
                    f"machine draft/{label}",
                    "machine draft",
                    ["machine", "draft", run, "--out", "d.toml"],
                    folder,
                    [run],
                    ["d.toml"],
                    frozenset({EXIT_OK, EXIT_INPUT}),
                    ("Q_In", "gap", "run.parquet"),
                )
            )
        if every_cycle and "machine calibrate" in chosen:  # refused before the twin runs
            cases.append(
                Case(
                    f"machine calibrate/{label}",
                    "machine calibrate",
                    ["machine", "calibrate", MACHINE, run, "--out", "c.toml"],
                    folder,
                    [run],
                    ["c.toml"],
                    frozenset({EXIT_INPUT}),
                    ("Q_In", "gap", "run.parquet"),
                )
            )
    return cases
