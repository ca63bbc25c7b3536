"""Reading recordings on the command line: ``--map`` (a tag map) wherever one is read."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from pneufdd.recording.model import Recording

__all__ = ["MapOption", "read_recording", "read_recordings"]

MapOption = Annotated[
    Path | None,
    typer.Option(
        "--map",
        help="Tag map (.toml) naming each column/channel's role, unit and flow basis, for "
        "a CSV, TDMS or Parquet export under the PLC's own tag names (docs/recording.md).",
    ),
]


def read_recordings(paths: Sequence[Path], tag_map: Path | None) -> list[Recording]:
    """Read ``paths`` as pneufdd recordings, through the tag map when one is given."""
    from pneufdd.recording.model import Recording

    if tag_map is None:
        return [Recording.read(p) for p in paths]
    from pneufdd.recording.tag_map import load_tag_map, read_mapped

    parsed = load_tag_map(tag_map)
    return [read_mapped(p, parsed) for p in paths]


def read_recording(path: Path, tag_map: Path | None) -> Recording:
    """One recording (see :func:`read_recordings`)."""
    return read_recordings([path], tag_map)[0]
