"""``pneufdd demo``: the most complete end-to-end job the package can run today."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def demo(
    out: Annotated[Path, typer.Option(help="Folder for the demo's outputs.")] = Path("build/demo"),
) -> None:
    """Run the built-in demonstration and write its outputs under OUT."""
    out.mkdir(parents=True, exist_ok=True)
    typer.echo("pneufdd demo: the foundation is in place; later issues extend this demo.")


def register(app: typer.Typer) -> None:
    """Attach the ``demo`` command to ``app``."""
    app.command("demo")(demo)
