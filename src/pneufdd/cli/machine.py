"""``pneufdd machine ...``: work with machine descriptions (``vary``: a plant from a twin)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from pneufdd import __version__
from pneufdd.cli.outputs import check_outputs
from pneufdd.errors import InputError, describe

__all__ = ["register"]

machine_app = typer.Typer(
    help="Work with machine descriptions: draw plants that differ from their twin.",
    no_args_is_help=True,
)


@machine_app.command("vary")
def vary(
    description: Annotated[
        str,
        typer.Argument(help="Built-in machine name (see `pneufdd machines`) or a TOML path."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Plant description to write (.toml).")],
    scale: Annotated[
        float,
        typer.Option(
            help="Spread relative to the documented tolerances: 0 = the description, "
            "1 = a plausible real machine, 2 = a badly documented one (at most 5)."
        ),
    ] = 1.0,
    seed: Annotated[int, typer.Option(min=0, help="Random seed (same seed, same plant).")] = 0,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing OUT.")] = False,
) -> None:
    """Draw a plant from DESCRIPTION (every physical parameter around its value) to OUT.

    Spreads and their sources: docs/plant-variation.md.
    """
    from pneufdd.sim import load_machine
    from pneufdd.sim.variation import MAX_SCALE, parameter_changes, vary_machine, write_machine

    if not 0.0 <= scale <= MAX_SCALE:  # also refuses nan
        raise InputError(
            describe("--scale", scale, f"a number from 0 to {MAX_SCALE:g} (1: a real machine)")
        )
    check_outputs({"--out": out}, {"DESCRIPTION": description}, overwrite)
    twin = load_machine(description)
    plant = vary_machine(twin, scale=scale, seed=seed)
    origin = twin.name if twin.source == twin.name else f"{twin.name} ({twin.source})"
    header = (
        f"plant varied from {origin} at scale {scale:g}, seed {seed} by pneufdd "
        f"{__version__}\nspreads: docs/plant-variation.md"
    )
    path = write_machine(plant, out, header=header, overwrite=overwrite)
    changes = parameter_changes(twin, plant)
    largest = ", ".join(str(c) for c in changes[:3]) or "none"
    Console(stderr=True).print(
        f"wrote {path}: plant of {twin.name} at scale {scale:g}, seed {seed}, "
        f"{len(changes)} parameters changed; largest: {largest}",
        highlight=False,
        markup=False,
        soft_wrap=True,
    )


def register(app: typer.Typer) -> None:
    """Attach the ``machine`` command group to ``app``."""
    app.add_typer(machine_app, name="machine")
