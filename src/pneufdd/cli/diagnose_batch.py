"""``pneufdd diagnose RUN... --reference REF``: many runs, one JSON line each.

Reached from ``pneufdd diagnose`` when it is given more than one run, a folder or a
glob pattern. The runs are diagnosed on a local Dask cluster (``--workers``, default
one process per CPU) or an existing one (``--scheduler tcp://host:8786``); each run's
``--json`` record is printed as one line on standard output (or written to the
``--json`` file, JSON Lines), in the order of the runs. Exit code 2 when a run could
not be diagnosed (its line carries ``"error"``), else 1 when a leak was found in any
run, else 0.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from pneufdd.cli.exit_codes import ExitCode
from pneufdd.diagnosis.cost import CostSettings
from pneufdd.errors import InputError, describe

__all__ = ["is_batch", "run_batch"]


def is_batch(runs: list[Path]) -> bool:
    """Whether ``pneufdd diagnose`` was given a batch: several runs, a folder, a pattern."""
    pattern = bool(set("*?[") & set(str(runs[0]))) and not runs[0].exists()
    return len(runs) != 1 or runs[0].is_dir() or pattern


def run_batch(
    runs: list[Path],
    reference: Path,
    json_out: Path | None,
    report: Path | None,
    settings: CostSettings,
    max_leaks: int | None,
    simulate: bool | None,
    workers: int | None,
    scheduler: str | None,
    threads: int | None = None,
) -> int:
    """Diagnose every run; print or write one JSON line per run; return the exit code."""
    from rich.console import Console

    from pneufdd.diagnosis.batch import diagnose_runs
    from pneufdd.diagnosis.reference.file import load_reference

    if report is not None:
        raise InputError(
            describe("--report", str(report), "one run (a batch writes JSON lines only)")
        )
    if json_out is not None and json_out.exists():
        raise InputError(describe(f"--json file {str(json_out)!r}", "exists", "a new file"))
    localisation = None
    if max_leaks is not None or simulate is not None:
        localisation = load_reference(reference).localisation
        if max_leaks is not None:
            localisation = replace(localisation, max_leaks=max_leaks)
        if simulate is not None:
            localisation = replace(localisation, simulate_explanations=simulate)
    lines = []
    errors = leaks = 0
    out = Console(soft_wrap=True)
    for record in diagnose_runs(
        runs, reference, settings, localisation, workers, scheduler, threads
    ):
        line = json.dumps(record, allow_nan=False)
        errors += "error" in record
        leaks += bool(record.get("detected"))
        if json_out is None:
            out.print(line, markup=False, highlight=False)
        lines.append(line)
    if json_out is not None:
        from pneufdd.files import write_text_atomic

        write_text_atomic(json_out, "\n".join(lines) + "\n")
    Console(stderr=True).print(
        f"{len(lines)} runs: {leaks} with a leak, {errors} not diagnosed", highlight=False
    )
    if errors:
        return ExitCode.INPUT_ERROR
    return ExitCode.LEAK_FOUND if leaks else ExitCode.OK
