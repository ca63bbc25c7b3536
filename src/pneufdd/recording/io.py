"""Dispatch :meth:`Recording.read` on the file suffix."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pneufdd.errors import FileFormatError, InputError, describe
from pneufdd.recording._files import check_input_file, file_label
from pneufdd.recording.model import Recording

__all__ = ["SUFFIXES", "read_any"]

SUFFIXES = (".parquet", ".csv", ".tdms")
"""File suffixes :func:`read_any` knows (case-insensitive)."""


def read_any(path: str | Path, **options: Any) -> Recording:
    """Read ``path`` with the reader its suffix names.

    Parameters
    ----------
    path : str or Path
        A ``.parquet`` (pneufdd's own format), ``.csv`` or ``.tdms`` file.
    **options
        Passed to the reader: :func:`~pneufdd.recording.csv.read_csv` needs
        ``column_map`` and ``units``; :func:`~pneufdd.recording.tdms.read_tdms` takes
        ``channel_map``, ``units``, ``digital``; Parquet takes none.

    Returns
    -------
    Recording

    Raises
    ------
    FileFormatError
        Unknown suffix (the message lists those allowed), or a missing, empty,
        truncated or corrupted file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise FileFormatError(describe(f"{file_label(path)}: file suffix", path.suffix, SUFFIXES))
    check_input_file(path, f"a {suffix} file")
    if suffix == ".parquet":
        from pneufdd.recording.parquet import read_parquet

        if options:
            raise InputError(
                describe(
                    f"{file_label(path)}: options for a .parquet file", sorted(options), "none"
                )
            )
        return read_parquet(path)
    if suffix == ".csv":
        from pneufdd.recording.csv import read_csv

        missing = [k for k in ("column_map", "units") if k not in options]
        if missing:
            raise InputError(
                describe(
                    f"{file_label(path)}: a CSV export needs {' and '.join(missing)} "
                    "(which column is which channel, in which unit)",
                    "none",
                    "pneufdd.recording.read_csv(path, column_map, units) in Python, then "
                    "recording.write('run.parquet'); the commands read .parquet recordings",
                )
            )
        return read_csv(path, **options)
    from pneufdd.recording.tdms import read_tdms

    return read_tdms(path, **options)
