"""``pneufdd evaluate CAMPAIGN_DIR``: every method against the engine on a campaign's plants."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def evaluate(
    campaign_dir: Annotated[
        Path, typer.Argument(help="A campaign folder written by `pneufdd campaign`.")
    ],
    out: Annotated[
        Path | None,
        typer.Option(help="Folder for the table and figures (default CAMPAIGN_DIR/evaluation)."),
    ] = None,
    workers: Annotated[
        int, typer.Option(min=1, help="Plants labelled in parallel (simulation).")
    ] = 1,
    overwrite: Annotated[
        bool, typer.Option(help="Replace an existing table in the output folder.")
    ] = False,
) -> None:
    """Cross-validate the dissertation's classifiers, the residual detector and the engine.

    Re-simulates the campaign's runs from its manifest (CAMPAIGN_DIR/labelled/*.parquet,
    kept for later calls), then writes evaluation.md, evaluation.csv (reproducible from
    the manifest), evaluation_times.csv (measured) and confusion-matrix figures.
    """
    from rich.console import Console

    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.errors import InputError, describe
    from pneufdd.evaluation.compare import compare, confusion_figures
    from pneufdd.evaluation.labelled import labelled_frames, write_labelled

    console = Console()
    folder = out or campaign_dir / "evaluation"
    table = folder / "evaluation.csv"
    if table.exists() and not overwrite:
        raise InputError(describe(f"output {str(table)!r}", "exists", "a new folder or --overwrite"))
    with progress_bars() as progress:
        paths = write_labelled(campaign_dir, workers, progress)
    result = compare(campaign_dir, labelled_frames(paths), log=console.print)
    folder.mkdir(parents=True, exist_ok=True)
    result.table.to_csv(table, index=False)
    result.times.to_csv(folder / "evaluation_times.csv", index=False)
    (folder / "evaluation.md").write_text(
        "# Leak diagnosis methods compared on simulated plants\n" + result.markdown(), "utf-8"
    )
    figures = confusion_figures(result, folder)
    console.print(result.markdown(), highlight=False, markup=False)
    console.print(f"table: {table}; {len(figures)} confusion figures in {folder}")


def register(app: typer.Typer) -> None:
    """Attach the ``evaluate`` command to ``app``."""
    app.command("evaluate")(evaluate)
