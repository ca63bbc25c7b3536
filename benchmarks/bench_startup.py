"""Start-up of the ``pneufdd`` command as whole processes (issue 13, item 1).

``pneufdd --help`` and ``pneufdd machines`` (target: <= 0.3 s each) and ``import
pneufdd``, each the median wall time of 5 fresh processes, against the same
interpreter doing nothing (``python -c pass``) and importing numpy, measured in the
same run; and ``pneufdd simulate --machine festo-dsd --cycles 4`` as a whole
process (target: >= 100 x real time), against the libraries it cannot do without
(numba with one cached compiled function, and pyarrow's Parquet writer; since stop 25
a simulation builds its Arrow arrays from NumPy buffers and no longer imports pandas).
"""

from __future__ import annotations

import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import BenchResult

PYTHON = sys.executable
PNEUFDD = str(Path(PYTHON).with_name("pneufdd"))
REPEAT = 5


def median_times(argv: list[str], repeat: int = REPEAT) -> tuple[float, float]:
    """Median wall and CPU (user + system) time of ``repeat`` fresh processes [s].

    CPU time is what a process costs on a shared machine whatever its load.
    """
    walls, cpus = [], []
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run(argv, check=True, capture_output=True)
        walls.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


_FLOOR = (
    "import numpy, pyarrow.parquet\n"
    "from pneufdd.sim.sensors import first_order_recursion\n"
    "first_order_recursion(numpy.ones(3), 1.0, 0.5)\n"
)


def simulate_process() -> list[BenchResult]:
    """``pneufdd simulate --cycles 4`` as whole processes: wall time and real-time factor."""
    from pneufdd.recording import read_parquet

    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "run.parquet"
        argv = [PNEUFDD, "simulate", "--machine", "festo-dsd", "--cycles", "4"]
        argv += ["--out", str(out), "--overwrite"]
        subprocess.run(argv, check=True, capture_output=True)  # warm numba's cache
        wall, cpu = median_times(argv)
        recording = read_parquet(out)
        simulated = recording.duration
        floor_wall, floor_cpu = median_times([PYTHON, "-c", _FLOOR], repeat=REPEAT)
    name = "pneufdd simulate --cycles 4"
    libraries = "python: import numba, pyarrow.parquet; one call of a cached numba function"
    return [
        BenchResult(f"{name} (wall)", wall, "s", libraries, floor_wall),
        BenchResult(f"{name} (cpu)", cpu, "s", libraries, floor_cpu),
        BenchResult(
            f"{name}: simulated time (ratio = x real time)", simulated, "s", "its wall time", wall
        ),
    ]


def run() -> list[BenchResult]:
    base_wall, _ = median_times([PYTHON, "-c", "pass"])
    numpy_wall, numpy_cpu = median_times([PYTHON, "-c", "import numpy"])
    out = []
    for name, argv in (
        ("pneufdd --help", [PNEUFDD, "--help"]),
        ("pneufdd machines", [PNEUFDD, "machines"]),
        ("python -c 'import pneufdd'", [PYTHON, "-c", "import pneufdd"]),
    ):
        wall, cpu = median_times(argv)
        out.append(BenchResult(f"{name} (wall)", wall, "s", "python -c pass", base_wall))
        out.append(BenchResult(f"{name} (wall)", wall, "s", "python -c 'import numpy'", numpy_wall))
        out.append(BenchResult(f"{name} (cpu)", cpu, "s", "python -c 'import numpy'", numpy_cpu))
    return out + simulate_process()


if __name__ == "__main__":
    for result in run():
        print(result.line())
