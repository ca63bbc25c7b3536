"""Batch diagnosis: many recordings against one reference, here or on a Dask cluster.

A fleet of machines, or one machine's recordings of a month, is diagnosed run by run
against one leak-free reference (``pneufdd diagnose RUN... --reference REF``). The
runs are independent, so :func:`diagnose_runs` spreads them over a
:func:`pneufdd.parallel.executor` (a local Dask cluster, or an existing one by its
scheduler's address) and yields one JSON-ready record per run, in the order the runs
were given, identical to what the serial path gives.

A run that cannot be diagnosed (unreadable file, another machine, too few cycles)
gives a record with an ``"error"`` message instead of stopping the batch.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pneufdd.diagnosis.cost import CostSettings
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.diagnosis.recordings import diagnose_recording
from pneufdd.diagnosis.reference.file import load_reference
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError, PneufddError, describe
from pneufdd.parallel import available_cores, executor, map_unordered, positive_count
from pneufdd.recording.io import SUFFIXES

__all__ = ["RunJob", "diagnose_one", "diagnose_runs", "expand_runs"]

_PATTERN_CHARACTERS = frozenset("*?[")


def _glob(pattern: str) -> Iterator[Path]:
    """The paths ``pattern`` matches; ``**`` does not descend into symlinked folders.

    :func:`glob.glob` follows them, so a folder holding a link to itself or to its
    parent never finishes (issue 39); :meth:`pathlib.Path.glob` does not follow them
    (Python < 3.13; from 3.13 its default, ``recurse_symlinks=False``).
    """
    parts = Path(pattern).parts
    first = next(i for i, part in enumerate(parts) if _PATTERN_CHARACTERS & set(part))
    anchor = Path(*parts[:first]) if first else Path()
    rest = "/".join(parts[first:])
    if not anchor.is_dir():
        return iter(())
    return anchor.glob(rest)


def expand_runs(items: Sequence[str | Path]) -> list[Path]:
    """The recordings named by files, folders and glob patterns, in a fixed order.

    A folder stands for its recordings (files ending in one of
    :data:`pneufdd.recording.io.SUFFIXES`, not its sub-folders), a pattern
    (``"runs/*.parquet"``, ``"plant-*/**/*.tdms"``) for the files it matches; both
    are sorted by name. Files are kept as given (a missing file is reported when it
    is diagnosed). A recording named twice is diagnosed once.

    Raises
    ------
    InputError
        If nothing is given, or a folder or a pattern holds no recording.
    """
    if not items:
        raise InputError(describe("runs to diagnose", [], "at least one file, folder or pattern"))
    found: list[Path] = []
    for item in items:
        text = str(item)
        path = Path(item)
        if path.is_dir():
            matches = sorted(
                p for p in path.iterdir() if p.is_file() and p.suffix.lower() in SUFFIXES
            )
            what = f"recordings in folder {text!r}"
        elif _PATTERN_CHARACTERS & set(text) and not path.exists():
            matches = sorted(p for p in _glob(text) if p.is_file() and p.suffix.lower() in SUFFIXES)
            what = f"recordings matching {text!r}"
        else:
            found.append(path)
            continue
        if not matches:
            raise InputError(describe(what, "none", f"files ending in {', '.join(SUFFIXES)}"))
        found.extend(matches)
    seen: set[Path] = set()
    unique = []
    for path in found:
        key = path.absolute()
        if key not in seen:
            seen.add(key)
            unique.append(path)
    return unique


@dataclass(frozen=True)
class RunJob:
    """One run to diagnose (picklable: a worker process receives it)."""

    run: str
    reference: str
    settings: CostSettings | None = None
    localisation: LocalisationSettings | None = None
    threads: int = 1
    """Threads of the run's check by simulation (1 when runs share the cores)."""


_REFERENCES: dict[str, ReferenceModel] = {}


def _reference(path: str) -> ReferenceModel:
    """The reference at ``path``, read once per process."""
    if path not in _REFERENCES:
        _REFERENCES[path] = load_reference(path)
    return _REFERENCES[path]


def diagnose_one(job: RunJob) -> dict[str, Any]:
    """Diagnose one run; its ``--json`` record, or ``{"run", "reference", "error"}``."""
    base: dict[str, Any] = {"run": job.run, "reference": job.reference}
    try:
        model = _reference(job.reference)
        _, result = diagnose_recording(
            model, Path(job.run), job.settings, localisation=job.localisation, threads=job.threads
        )
    except PneufddError as exc:
        return {**base, "error": str(exc)}
    data = result.to_dict()
    data.update({**base, "machine": model.machine})
    return data


def diagnose_runs(
    runs: Sequence[str | Path],
    reference: str | Path,
    settings: CostSettings | None = None,
    localisation: LocalisationSettings | None = None,
    workers: int | None = 1,
    scheduler: str | None = None,
    threads: int | None = None,
) -> Iterator[dict[str, Any]]:
    """Diagnose every run against ``reference``; one record per run, in order.

    Parameters
    ----------
    runs : sequence of str or Path
        Recordings, folders of recordings or glob patterns (:func:`expand_runs`).
    reference : str or Path
        The ``.pnref`` reference file (read once per worker).
    settings : CostSettings, optional
        Costing (eq. 1.1).
    localisation : LocalisationSettings, optional
        Overrides the reference's localisation settings.
    workers : int, optional
        Processes of a local Dask cluster (None: one per CPU; 1: this process).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) instead; its workers
        must read the runs and the reference at the same paths.
    threads : int, optional
        Threads of each run's check by simulation (None: every core when the runs
        are diagnosed in this process, one per worker on a cluster).

    Yields
    ------
    dict
        The run's ``pneufdd diagnose --json`` record plus ``"run"``, ``"reference"``
        and ``"machine"``, or ``"run"``, ``"reference"`` and ``"error"`` (the
        message) when the run could not be diagnosed.
    """
    given = [str(path) for path in expand_runs(runs)]
    reference_path = str(Path(reference).absolute())  # workers may run in another folder
    _reference(reference_path)  # a bad reference fails at once, here
    size = None if workers is None else min(workers, len(given))
    # one run at a time in this process: its simulations may use every core
    if threads is None:
        threads = available_cores() if size == 1 and scheduler is None else 1
    threads = positive_count(threads, "threads")
    jobs = [
        RunJob(str(Path(run).absolute()), reference_path, settings, localisation, threads)
        for run in given
    ]
    with executor(size, scheduler) as pool:
        done: dict[int, dict[str, Any]] = {}
        next_index = 0
        for index, record in map_unordered(diagnose_one, jobs, pool):
            done[index] = {**record, "run": given[index], "reference": str(reference)}
            while next_index in done:
                yield done.pop(next_index)
                next_index += 1
