"""Segmentation + feature extraction throughput for 100 cycles, against reading Parquet.

Data: 100 simulated ``festo-dsd`` cycles when :mod:`pneufdd.sim` exists, otherwise
the synthetic 58-step recording of ``tests/synth.py``. The baseline is the time to
read the same recording back from Parquet (``Recording.read`` when the Parquet I/O
exists; otherwise the channel arrays written with pyarrow, one table per rate).
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from common import BenchResult, best_time
from pneufdd import Recording
from pneufdd.features import feature_matrix
from pneufdd.signals import segment

CYCLES = 100


def _recording() -> tuple[Recording, str]:
    try:
        from pneufdd.sim import simulate
    except ImportError:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
        from synth import make_recording

        rec, _ = make_recording(cycles=CYCLES, seed=1)
        return rec, "synthetic"
    return simulate(machine="festo-dsd", cycles=CYCLES, seed=1), "simulated festo-dsd"


def _parquet_reader(rec: Recording, folder: Path) -> tuple[Callable[[], object], str]:
    path = folder / "run.parquet"
    try:
        rec.write(path)
        Recording.read(path)
    except (NotImplementedError, ValueError):
        pass
    else:
        return (lambda: Recording.read(path)), "Recording.read"
    for kind, names in (("analog", rec.analog_channels), ("digital", rec.digital_channels)):
        table = pa.table({n: np.asarray(rec.channel(n)[1]) for n in names})
        pq.write_table(table, folder / f"{kind}.parquet")

    def read() -> object:
        analog = pq.read_table(folder / "analog.parquet")
        digital = pq.read_table(folder / "digital.parquet")
        return Recording.from_arrays(
            {n: analog[n].to_numpy() for n in analog.column_names},
            rec.rate(rec.analog_channels[0]),
            {n: digital[n].to_numpy() for n in digital.column_names},
            rec.rate(rec.digital_channels[0]),
            units={n: rec.unit(n) for n in analog.column_names},
        )

    return read, "pyarrow read of the channel arrays"


def run() -> list[BenchResult]:
    rec, source = _recording()
    n = len(segment(rec).complete)
    with tempfile.TemporaryDirectory() as tmp:
        read, how = _parquet_reader(rec, Path(tmp))
        t_read = best_time(read)
    t_seg = best_time(lambda: segment(rec))
    t_all = best_time(lambda: feature_matrix(rec), repeat=2)
    base = f"{how} ({source}, {n} cycles)"
    return [
        BenchResult("segmentation", n / t_seg, "cycles/s", base, n / t_read),
        BenchResult("segmentation + features", n / t_all, "cycles/s", base, n / t_read),
    ]
