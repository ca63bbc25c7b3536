"""``pneufdd evaluate CAMPAIGN_DIR`` (every method against the engine on a campaign's plants)
and ``pneufdd vector-map`` (Fig. 5.18, eq. 5.23 and the learned Table 4.5)."""

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
        bool, typer.Option("--overwrite", help="Replace an existing table in the output folder.")
    ] = False,
) -> None:
    """Cross-validate the dissertation's classifiers, the residual detector and the engine.

    Re-simulates the campaign's runs from its manifest (CAMPAIGN_DIR/labelled/*.parquet,
    kept for later calls), then writes evaluation.md, evaluation.csv (reproducible from
    the manifest), evaluation_times.csv (measured) and confusion-matrix figures.
    """
    from rich.console import Console

    from pneufdd.cli.outputs import check_outputs
    from pneufdd.cli.progress_bar import progress_bars
    from pneufdd.errors import InputError, describe
    from pneufdd.evaluation.compare import compare, confusion_figures
    from pneufdd.evaluation.labelled import labelled_frames, read_manifest, write_labelled
    from pneufdd.files import atomic_target, write_text_atomic

    console = Console()
    if not campaign_dir.is_dir():
        raise InputError(
            describe("CAMPAIGN_DIR", str(campaign_dir), "a campaign folder (pneufdd campaign)")
        )
    if workers > 1024:
        raise InputError(describe("--workers", workers, "1 to 1024"))
    folder = out or campaign_dir / "evaluation"
    if folder.exists() and not folder.is_dir():
        raise InputError(describe("--out", str(folder), "a folder (this is a file)"))
    table = folder / "evaluation.csv"
    names = ("evaluation.csv", "evaluation_times.csv", "evaluation.md")
    check_outputs({f"--out {n}": folder / n for n in names}, {}, overwrite=True)
    if table.exists() and not overwrite:
        raise InputError(
            describe(f"output {str(table)!r}", "exists", "a new folder or --overwrite")
        )
    read_manifest(campaign_dir)  # a damaged manifest is refused before any work
    with progress_bars() as progress:
        paths = write_labelled(campaign_dir, workers, progress)
    result = compare(campaign_dir, labelled_frames(paths), log=console.print)
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_target(table) as tmp:
        result.table.to_csv(tmp, index=False)
    with atomic_target(folder / "evaluation_times.csv") as tmp:
        result.times.to_csv(tmp, index=False)
    write_text_atomic(
        folder / "evaluation.md",
        "# Leak diagnosis methods compared on simulated plants\n" + result.markdown(),
    )
    figures = confusion_figures(result, folder)
    console.print(result.markdown(), highlight=False, markup=False)
    console.print(f"table: {table}; {len(figures)} confusion figures in {folder}", markup=False)


def vector_map(
    out: Annotated[Path, typer.Option(help="New folder for the figures and the numbers.")],
    machine: Annotated[str, typer.Option(help="Built-in machine name or TOML path.")] = "festo-dsd",
    actuator: Annotated[str, typer.Option(help="Actuator whose two lines leak.")] = "DNC",
    plant_scale: Annotated[
        float, typer.Option(min=0.0, max=5.0, help="Plant variation scale (0: the twin).")
    ] = 1.0,
    sizes: Annotated[str, typer.Option(help="Leak sizes, comma separated (turns).")] = "2,4,6",
    cycles: Annotated[int, typer.Option(min=2, help="Cycles per run.")] = 8,
    seed: Annotated[int, typer.Option(min=0, help="First seed (plant, then runs).")] = 96_200_000,
) -> None:
    """Combined extend + retract leaks as vector sums on a plant (Fig. 5.18, eq. 5.23).

    Also learns the sign table of the Table 4.4 features and sets it beside Table 4.5.
    """
    import math

    from rich.console import Console

    from pneufdd.cli.outputs import check_outputs
    from pneufdd.cli.simulate import MAX_CYCLES
    from pneufdd.errors import InputError, describe
    from pneufdd.evaluation.vector_sum import check_lines, vector_sum_check
    from pneufdd.features import TABLE_4_5
    from pneufdd.files import write_text_atomic
    from pneufdd.report.classifier_figures import sign_table_figure, vector_map_figure
    from pneufdd.report.figures import save_figure

    if out.exists() and not out.is_dir():
        raise InputError(describe("--out", str(out), "a folder (this is a file)"))
    if (out / "vector_sum.txt").exists():
        raise InputError(describe(f"output folder {str(out)!r}", "holds a result", "a new folder"))
    names = ("vector_map.png", "sign_table.png", "vector_sum.txt")
    check_outputs({f"--out {n}": out / n for n in names}, {"--machine": machine}, overwrite=True)
    if not math.isfinite(plant_scale):
        raise InputError(describe("--plant-scale", plant_scale, "a number from 0 to 5"))
    if cycles > MAX_CYCLES:
        raise InputError(describe("--cycles", cycles, f"2 to {MAX_CYCLES:,}"))
    chosen = tuple(s.strip() for s in sizes.split(",") if s.strip())
    if not chosen:
        raise InputError(describe("--sizes", sizes, "leak sizes, comma separated (e.g. 2,4,6)"))
    result = vector_sum_check(machine, actuator, plant_scale, chosen, cycles, seed)
    out.mkdir(parents=True, exist_ok=True)
    singles = [c for c in result.vmap.classes_ if c != "none"]
    vectors = {str(c): result.vmap.vector(c).tolist() for c in singles}
    title = f"{machine}, {actuator}, plant scale {plant_scale:g}, seed {seed}"
    save_figure(
        vector_map_figure(result.normalised, vectors, result.axes, title), out / "vector_map.png"
    )
    save_figure(sign_table_figure(result.learned_table, TABLE_4_5, title), out / "sign_table.png")
    lines = check_lines(result, TABLE_4_5)
    write_text_atomic(out / "vector_sum.txt", "\n".join(lines) + "\n")
    console = Console()
    for line in lines:
        console.print(line, highlight=False, markup=False)
    console.print(f"figures: {out / 'vector_map.png'}, {out / 'sign_table.png'}", markup=False)


def register(app: typer.Typer) -> None:
    """Attach the ``evaluate`` and ``vector-map`` commands to ``app``."""
    app.command("evaluate")(evaluate)
    app.command("vector-map")(vector_map)
