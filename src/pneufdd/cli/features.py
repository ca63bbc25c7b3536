"""``pneufdd features RUN.parquet... --out features.csv``: the feature matrix as CSV."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd.cli.outputs import check_outputs
from pneufdd.cli.recordings import MapOption, read_recordings
from pneufdd.errors import FileExistsInputError, InputError, NoCompleteCycleError, describe
from pneufdd.files import atomic_target

if TYPE_CHECKING:
    import pandas as pd

    from pneufdd.recording.model import Recording

GROUPS = ("motion", "air", "table44", "wavelet")
"""Feature groups (:data:`pneufdd.features.matrix.GROUPS`, repeated here so the CLI's
help does not import the feature code; a test keeps the two equal)."""

__all__ = ["features", "register", "write_features"]


def write_features(
    recordings: Sequence[Recording],
    out: Path,
    overwrite: bool = False,
    actuators: Sequence[str] = ("DNC",),
    groups: Sequence[str] = GROUPS,
    wavelet: str = "db4",
    where: str = "the recordings",
    names: Sequence[str] | None = None,
) -> pd.DataFrame:
    """Build the feature matrix of ``recordings`` and write it to ``out`` as CSV.

    Refuses to replace an existing file unless ``overwrite``; the file is written
    under a temporary name and renamed into place. A matrix without a single
    complete cycle is refused (:class:`~pneufdd.errors.NoCompleteCycleError`, as the
    other commands do) rather than written empty.
    """
    from pneufdd.features.context import Options
    from pneufdd.features.matrix import feature_matrix

    out = Path(out)
    if out.exists() and not overwrite:
        raise FileExistsInputError(
            describe(f"output file {str(out)!r}", "an existing file", "a new path, or --overwrite")
        )
    df = feature_matrix(
        recordings,
        actuators=actuators,
        groups=groups,
        options=Options(wavelet=wavelet),
        names=names,
    )
    if df.shape[0] == 0:
        raise NoCompleteCycleError(
            describe(f"complete machine cycles in {where}", 0, "at least one")
        )
    with atomic_target(out) as tmp, open(tmp, "w", newline="") as handle:
        df.to_csv(handle)
    return df


def features(
    runs: Annotated[
        list[Path], typer.Argument(help="Recordings (.parquet); the first is the reference.")
    ],
    out: Annotated[Path, typer.Option("--out", help="CSV file to write.")],
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace OUT if it exists.")
    ] = False,
    actuator: Annotated[
        list[str] | None, typer.Option(help="Actuator(s) for per-actuator features.")
    ] = None,
    group: Annotated[
        list[str] | None, typer.Option(help=f"Feature group(s): {', '.join(GROUPS)}.")
    ] = None,
    wavelet: Annotated[str, typer.Option(help="Mother wavelet of the DWT features.")] = "db4",
    tag_map: MapOption = None,
) -> None:
    """Write the (cycles x features) matrix of RUNS, with leak labels, to OUT."""
    inputs: dict[str, Path | None] = {f"RUNS[{i}]": r for i, r in enumerate(runs)}
    inputs["--map"] = tag_map
    check_outputs({"--out": out}, inputs, overwrite)
    for name in actuator or ():  # a name is printed and becomes column names
        if not name.strip() or not name.isprintable():
            raise InputError(describe("--actuator", name, "an actuator's name, e.g. PRESS"))
    unknown = [g for g in group or () if g not in GROUPS]
    if unknown:
        raise InputError(describe("--group", unknown, GROUPS))
    recordings = read_recordings(runs, tag_map)
    df = write_features(
        recordings,
        out,
        overwrite,
        tuple(actuator or ("DNC",)),
        tuple(group or GROUPS),
        wavelet,
        where=", ".join(repr(str(r)) for r in runs),
        names=[str(r) for r in runs],
    )
    typer.echo(f"wrote {df.shape[0]} cycles x {df.shape[1]} columns to {out}")


def register(app: typer.Typer) -> None:
    """Attach the ``features`` command to ``app``."""
    app.command("features")(features)
