"""Exception types shared by every layer of pneufdd.

Every error raised on bad user input is an :class:`InputError` (a ``ValueError``),
whose message names the file, channel or parameter, the allowed values and what was
received. Use :func:`describe` to build such messages consistently.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = [
    "ChannelError",
    "FileExistsInputError",
    "FileFormatError",
    "InputError",
    "MachineError",
    "MissingFileError",
    "NoCompleteCycleError",
    "PneufddError",
    "UnitError",
    "describe",
    "naming",
]


class PneufddError(Exception):
    """Base class of all pneufdd errors."""


class InputError(PneufddError, ValueError):
    """Bad input: a file, channel, parameter or value the user gave us."""


class FileFormatError(InputError):
    """A file that cannot be read: missing, truncated, corrupted or of the wrong kind."""


class MissingFileError(FileFormatError, FileNotFoundError):
    """The file to read does not exist (also a :class:`FileNotFoundError`)."""


class FileExistsInputError(InputError, FileExistsError):
    """The file to write exists and overwrite was not asked for (a :class:`FileExistsError`)."""


class ChannelError(InputError):
    """A channel that is missing, duplicated or inconsistent."""


class UnitError(InputError):
    """A unit that pneufdd does not know, or that does not fit the quantity."""


class MachineError(InputError):
    """An invalid machine description."""


class NoCompleteCycleError(InputError):
    """A recording holds no complete machine cycle (truncated, stopped, or too slow)."""


MAX_RECEIVED_CHARS = 600
"""Longest shown form of a received value in a message (``docs/limits.md``)."""


def describe(what: str, received: object, allowed: Iterable[object] | str | None = None) -> str:
    """Build a uniform error message: what is wrong, what was received, what is allowed.

    >>> describe("unit of channel 'P_In'", "furlong", ["Pa", "bar", "psi"])
    "unit of channel 'P_In': received 'furlong'; allowed: 'Pa', 'bar', 'psi'"
    """
    shown = repr(received)
    if len(shown) > MAX_RECEIVED_CHARS:  # a whole file's worth of columns: its start and end
        half = MAX_RECEIVED_CHARS // 2
        shown = f"{shown[:half]} [... {len(shown) - 2 * half:,} characters ...] {shown[-half:]}"
    message = f"{what}: received {shown}"
    if allowed is None:
        return message
    if isinstance(allowed, str):
        return f"{message}; allowed: {allowed}"
    return f"{message}; allowed: " + ", ".join(repr(a) for a in allowed)


def naming(exc: InputError, where: str) -> InputError:
    """A copy of ``exc`` with ``where`` (a file) in front of its message, unless it names it.

    >>> str(naming(ChannelError("no valve fires"), "run.parquet"))
    'run.parquet: no valve fires'
    """
    message = str(exc) if where in str(exc) else f"{where}: {exc}"
    return type(exc)(message)
