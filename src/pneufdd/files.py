"""Writing a user's files safely: atomically, never over a file that must not be replaced.

Every file pneufdd writes (recordings, references, machine descriptions, reports, JSON,
CSV) goes through :func:`atomic_target`: the content is written to a temporary file in
the target's folder, flushed to disk, and moved onto the target's name in one step
only when complete. An error or Ctrl-C leaves the target as it was and no temporary
file behind. Without ``overwrite`` the move is a hard link, which fails if the target
appeared meanwhile (no race with another writer); on a file system without hard links
an existing target is refused before an atomic rename.

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> target = Path(tempfile.mkdtemp()) / "out" / "a.txt"
>>> _ = write_text_atomic(target, "first")
>>> try:
...     write_text_atomic(target, "second", overwrite=False)
... except FileExistsInputError as exc:
...     print(str(exc).split("allowed: ")[1])
a new file, or overwrite=True
>>> target.read_text()
'first'
>>> sorted(p.name for p in target.parent.iterdir())
['a.txt']
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from pneufdd.errors import FileExistsInputError, describe

__all__ = [
    "MAX_NAME_CHARS",
    "atomic_target",
    "new_file_mode",
    "safe_name",
    "write_bytes_atomic",
    "write_text_atomic",
]

MAX_NAME_CHARS = 80
"""Longest file-name component :func:`safe_name` returns (file systems allow 255 bytes)."""

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]")


def safe_name(text: str) -> str:
    """A name read from a file (machine, actuator, tag), made a safe file-name component.

    Every character but ASCII letters, digits, ``.``, ``_``, ``+`` and ``-`` becomes
    ``_`` (path separators, ``..`` at the start, control characters, spaces, markup),
    leading dots are replaced (no ``..`` or hidden file), and the result is at most
    :data:`MAX_NAME_CHARS` long and never empty. A name that is already safe (the
    built-in machines' names) is returned unchanged, so such files keep their names.
    The result joined to a folder always stays inside that folder.

    Parameters
    ----------
    text : str
        The name as read.

    Returns
    -------
    str

    Examples
    --------
    >>> safe_name("press-fit-cell")
    'press-fit-cell'
    >>> safe_name("../../victim"), safe_name("/abs/path"), safe_name("..")
    ('_._.._victim', '_abs_path', '_.')
    >>> safe_name(""), safe_name("cell[/]")
    ('_', 'cell___')
    """
    name = _UNSAFE.sub("_", str(text))[:MAX_NAME_CHARS]
    if name.startswith("."):
        name = "_" + name[1:]
    return name or "_"


def new_file_mode() -> int:
    """The permission bits a newly created file gets under the process's umask."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _exists_error(path: Path) -> FileExistsInputError:
    return FileExistsInputError(
        describe(f"output file {str(path)!r}", "exists", "a new file, or overwrite=True")
    )


def _commit(tmp: Path, path: Path, overwrite: bool, exists: Callable[[Path], Exception]) -> None:
    """Move the finished temporary file onto ``path`` in one step."""
    if overwrite:
        os.replace(tmp, path)
        return
    try:  # a hard link fails if path appeared meanwhile: no race with another writer
        os.link(tmp, path)
    except FileExistsError:
        raise exists(path) from None
    except OSError:  # file system without hard links
        if path.exists():
            raise exists(path) from None
        os.replace(tmp, path)


def _sync_folder(folder: Path) -> None:
    """Flush the folder entry of a renamed file to disk where the OS allows it (POSIX)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextmanager
def atomic_target(
    path: str | Path,
    overwrite: bool = True,
    exists: Callable[[Path], Exception] = _exists_error,
) -> Iterator[Path]:
    """A temporary path beside ``path``, moved onto ``path`` if the block succeeds.

    Parameters
    ----------
    path : str or Path
        The file to write; missing parent folders are created.
    overwrite : bool
        Replace an existing ``path``; otherwise it is refused with ``exists(path)``,
        also when it appears while the block runs.
    exists : callable
        Builds the error raised for an existing ``path`` (default: a
        :class:`~pneufdd.errors.FileExistsInputError` naming it).

    The temporary file exists (empty) when the block starts, with the permissions a
    new file gets (not mkstemp's 0600); it is flushed to disk before the move. On any
    error it is removed and ``path`` is left as it was.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        os.chmod(tmp, new_file_mode())
        yield tmp
        with tmp.open("rb") as handle:
            os.fsync(handle.fileno())
        _commit(tmp, target, overwrite, exists)
    finally:
        tmp.unlink(missing_ok=True)
    _sync_folder(target.parent)


def write_bytes_atomic(path: str | Path, data: bytes, overwrite: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_target`)."""
    with atomic_target(path, overwrite) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text_atomic(path: str | Path, text: str, overwrite: bool = True) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_target`)."""
    return write_bytes_atomic(path, text.encode("utf-8"), overwrite)
