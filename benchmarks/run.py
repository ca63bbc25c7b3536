"""``make bench``: every figure is printed as a ratio against a baseline run alongside.

Each benchmark module in this folder defines ``run() -> list[BenchResult]``.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from common import BenchResult


def main() -> int:
    here = Path(__file__).parent
    results: list[BenchResult] = []
    for info in sorted(pkgutil.iter_modules([str(here)]), key=lambda m: m.name):
        if not info.name.startswith("bench_"):
            continue
        module = importlib.import_module(info.name)
        print(f"== {info.name}", flush=True)
        for result in module.run():
            print(result.line(), flush=True)
            results.append(result)
    if not results:
        print("no benchmarks yet")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
