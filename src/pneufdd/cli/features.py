"""``pneufdd features RUN.parquet... --out features.csv``: the feature matrix as CSV."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

import pandas as pd
import typer

from pneufdd.cli.recordings import MapOption, read_recordings
from pneufdd.errors import FileExistsInputError, describe
from pneufdd.features.context import Options
from pneufdd.features.matrix import GROUPS, feature_matrix
from pneufdd.recording.model import Recording

__all__ = ["features", "register", "write_features"]


def write_features(
    recordings: Sequence[Recording],
    out: Path,
    overwrite: bool = False,
    actuators: Sequence[str] = ("DNC",),
    groups: Sequence[str] = GROUPS,
    wavelet: str = "db4",
) -> pd.DataFrame:
    """Build the feature matrix of ``recordings`` and write it to ``out`` as CSV.

    Refuses to replace an existing file unless ``overwrite``; the file is written
    under a temporary name and renamed into place.
    """
    out = Path(out)
    if out.exists() and not overwrite:
        raise FileExistsInputError(
            describe(f"output file {str(out)!r}", "an existing file", "a new path, or --overwrite")
        )
    df = feature_matrix(
        recordings, actuators=actuators, groups=groups, options=Options(wavelet=wavelet)
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="") as handle:
            df.to_csv(handle)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return df


def features(
    runs: Annotated[
        list[Path], typer.Argument(help="Recordings (.parquet); the first is the reference.")
    ],
    out: Annotated[Path, typer.Option("--out", help="CSV file to write.")],
    overwrite: Annotated[bool, typer.Option(help="Replace OUT if it exists.")] = False,
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
    if out.exists() and not overwrite:
        raise FileExistsInputError(
            describe(f"output file {str(out)!r}", "an existing file", "a new path, or --overwrite")
        )
    recordings = read_recordings(runs, tag_map)
    df = write_features(
        recordings, out, overwrite, tuple(actuator or ("DNC",)), tuple(group or GROUPS), wavelet
    )
    typer.echo(f"wrote {df.shape[0]} cycles x {df.shape[1]} columns to {out}")


def register(app: typer.Typer) -> None:
    """Attach the ``features`` command to ``app``."""
    app.command("features")(features)
