"""pneufdd's own Parquet format for a :class:`Recording`."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pneufdd.recording.model import Recording

__all__ = ["write_parquet"]


def write_parquet(recording: Recording, path: Path, overwrite: bool = False) -> Path:
    """Write ``recording`` to ``path``."""
    raise NotImplementedError
