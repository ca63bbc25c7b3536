"""Locating and sizing beside the ingestion: the engine runs in a worker thread.

When the CUSUM declares a leak, or a re-estimate falls due, the monitor records the
cycle (with the declaration's alarm) and an :class:`EstimateJob`: the step summaries
of the cycles the estimate is made from, and what the result needs to be stored as
if it had been computed in that cycle. The job's input goes into the history
(``pending_estimates``, in the cycle's transaction), the engine
(:func:`pneufdd.diagnosis.engine.diagnose`) runs in an :class:`EstimateWorker`, and
the result is stored in a transaction of its own, which also removes the input. A
monitor killed before that transaction finds the input at its next start and runs
the estimate again.

Why a thread and not a process: the engine's heavy part, the check by simulation,
runs the twin's compiled kernel, which releases the GIL; the rest is numpy. Measured
with a diagnosis running without pause beside the monitor's ingestion (segmentation
and scores of a replay at full speed, ``benchmarks/monitor_acceptance.py offpath``),
the ingestion took about as long as beside the same diagnosis in a separate process
(``docs/monitor.md``, section Locating and sizing off the ingest path); a process
would need the reference pickled across and the twin compiled again in it.

``mode="inline"`` runs the engine on the caller's thread when the result is needed
(:meth:`MachineMonitor.settle <pneufdd.monitor.live.MachineMonitor.settle>`): the
same transactions in a fixed order, for tests that interrupt them.
"""

from __future__ import annotations

import contextlib
import io
import json
import multiprocessing
import os
import threading
import time
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from pneufdd.diagnosis.cost import CostSettings
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError, describe
from pneufdd.features.step_table import StepTable
from pneufdd.parallel import available_cores

__all__ = ["MODES", "EstimateJob", "EstimateWorker", "Timed", "decode_job", "encode_job"]

MODES = ("process", "thread", "inline")
"""Where the engine runs: a worker process or thread beside the ingestion, or the
caller's thread."""


@dataclass(frozen=True)
class EstimateJob:
    """A location and sizing run decided with a committed cycle.

    Attributes
    ----------
    time : float
        Start of the cycle that decided it [s since 1970-01-01 UTC]; the diagnosis,
        sizes and alarm are stored at this time.
    duration_s : float
        That cycle's duration [s]: its cost accrues once its leaks are sized.
    declared : bool
        A declaration (its alarm row is ``alarm_id``) or a re-estimate.
    first_cycle : float
        Start of the first cycle of the estimate's window [s since 1970-01-01 UTC].
    table : StepTable
        The step summaries of the window's cycles.
    change_start : float or None
        The CUSUM's change point when it was decided [s since 1970-01-01 UTC].
    alarm_id : int or None
        The declaration's alarm row (None for a re-estimate).
    pending_id : int
        Its row in ``pending_estimates`` (0 before it is stored).
    """

    time: float
    duration_s: float
    declared: bool
    first_cycle: float
    table: StepTable
    change_start: float | None
    alarm_id: int | None = None
    pending_id: int = 0

    @property
    def n_cycles(self) -> int:
        """Cycles in the window [-]."""
        return self.table.n_cycles


_ARRAYS = ("step_start", "step_end", "summaries", "traces", "trace_offsets", "cycle_index")


def encode_job(job: EstimateJob) -> bytes:
    """The job as NPZ bytes (a JSON header and the step table's arrays; no pickle).

    Examples
    --------
    >>> table = StepTable("m", np.zeros((1, 2)), np.ones((1, 2)), (), (), np.zeros((1, 2, 0, 3)))
    >>> job = EstimateJob(10.0, 14.7, True, 10.0, table, 9.5, alarm_id=3)
    >>> back = decode_job(encode_job(job))
    >>> (back.time, back.declared, back.alarm_id, back.table.step_end.tolist())
    (10.0, True, 3, [[1.0, 1.0]])
    """
    table = job.table
    header = {
        "time": job.time,
        "duration_s": job.duration_s,
        "declared": job.declared,
        "first_cycle": job.first_cycle,
        "change_start": job.change_start,
        "alarm_id": job.alarm_id,
        "machine": table.machine,
        "channels": list(table.channels),
        "units": list(table.units),
        "trace_rate_hz": table.trace_rate_hz,
    }
    arrays = {name: getattr(table, name) for name in _ARRAYS if getattr(table, name) is not None}
    buffer = io.BytesIO()
    np.savez(buffer, header=np.array(json.dumps(header, allow_nan=False)), **arrays)
    return buffer.getvalue()


