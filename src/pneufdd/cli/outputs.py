"""Output files of a command: checked before any work, written atomically.

Every command that writes files calls :func:`check_outputs` first, with its inputs
and its outputs named by the option that gave them. The rules (issue 14):

* an output may never be one of the command's own inputs, with or without
  ``--overwrite`` (``--json run.parquet`` would destroy the recording);
* two outputs of one command may not share a path (one would lose the other);
* an output may not be a folder, nor lie inside a path that is a file;
* an existing output is replaced only with ``--overwrite`` (a symbolic link too, even
  one that leads nowhere or to itself: the link is replaced, never written through);
* the place must be one the output can be written to (:func:`check_place`: a name the
  system accepts, a writable folder; missing folders are created). Folder outputs
  (``--out DIR``) call :func:`check_place` with ``folder=True`` before their files are
  checked.

Every refusal names the option that gave the path.

Writing goes through :mod:`pneufdd.files` (``write_text_atomic``, ``atomic_target``): a temporary
file in the target's folder, renamed into place once complete, so an error (or
Ctrl-C) never leaves a partial file under the user's name.

Examples
--------
>>> import tempfile
>>> from pathlib import Path
>>> folder = Path(tempfile.mkdtemp())
>>> run = folder / "run.parquet"
>>> _ = run.write_bytes(b"PAR1")
>>> def refused(outputs, inputs):
...     try:
...         check_outputs(outputs, inputs, overwrite=True)
...     except InputError as exc:
...         return str(exc).split("allowed: ")[1]
>>> refused({"--json": run}, {"RUN": run})
"a path that is not one of this command's inputs (it is RUN)"
>>> refused({"--json": folder / "a.json", "--report": folder / "a.json"}, {})
'a path no other output uses (--json writes there)'
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

from pneufdd.errors import FileExistsInputError, InputError, describe

__all__ = [
    "check_appended",
    "check_outputs",
    "check_place",
    "check_writable",
    "database_files",
    "same_file",
]

SQLITE_COMPANIONS = ("-wal", "-shm", "-journal")
"""Files SQLite writes beside a database (write-ahead log, shared memory, rollback)."""


def _key(path: Path) -> Path:
    """An absolute, symlink-resolved form of ``path`` (existing or not)."""
    try:
        return Path(os.path.realpath(path))
    except (OSError, ValueError):  # pragma: no cover - realpath rarely fails
        return Path(os.path.abspath(path))


def same_file(a: str | Path, b: str | Path) -> bool:
    """True when ``a`` and ``b`` name the same file (hard links and symlinks included)."""
    pa, pb = Path(a), Path(b)
    try:
        if pa.exists() and pb.exists():
            return os.path.samefile(pa, pb)
    except (OSError, ValueError):
        pass
    return _key(pa) == _key(pb)


def check_outputs(
    outputs: Mapping[str, str | Path | None],
    inputs: Mapping[str, str | Path | None],
    overwrite: bool = False,
) -> None:
    """Refuse outputs that would destroy an input, collide, or replace a file unasked.

    Parameters
    ----------
    outputs : mapping of str to path or None
        Each output by the option that names it (``"--json"``); None: not requested.
    inputs : mapping of str to path or None
        Each input file by the argument or option that names it; entries that are not
        existing files (e.g. a built-in machine name) are ignored.
    overwrite : bool
        Whether an existing output may be replaced.

    Raises
    ------
    InputError
        Naming the option, the path and what is allowed.
    FileExistsInputError
        If an output exists and ``overwrite`` is false.
    """
    given = {name: Path(p) for name, p in outputs.items() if p is not None}
    sources = {name: Path(p) for name, p in inputs.items() if p is not None}
    seen: dict[Path, str] = {}
    for name, path in given.items():
        if str(path).strip() == "":
            raise InputError(describe(name, str(path), "a file path"))
        check_place(name, path)  # a name too long, a loop on the way, a read-only folder
        for source_name, source in sources.items():
            if _is_file(source) and same_file(path, source):
                raise InputError(
                    describe(
                        name,
                        str(path),
                        f"a path that is not one of this command's inputs (it is {source_name})",
                    )
                )
        key = _key(path)
        if key in seen:
            raise InputError(
                describe(name, str(path), f"a path no other output uses ({seen[key]} writes there)")
            )
        seen[key] = name
        if path.is_dir():
            raise InputError(describe(name, str(path), "a file path (this is a folder)"))
        for parent in path.parents:
            if parent.exists() and not parent.is_dir():
                raise InputError(
                    describe(name, str(path), f"a path in a folder ({str(parent)!r} is a file)")
                )
        # a link counts as there even when it leads nowhere (dangling, or a loop, which
        # path.exists() reports as absent): replacing it needs --overwrite too
        if os.path.lexists(path) and not overwrite:
            raise FileExistsInputError(
                describe(name, str(path), "a new file (or pass --overwrite to replace it)")
            )


def check_place(name: str, path: str | Path, folder: bool = False) -> None:
    """Refuse at start an output path that cannot be created where it is named.

    The one check of where an output goes, naming the option: a link that leads nowhere
    or to itself where a folder output goes (it could only be written through), a path
    inside a file, a path whose name the system refuses (too long), and a nearest
    existing folder this process cannot write in (missing folders are created).

    Parameters
    ----------
    name : str
        The option that names the output (``"--out"``).
    path : str or Path
        The output file, or folder when ``folder``.
    folder : bool
        Whether the output is a folder (its files are checked by :func:`check_outputs`).

    Raises
    ------
    InputError
        Naming the option, the path and what is allowed.

    Examples
    --------
    >>> import tempfile
    >>> place = Path(tempfile.mkdtemp())
    >>> (place / "loop").symlink_to("loop")
    >>> try:
    ...     check_place("--out", place / "loop", folder=True)
    ... except InputError as exc:
    ...     print(str(exc).split("allowed: ")[1])
    a folder (or a path to create one); this is a link that leads nowhere or to itself
    >>> check_place("--out", place / "new" / "sub" / "x.json")  # created when written
    """
    target = Path(path)
    allowed = "a folder (or a path to create one)" if folder else "a file path"
    if str(path).strip() == "":
        raise InputError(describe(name, str(path), allowed))
    try:
        for parent in target.parents:
            if os.path.lexists(parent) and not parent.is_dir():
                what = "is a file" if parent.is_file() else "is no folder"
                raise InputError(
                    describe(name, _shown(path), f"a path in a folder ({str(parent)!r} {what})")
                )
        with contextlib.suppress(FileNotFoundError):
            os.lstat(target)  # a name too long, or a loop on the way, raises here
        if folder and os.path.lexists(target) and not target.exists():
            raise InputError(
                describe(
                    name, str(path), f"{allowed}; this is a link that leads nowhere or to itself"
                )
            )
        if folder and target.exists() and not target.is_dir():
            raise InputError(describe(name, str(path), f"{allowed}; this is a file"))
    except OSError as exc:
        raise InputError(
            describe(name, _shown(path), f"{allowed} ({exc.strerror or type(exc).__name__})")
        ) from None
    if target.is_file():
        check_writable(name, target)
    elif not target.exists():
        check_writable(name, target)  # a probe in the nearest existing folder
    elif folder:  # an existing folder: a probe inside it
        check_writable(name, target, inside=True)


def check_appended(name: str, path: str | Path) -> None:
    """Refuse a file a command appends to (an alarm log, a SQLite history) that is a link
    leading nowhere or to itself: appending would create a file where the link points,
    outside what the user named (``monitor --history`` on a dangling link did).

    >>> import tempfile
    >>> place = Path(tempfile.mkdtemp())
    >>> (place / "h.db").symlink_to("elsewhere.db")
    >>> try:
    ...     check_appended("--history", place / "h.db")
    ... except InputError as exc:
    ...     print(str(exc).split("allowed: ")[1])
    a file, or a path where one can be created (this is a link that leads nowhere or to itself)
    >>> check_appended("--history", place / "new.db")
    """
    target = Path(path)
    if os.path.lexists(target) and not target.exists():
        raise InputError(
            describe(
                name,
                _shown(path),
                "a file, or a path where one can be created (this is a link that leads "
                "nowhere or to itself)",
            )
        )


def _is_file(path: Path) -> bool:
    """Whether ``path`` is a file; False for a name the system refuses (its reader says why)."""
    try:
        return path.is_file()
    except OSError:
        return False


def _shown(path: str | Path, limit: int = 120) -> str:
    """``path`` as text, cut to ``limit`` characters (a 10,000-character name in one line)."""
    text = str(path)
    return text if len(text) <= limit else f"{text[: limit - 3]}..."


def database_files(url: str) -> list[Path]:
    """The files a SQLAlchemy URL makes a command write: a SQLite database and its companions.

    None for a database server (``postgresql://``), an in-memory database or a URL
    that does not parse (the database's own check names it).

    >>> [p.name for p in database_files("sqlite:///data/h.db")]
    ['h.db', 'h.db-wal', 'h.db-shm', 'h.db-journal']
    >>> database_files("postgresql://plant@db/pneufdd"), database_files("sqlite://")
    ([], [])
    """
    import sqlalchemy as sa

    try:
        parsed = sa.engine.make_url(url)
        backend = parsed.get_backend_name()
    except (sa.exc.ArgumentError, ValueError, TypeError):
        return []
    name = parsed.database or ""
    if backend != "sqlite" or name in ("", ":memory:") or name.startswith("file:"):
        return []
    db = Path(name)
    return [db, *(db.with_name(db.name + suffix) for suffix in SQLITE_COMPANIONS)]


def check_writable(name: str, path: str | Path, inside: bool = False) -> None:
    """Refuse at start a file this process could not write (created, appended or replaced).

    Parameters
    ----------
    name : str
        The option that names the file (``"--alarm-log"``).
    path : str or Path
        The file; it need not exist, its nearest existing folder must be writable.
    inside : bool
        ``path`` is an existing folder a command writes files in: probed inside.

    Raises
    ------
    InputError
        Naming the option, the path and why it cannot be written.
    """
    target = Path(path)
    folder = next((p for p in target.absolute().parents if p.exists()), Path("/"))
    if inside:
        folder = target
    try:
        if target.exists() and not inside:
            with open(target, "ab"):  # opened for appending, nothing written
                pass
        else:  # a probe file in the nearest existing folder, removed at once
            fd, probe = tempfile.mkstemp(prefix=".pneufdd-probe-", dir=folder)
            os.close(fd)
            os.unlink(probe)
    except OSError as exc:
        where = f"{str(target)!r}" if target.exists() else f"folder {str(folder)!r}"
        raise InputError(
            describe(
                name,
                str(target),
                f"a file this user may write ({where}: {exc.strerror or type(exc).__name__})",
            )
        ) from None
