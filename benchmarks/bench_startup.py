"""Start-up of the ``pneufdd`` command as whole processes (issue 13, item 1).

``pneufdd --help`` and ``pneufdd machines`` (target: <= 0.3 s each) and ``import
pneufdd``, each the median wall time of 5 fresh processes, against the same
interpreter doing nothing (``python -c pass``) and importing numpy, measured in the
same run.
"""

from __future__ import annotations

import resource
import statistics
import subprocess
import sys
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
    return out


if __name__ == "__main__":
    for result in run():
        print(result.line())
