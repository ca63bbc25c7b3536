"""Output files of a command: checked before any work, written atomically.

Every command that writes files calls :func:`check_outputs` first, with its inputs
and its outputs named by the option that gave them. The rules (issue 14):

* an output may never be one of the command's own inputs, with or without
  ``--overwrite`` (``--json run.parquet`` would destroy the recording);
* two outputs of one command may not share a path (one would lose the other);
* an output may not be a folder, nor lie inside a path that is a file;
* an existing output is replaced only with ``--overwrite``.

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

import os
from collections.abc import Mapping
from pathlib import Path

from pneufdd.errors import FileExistsInputError, InputError, describe

__all__ = ["check_outputs", "same_file"]


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
        for source_name, source in sources.items():
            if source.is_file() and same_file(path, source):
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
        if path.exists() and not overwrite:
            raise FileExistsInputError(
                describe(name, str(path), "a new file (or pass --overwrite to replace it)")
            )
