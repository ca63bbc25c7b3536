"""``pneufdd build-twin``: compile the twin ahead of time, so short commands start at once."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def build_twin(
    directory: Annotated[
        Path | None,
        typer.Option(
            "--dir",
            help="Where to keep it (default: $PNEUFDD_PREBUILT_DIR, else "
            "~/.cache/pneufdd/prebuilt).",
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Compile even if it is up to date.")
    ] = False,
) -> None:
    """Compile the twin's kernels ahead of time (about 15 s; needs gcc and Python.h).

    Every later process uses the prebuilt module instead of numba's JIT, with the same
    results bit for bit, and a four-cycle `pneufdd simulate` starts without loading
    numba. After pneufdd's sources, Python, NumPy or numba change, the module is
    ignored until this command runs again. Details: docs/twin.md.
    """
    from rich.console import Console

    from pneufdd.sim.prebuilt import build_prebuilt_twin, load_prebuilt_twin, prebuilt_path

    console = Console()
    target = prebuilt_path(directory)
    if not force and load_prebuilt_twin(directory) is not None:
        console.print(f"up to date: {target}", highlight=False, markup=False, soft_wrap=True)
        return
    start = time.perf_counter()
    with console.status("compiling the twin ahead of time (about 15 s)"):
        path = build_prebuilt_twin(directory, force=True)
    console.print(
        f"built {path} in {time.perf_counter() - start:.1f} s",
        highlight=False,
        markup=False,
        soft_wrap=True,
    )


def register(app: typer.Typer) -> None:
    """Add ``build-twin`` to ``app``."""
    app.command("build-twin")(build_twin)
