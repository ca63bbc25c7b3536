"""Start-up of the ``pneufdd`` command as whole processes (issue 13, item 1).

``pneufdd --help`` and ``pneufdd machines`` (target: <= 0.3 s each) and ``import
pneufdd``, each the median wall time of 5 fresh processes, against the same
interpreter doing nothing (``python -c pass``) and importing numpy, measured in the
same run; and ``pneufdd simulate --machine festo-dsd --cycles 4`` as a whole
process (target: >= 100 x real time), against the libraries it cannot do without
(numpy, pyarrow's Parquet writer and one call of the twin's compiled code; since stop
25 a simulation builds its Arrow arrays from NumPy buffers and no longer imports
pandas).

The command runs twice over: with the twin compiled ahead of time (``make bench``
runs ``pneufdd build-twin`` first; :mod:`pneufdd.sim.prebuilt`), which is what the
target is about, and with numba's JIT (``PNEUFDD_PREBUILT=0``), whose process imports
numba and loads the kernels from numba's cache (about 0.6 s more). A third line
simulates with a leak: its size becomes an area through the compiled leak law
(``physics/leaks.py``), which loads numba in any case.
"""

from __future__ import annotations

import os
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


def median_times(
    argv: list[str], repeat: int = REPEAT, env: dict[str, str] | None = None
) -> tuple[float, float]:
    """Median wall and CPU (user + system) time of ``repeat`` fresh processes [s].

    CPU time is what a process costs on a shared machine whatever its load.
    """
    walls, cpus = [], []
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run(argv, check=True, capture_output=True, env=env)
        walls.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


_FLOOR = (
    "import numpy, pyarrow.parquet\n"
    "from pneufdd.sim.sensors import first_order_recursion\n"
    "first_order_recursion(numpy.ones(3), 1.0, 0.5)\n"
)


def simulate_process(prebuilt: bool, leak: str | None = None) -> list[BenchResult]:
    """``pneufdd simulate --cycles 4`` as whole processes: wall time and real-time factor.

    Parameters
    ----------
    prebuilt : bool
        Use the prebuilt twin if one is current (else ``PNEUFDD_PREBUILT=0``: the JIT).
    leak : str, optional
        A ``--leak`` option (its size is turned into an area by the compiled leak law,
        which loads numba even with the prebuilt twin).
    """
    from pneufdd.recording import read_parquet

    env = dict(os.environ, PNEUFDD_PREBUILT="1" if prebuilt else "0")
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "run.parquet"
        argv = [PNEUFDD, "simulate", "--machine", "festo-dsd", "--cycles", "4"]
        argv += ["--out", str(out), "--overwrite"] + (["--leak", leak] if leak else [])
        subprocess.run(argv, check=True, capture_output=True, env=env)  # warm the caches
        wall, cpu = median_times(argv, env=env)
        recording = read_parquet(out)
        simulated = recording.duration
        floor_wall, floor_cpu = median_times([PYTHON, "-c", _FLOOR], repeat=REPEAT, env=env)
    name = "pneufdd simulate --cycles 4" + (f" --leak {leak}" if leak else "")
    name += "" if prebuilt else " on numba's JIT"
    libraries = "python: import numpy, pyarrow.parquet; one call of the twin's compiled code"
    results = [BenchResult(f"{name} (wall)", wall, "s", libraries, floor_wall)]
    if leak is None:
        results.append(BenchResult(f"{name} (cpu)", cpu, "s", libraries, floor_cpu))
    results.append(
        BenchResult(
            f"{name}: simulated time (ratio = x real time)", simulated, "s", "its wall time", wall
        )
    )
    return results


def twin_origin() -> str:
    """Which compiled twin a fresh process of this environment uses ("jit" or a path)."""
    code = "from pneufdd.sim.prebuilt import compiled_twin; print(compiled_twin().origin)"
    done = subprocess.run([PYTHON, "-c", code], check=True, capture_output=True, text=True)
    return done.stdout.strip()


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
    origin = twin_origin()
    print(f"the twin of these processes: {origin}", flush=True)
    if origin == "jit":
        print("no prebuilt twin (run `pneufdd build-twin`): both lines use the JIT", flush=True)
    out += simulate_process(prebuilt=True) + simulate_process(prebuilt=False)
    return out + simulate_process(prebuilt=True, leak="DNC_B=3")


if __name__ == "__main__":
    for result in run():
        print(result.line())
