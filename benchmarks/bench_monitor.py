"""Live monitor: per-cycle processing cost against the cycle's own duration; memory flat.

A 20-cycle simulated festo-dsd recording (seed 96_300_000) is streamed in 1 s blocks
(as an MQTT batch or a replay would deliver them) over and over, its clock advancing,
through the whole monitor: sample assembly, incremental segmentation, per-cycle score,
CUSUM and a SQLite history (WAL), one transaction per cycle. ``PNEUFDD_BENCH_MONITOR_CYCLES``
cycles are streamed (default 1000; the acceptance figure uses 10000).

Figures:

- CPU time of 1000 cycles [s] (process time, so other load on the machine does not
  count) against the baseline **one cycle's duration** [s]: a ratio <= 1 means one core
  keeps up with 1000 machines in real time;
- resident memory [MB] after all cycles against the baseline after the first 10 %:
  ratio 1.00 is flat memory.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from common import BenchResult
from pneufdd.recording.model import Recording

SEED = 96_300_000


def _rss_mb() -> float:
    pages = int(Path("/proc/self/statm").read_text().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def _looped(rec: Recording, loops: int, chunk_s: float = 1.0) -> Iterator[object]:
    """The recording's 1 s blocks, over and over with the clock advancing.

    The blocks are cut once, so the stream costs the monitor's reading of it, not the
    slicing of the recording.
    """
    from pneufdd.monitor.samples import SampleBatch

    infos = [rec.info(c) for c in rec.channels]
    n_chunks = math.ceil(rec.duration / chunk_s)
    chunks: list[list[tuple[str, np.ndarray, float, float]]] = []
    for k in range(n_chunks):
        lo, hi = k * chunk_s, (k + 1) * chunk_s
        chunk = []
        for info in infos:
            a = math.ceil((lo - info.t0) * info.rate_hz - 1e-9)
            b = math.ceil((hi - info.t0) * info.rate_hz - 1e-9)
            if b > a:
                values = np.asarray(info.values[a:b], dtype=np.float64)
                chunk.append((info.name, values, info.t0 + a / info.rate_hz, info.rate_hz))
        chunks.append(chunk)
    t0 = datetime(2026, 1, 1, tzinfo=UTC).timestamp()
    for loop in range(loops):
        base = t0 + loop * rec.duration
        for chunk in chunks:
            for name, values, offset, rate in chunk:
                yield SampleBatch(name, values, t0=base + offset, rate_hz=rate)
            yield None


def run() -> list[BenchResult]:
    from pneufdd.diagnosis.recordings import build_reference_from_recordings
    from pneufdd.monitor.database import HistoryDatabase
    from pneufdd.monitor.live import MachineMonitor
    from pneufdd.monitor.stream import run_stream
    from pneufdd.sim import simulate

    total = int(os.environ.get("PNEUFDD_BENCH_MONITOR_CYCLES", "1000"))
    refs = [simulate("festo-dsd", cycles=10, seed=SEED + 1 + i) for i in range(2)]
    model = build_reference_from_recordings(refs, with_signatures=False)
    rec = simulate("festo-dsd", cycles=20, seed=SEED)
    # the idle tail of a simulated run is cut so that loops join like one long run
    starts = rec.metadata["cycle_start_s"]
    # on the 10 ms grid every channel shares, so that no channel skips a sample at the seam
    period = math.floor(starts[-1] * 100.0) / 100.0
    rec = Recording(
        [
            type(info)(
                info.name,
                info.values[: round(period * info.rate_hz)],
                info.rate_hz,
                info.unit,
                info.kind,
                info.t0,
            )
            for info in (rec.info(c) for c in rec.channels)
        ],
        start_time=rec.start_time,
    )
    per_loop = len(starts) - 1
    loops = math.ceil(total / per_loop)
    rss: list[tuple[int, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        db = HistoryDatabase(f"sqlite:///{Path(tmp) / 'bench.db'}")
        mon = MachineMonitor(model, db)
        rates = {c: rec.rate(c) for c in rec.channels}

        def seen(outcome: object) -> None:
            n = mon.stats.cycles
            if n % max(total // 20, 1) == 0:
                rss.append((n, _rss_mb()))
                cpu = time.process_time() - began
                print(
                    f"  {n} cycles: {rss[-1][1]:.1f} MB, {cpu / n * 1e3:.1f} ms CPU/cycle",
                    flush=True,
                )

        began = time.process_time()
        stats = run_stream(mon, _looped(rec, loops), rates, 0.0, on_cycle=seen, flush=False)
        elapsed = time.process_time() - began
        db.close()
    cycle_s = period / per_loop
    cost = elapsed / max(stats.cycles, 1)
    first = next(v for n, v in rss if n >= total // 10)
    return [
        BenchResult(
            f"monitor CPU time of 1000 machines' cycles ({stats.cycles} festo-dsd cycles)",
            1000.0 * cost,
            "s",
            "one cycle's duration (ratio <= 1: one core keeps up with 1000 machines)",
            cycle_s,
        ),
        BenchResult(
            f"monitor resident memory after {stats.cycles} cycles",
            rss[-1][1],
            "MB",
            f"after {total // 10} cycles",
            first,
        ),
    ]


if __name__ == "__main__":
    for result in run():
        print(result.line())