def decode_job(data: bytes) -> EstimateJob:
    """Inverse of :func:`encode_job`.

    Raises
    ------
    InputError
        If the bytes are not a job this version wrote.
    """
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            header: dict[str, Any] = json.loads(str(npz["header"][()]))
            arrays = {name: npz[name] for name in _ARRAYS if name in npz.files}
        table = StepTable(
            machine=str(header["machine"]),
            step_start=arrays["step_start"],
            step_end=arrays["step_end"],
            channels=tuple(header["channels"]),
            units=tuple(header["units"]),
            summaries=arrays["summaries"],
            traces=arrays.get("traces"),
            trace_offsets=arrays.get("trace_offsets"),
            trace_rate_hz=float(header["trace_rate_hz"]),
            cycle_index=arrays["cycle_index"],
        )
        change = header["change_start"]
        alarm_id = header["alarm_id"]
        return EstimateJob(
            float(header["time"]),
            float(header["duration_s"]),
            bool(header["declared"]),
            float(header["first_cycle"]),
            table,
            None if change is None else float(change),
            None if alarm_id is None else int(alarm_id),
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(
            describe("a pending estimate in the history", type(exc).__name__, "one pneufdd wrote")
        ) from exc


class EstimateWorker:
    """Runs location and sizing jobs one at a time, beside the caller (``process``:
    in a worker process started on first use, the reference sent once; ``thread``: in
    a worker thread) or on the caller's thread when asked for the result (``inline``).

    Parameters
    ----------
    model : ReferenceModel
        The machine's reference.
    cost : CostSettings
        Economic inputs of eq. 1.1.
    mode : str
        One of :data:`MODES`.
    """

    def __init__(self, model: ReferenceModel, cost: CostSettings, mode: str = "thread") -> None:
        if mode not in MODES:
            raise InputError(describe("estimate worker mode", mode, list(MODES)))
        self.model = model
        self.cost = cost
        self.mode = mode
        self.spans: list[tuple[float, float]] = []
        """Wall-clock start and end of every job run so far [s since 1970-01-01 UTC]."""
        self._pool: Executor | None = None

    @property
    def concurrent(self) -> bool:
        """Whether jobs run beside the caller (the caller need not wait for them)."""
        return self.mode != "inline"

    def start(self, job: EstimateJob) -> Future[Timed] | None:
        """Start ``job`` beside the caller; None in ``inline`` mode (run by :meth:`result`)."""
        if self.mode == "inline":
            return None
        if self._pool is None:  # made on first use: a monitor that never estimates has none
            if self.mode == "process":
                self._pool = ProcessPoolExecutor(
                    1,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_keep,
                    initargs=(self.model, self.cost, os.getpid()),
                )
            else:
                self._pool = ThreadPoolExecutor(1, thread_name_prefix="pneufdd-estimate")
        if self.mode == "process":
            return self._pool.submit(_run_kept, job.table)
        return self._pool.submit(_run, self.model, job.table, self.cost)

    def result(self, job: EstimateJob, future: Future[Timed] | None) -> Diagnosis:
        """The job's result, waiting for it (``future`` None: run it now)."""
        timed = _run(self.model, job.table, self.cost) if future is None else future.result()
        self.spans.append((timed.began, timed.ended))
        return timed.result

    def abandon(self) -> None:
        """Stop without the running job's result (its input stays in the history: the
        next start runs it again). A worker process is ended; a thread cannot be, and the
        interpreter waits for it at exit."""
        if self._pool is None:
            return
        if self.mode == "process":
            for child in multiprocessing.active_children():
                child.terminate()
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = None

    def close(self) -> None:
        """Wait for a running job and release the thread or process."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None


class Timed(NamedTuple):
    """A job's result and when it ran [s since 1970-01-01 UTC]."""

    result: Diagnosis
    began: float
    ended: float


def _run(model: ReferenceModel, table: StepTable, cost: CostSettings) -> Timed:
    began = time.time()
    # the check by simulation leaves a core to the ingestion
    result = diagnose(model, table, cost, threads=max(1, available_cores() - 1))
    return Timed(result, began, time.time())


_KEPT: tuple[ReferenceModel, CostSettings] | None = None
"""The reference and cost settings a worker process was started with."""


def _keep(model: ReferenceModel, cost: CostSettings, monitor_pid: int) -> None:
    """The worker process's start: keep the reference, lower the priority, and end
    when the monitor (process ``monitor_pid``) is gone (killed: nothing else would end
    this process; killed while this one was still starting, it is gone already)."""
    global _KEPT
    if os.getppid() != monitor_pid:
        os._exit(0)
    _KEPT = (model, cost)
    with contextlib.suppress(OSError):  # not permitted: it runs at the monitor's priority
        os.nice(NICENESS)

    def orphaned() -> None:
        while os.getppid() == monitor_pid:
            time.sleep(1.0)
        os._exit(0)

    threading.Thread(target=orphaned, daemon=True, name="pneufdd-parent-watch").start()


NICENESS = 10
"""How much lower the worker process's scheduling priority is than the monitor's
(``nice``): on a busy machine the ingestion comes first."""


def _run_kept(table: StepTable) -> Timed:
    assert _KEPT is not None
    return _run(_KEPT[0], table, _KEPT[1])
