"""The twin's output buffers, kept between runs so that short runs start without page faults.

The compiled kernel (:func:`pneufdd.sim.kernel.run_cycle`) writes every sample of a
cycle into preallocated arrays (:class:`OutputBuffers`); :func:`pneufdd.sim.simulate`
takes them from :data:`POOL` and gives them back when a run is done. Nothing a run
returns refers to them, so results do not depend on this module.
"""

from __future__ import annotations

import threading

import numpy as np
import numpy.typing as npt

from pneufdd.sim import layout as lay

__all__ = ["POOL", "TRUTH_KEEP_BYTES", "BufferPool", "BufferShape", "OutputBuffers"]


class OutputBuffers:
    """Output buffers of the kernel, reused by every cycle of a run and by later runs
    (:class:`BufferPool`).

    The per-sample arrays are left uninitialised (``np.empty``): the kernel writes
    every column of every row it reports, and only those rows are read. Zeroing them
    (``np.zeros``) cost about 5 ms per run for the 120 s default (``max_cycle_s``):
    after the first run the C library serves these sizes from its heap, where calloc
    must clear the memory.
    """

    def __init__(self, n: int, nn: int, na: int, ns: int, nsw: int, nsteps: int) -> None:
        nc = 2 * na
        self.p = np.empty((n, nn))
        self.x = np.empty((n, na))
        self.vac = np.empty(n)
        self.fch = np.empty((n, nc))
        self.fexh = np.empty((n, nc))
        self.fleak = np.empty((n, nc))
        self.fr = np.empty((n, lay.FR_SIZE))
        self.cum = np.empty((n, lay.CM_SIZE))
        self.mass = np.empty(n)
        self.cmd = np.empty((n, ns), dtype=np.uint8)
        self.sw = np.empty((n, nsw), dtype=np.uint8)
        self.step = np.empty(n, dtype=np.int64)
        self.step_t = np.zeros(nsteps)
        n_ev = 8 * nsteps + 8 * na
        self.ev_act = np.zeros(n_ev, dtype=np.int64)
        self.ev_dir = np.zeros(n_ev, dtype=np.int64)
        self.ev_t0 = np.zeros((n_ev, 2))
        self.ev_t1 = np.zeros(n_ev)
        self.fpl = np.empty((n, na))
        self.truth = np.empty((0, 0))

    def truth_store(
        self, channels: int, written: int, samples: int, expected: int
    ) -> npt.NDArray[np.float64]:
        """Room for the true signals of ``channels`` sensors over ``samples`` samples.

        A run writes each cycle's samples after the ``written`` ones of the cycles
        before (one row per recorded sensor) and the sensor models read the rows at
        the end; what a run returns never refers to them. Kept with the buffers, the
        rows save the page faults of fresh memory: a festo-dsd run of four cycles
        freed and re-touched about 20 MB of NumPy arrays, about 5,000 page faults
        (measured, issue 13). When it must grow it makes room for the ``expected``
        samples of the whole run and keeps the ``written`` ones.
        """
        have = self.truth
        if have.shape[0] < channels or have.shape[1] < samples:
            grown = np.empty((max(channels, have.shape[0]), max(samples, expected)))
            grown[: have.shape[0], :written] = have[:, :written]
            self.truth = grown
        return self.truth


BufferShape = tuple[int, int, int, int, int, int]
"""``OutputBuffers`` arguments: samples, nodes, actuators, solenoids, switches, steps."""


class BufferPool:
    """Kernel buffers kept between runs (thread-safe; at most ``keep`` of them).

    A festo-dsd run's buffers hold about 16 MB: allocated anew for every run, the
    C library maps fresh pages, and touching them cost about 7 ms per run in page
    faults (measured, issue 13: one festo-dsd cycle 22.0-22.2 -> 16.1-16.4 ms, mean
    of 50 runs; four cycles 60.0-67.3 -> 58.6-61.9 ms, within the noise). A run
    takes a buffer of its shape out of the pool, or allocates one, and gives it back
    when done; nothing a run returns refers to its buffers (``_take`` copies), so
    results do not depend on it. Only buffers of the starting size are kept (those
    for ``max_cycle_s`` are 6 times larger); ``keep`` of 2 serves the two threads of
    a diagnosis.
    """

    def __init__(self, keep: int = 2) -> None:
        self._keep = keep
        self._lock = threading.Lock()
        self._free: list[tuple[BufferShape, OutputBuffers]] = []

    def take(self, shape: BufferShape) -> OutputBuffers:
        """A buffer of ``shape``: a kept one (events and step times cleared) or a new one."""
        with self._lock:
            for i, (kept, buf) in enumerate(self._free):
                if kept == shape:
                    del self._free[i]
                    buf.step_t[:] = 0.0
                    buf.ev_act[:] = 0
                    buf.ev_dir[:] = 0
                    buf.ev_t0[:] = 0.0
                    buf.ev_t1[:] = 0.0
                    return buf
        return OutputBuffers(*shape)

    def give(self, shape: BufferShape, buf: OutputBuffers) -> None:
        """Keep ``buf`` for a later run (the oldest kept buffer goes when full).

        True-signal rows above ``TRUTH_KEEP_BYTES`` (a long run's) are not kept.
        """
        if buf.truth.nbytes > TRUTH_KEEP_BYTES:
            buf.truth = np.empty((0, 0))
        with self._lock:
            self._free.append((shape, buf))
            del self._free[: -self._keep]


POOL = BufferPool()
TRUTH_KEEP_BYTES = 8 * 2**20
"""Largest true-signal store kept between runs [bytes]: the four-cycle runs of a
diagnosis's check with every festo-dsd sensor (about 5.3 MB), not a long run's."""
