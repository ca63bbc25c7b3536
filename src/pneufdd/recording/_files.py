"""File checks shared by the recording readers and the writer.

Every message names the file, so a user with many recordings knows which one is bad.
"""

from __future__ import annotations

from pathlib import Path

from pneufdd.errors import FileExistsInputError, FileFormatError, MissingFileError

__all__ = ["FileExistsInputError", "MissingFileError", "check_input_file", "file_label"]


def file_label(path: Path) -> str:
    """Return ``"file '<path>'"`` for error messages."""
    return f"file {str(path)!r}"


def check_input_file(path: Path, what: str) -> Path:
    """Return ``path`` if it is an existing, non-empty regular file.

    Parameters
    ----------
    path : Path
        File to read.
    what : str
        Kind of file expected, named in messages, e.g. ``"a pneufdd Parquet recording"``.

    Raises
    ------
    MissingFileError
        If ``path`` does not exist.
    FileFormatError
        If ``path`` is a directory or empty.
    """
    if not path.exists():
        raise MissingFileError(f"{file_label(path)} does not exist; expected {what}")
    if not path.is_file():
        raise FileFormatError(f"{file_label(path)} is not a regular file; expected {what}")
    if path.stat().st_size == 0:
        raise FileFormatError(f"{file_label(path)} is empty (0 bytes); expected {what}")
    return path
