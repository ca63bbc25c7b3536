"""Dispatch :meth:`Recording.read` on the file suffix."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pneufdd.errors import FileFormatError, describe
from pneufdd.recording.model import Recording

__all__ = ["read_any"]


def read_any(path: Path, **options: Any) -> Recording:
    """Read ``path`` with the reader its suffix names."""
    raise FileFormatError(describe(f"file {str(path)!r}: reader", path.suffix, [".parquet"]))
