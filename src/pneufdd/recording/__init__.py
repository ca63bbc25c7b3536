"""Acquire: the :class:`Recording` data model and its readers and writer.

May import: :mod:`pneufdd.physics` (units) and the shared helpers (``errors``,
``array_types``); the acquire layer of ISO 13374, below everything but physics.
"""

from __future__ import annotations

from pneufdd.recording._files import FileExistsInputError, MissingFileError
from pneufdd.recording.csv import read_csv
from pneufdd.recording.io import read_any
from pneufdd.recording.model import ANALOG, DIGITAL, Channel, ChannelKind, Recording
from pneufdd.recording.parquet import read_parquet, write_parquet
from pneufdd.recording.tdms import read_tdms

__all__ = [
    "ANALOG",
    "DIGITAL",
    "Channel",
    "ChannelKind",
    "FileExistsInputError",
    "MissingFileError",
    "Recording",
    "read_any",
    "read_csv",
    "read_parquet",
    "read_tdms",
    "write_parquet",
]
