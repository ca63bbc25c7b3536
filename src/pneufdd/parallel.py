"""Where long work runs: in this process, or on a Dask cluster (``dask.distributed``).

Campaigns and batch diagnoses are many independent jobs (one simulated or recorded
run each). :func:`executor` opens a :class:`concurrent.futures.Executor` for them:

* ``workers=1`` and no scheduler: None, the caller runs the jobs itself, in order;
* no scheduler: a :class:`distributed.LocalCluster` of ``workers`` processes (default:
  one per CPU), one thread each (a job's Python work holds the GIL), closed on exit;
* ``scheduler="tcp://host:8786"``: an existing cluster (started with
  ``dask scheduler`` and ``dask worker`` on other machines); its workers need pneufdd
  installed, and files the jobs name must be readable there (jobs that carry their
  inputs in memory need nothing else).

Jobs are plain functions of picklable arguments; results are identical whichever way
they run (every job seeds its own random numbers). ``distributed`` is imported only
when a cluster is used. Inside one job, :func:`thread_map` runs independent
simulations on threads (the twin's compiled kernel releases the GIL).

Examples
--------
>>> with executor(workers=1) as pool:
...     sorted(map_unordered(abs, [-2, 1, -3], pool))
[(0, 2), (1, 1), (2, 3)]
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from pneufdd.errors import InputError, describe

if TYPE_CHECKING:
    from distributed import LocalCluster

__all__ = [
    "LOOPBACK",
    "available_cores",
    "executor",
    "local_cluster",
    "map_unordered",
    "positive_count",
    "resolve_threads",
    "resolve_workers",
    "thread_map",
]

T = TypeVar("T")
R = TypeVar("R")


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system reports it) [-].

    >>> available_cores() >= 1
    True
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # no affinity on this system (macOS, Windows)
        return max(1, os.cpu_count() or 1)


def thread_map(func: Callable[[T], R], items: Iterable[T], threads: int) -> list[R]:
    """``[func(item) for item in items]``, in order, on up to ``threads`` threads.

    For work that releases the GIL (the twin's compiled kernel); with one thread or
    one item it runs on the calling thread.

    >>> thread_map(abs, [-1, 2, -3], threads=2)
    [1, 2, 3]
    """
    jobs = list(items)
    if threads <= 1 or len(jobs) <= 1:
        return [func(job) for job in jobs]
    with ThreadPoolExecutor(min(threads, len(jobs))) as pool:
        return list(pool.map(func, jobs))


def positive_count(value: object, name: str) -> int:
    """``value`` if it is an integer >= 1 (not a bool), else :class:`InputError` naming ``name``.

    >>> positive_count(2, "threads")
    2
    """
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(describe(name, value, "an integer >= 1"))
    return value


def resolve_threads(threads: int | None) -> int:
    """Threads to use: ``threads``, or every core this process may use when None.

    >>> resolve_threads(None) == available_cores()
    True
    """
    return available_cores() if threads is None else positive_count(threads, "threads")


def resolve_workers(workers: int | None) -> int:
    """Worker processes to use: ``workers``, or one per CPU when None.

    >>> resolve_workers(3)
    3
    """
    if workers is None:
        return max(1, os.cpu_count() or 1)
    return positive_count(workers, "workers")


LOOPBACK = "127.0.0.1"
"""The only address a local cluster listens on (issue 39: never 0.0.0.0)."""


def local_cluster(workers: int) -> LocalCluster:
    """A Dask cluster on this machine that only this machine can reach.

    The scheduler, the workers, their nannies and every dashboard listen on the loopback
    interface (:data:`LOOPBACK`), each on a free port; nothing listens on 0.0.0.0, so no
    other host on the network can submit work or read the dashboards.

    Parameters
    ----------
    workers : int
        Worker processes, one thread each.

    Returns
    -------
    distributed.LocalCluster
        To be closed by the caller.
    """
    from distributed import LocalCluster

    return LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host=LOOPBACK,  # scheduler, workers and nannies
        dashboard_address=f"{LOOPBACK}:0",  # any free port: never collides with another
        worker_dashboard_address=f"{LOOPBACK}:0",
    )


@contextmanager
def executor(workers: int | None = None, scheduler: str | None = None) -> Iterator[Executor | None]:
    """An executor for independent jobs, or None to run them in this process.

    Parameters
    ----------
    workers : int, optional
        Worker processes of a local cluster (default: one per CPU); 1 without a
        scheduler runs the jobs here, one after another. Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``).

    Yields
    ------
    concurrent.futures.Executor or None
    """
    if scheduler is None and resolve_workers(workers) == 1:
        yield None
        return
    from distributed import Client

    cluster: LocalCluster | None = None
    if scheduler is None:
        cluster = local_cluster(resolve_workers(workers))
        client = Client(cluster)  # type: ignore[no-untyped-call]
    else:
        if not scheduler.strip():
            raise InputError(describe("--scheduler", scheduler, "an address tcp://host:port"))
        try:
            client = Client(scheduler, timeout="20s")  # type: ignore[no-untyped-call]
        except (OSError, TimeoutError) as exc:
            raise InputError(
                describe("--scheduler", scheduler, "the address of a running Dask scheduler")
                + f" ({exc})"
            ) from exc
    try:
        yield client.get_executor(pure=False)  # type: ignore[no-untyped-call]
    finally:
        client.close()  # type: ignore[no-untyped-call]
        if cluster is not None:
            cluster.close()


class _OneBlasThread(Generic[T, R]):
    """``function`` run with one BLAS thread, wherever it runs (picklable).

    A Dask nanny starts its worker processes with ``OPENBLAS_NUM_THREADS=1``; with more
    threads NumPy's matrix products sum in another order, and a campaign's leak sizes
    and confidences differed from a cluster's in the last bit (measured on 142 of 1,266
    records of one campaign; docs/scale-out.md).
    """

    def __init__(self, function: Callable[[T], R]) -> None:
        self.function = function

    def __call__(self, item: T) -> R:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return self.function(item)


def map_unordered(
    function: Callable[[T], R],
    items: Iterable[T],
    pool: Executor | None,
) -> Iterator[tuple[int, R]]:
    """``(index, function(item))`` for every item, as each finishes.

    Without a pool the items run here in order. An exception of a job is raised
    here, as soon as that job finishes. Every job runs with one BLAS thread (as on a
    Dask worker), so its result is the same bit for bit whichever way it runs.
    """
    function = _OneBlasThread(function)
    jobs: Sequence[T] = list(items)
    if pool is None:
        for i, item in enumerate(jobs):
            yield i, function(item)
        return
    futures: dict[Future[Any], int] = {
        pool.submit(function, item): i for i, item in enumerate(jobs)
    }
    try:
        for future in as_completed(futures):
            yield futures[future], future.result()
    finally:
        for future in futures:
            future.cancel()
