"""Find and load machine descriptions: built-in names or TOML files."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

from pneufdd.errors import MachineError, describe
from pneufdd.sim.description import MachineDescription, parse_description

__all__ = ["builtin_machines", "load_machine"]


@lru_cache(maxsize=1)
def builtin_machines() -> tuple[str, ...]:
    """Names of the machine descriptions shipped with pneufdd.

    Examples
    --------
    >>> "festo-dsd" in builtin_machines()
    True
    """
    folder = resources.files("pneufdd.sim") / "machines"
    return tuple(sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml")))


@lru_cache(maxsize=8)
def _builtin(name: str) -> MachineDescription:
    res = resources.files("pneufdd.sim") / "machines" / f"{name}.toml"
    return parse_description(_read_toml(res.read_text("utf-8"), f"{name}.toml"), name)


MAX_DEPTH = 12
"""Deepest nesting of tables and arrays a machine file may have (it needs 4)."""

MAX_BYTES = 4 << 20
"""Largest machine file read [bytes] (the built-in ones are under 30 kB)."""


def _depth(value: object) -> int:
    depth, level = 0, [value]
    while level and depth <= MAX_DEPTH:
        depth += 1
        nxt: list[object] = []
        for v in level:
            if isinstance(v, dict):
                nxt.extend(v.values())
            elif isinstance(v, list):
                nxt.extend(v)
        level = nxt
    return depth


def _read_toml(text: str, source: str) -> dict[str, Any]:
    """Parse a machine file's text; refuse invalid TOML and absurd nesting."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MachineError(f"{source}: not valid TOML: {exc}") from None
    except RecursionError:
        raise MachineError(
            describe(f"{source}: nesting of tables and arrays", "too deep to read", "<= 12 levels")
        ) from None
    if _depth(data) > MAX_DEPTH:
        raise MachineError(
            describe(f"{source}: nesting of tables and arrays", f"> {MAX_DEPTH}", f"<= {MAX_DEPTH}")
        )
    return data


def _read_file(path: Path) -> str:
    """The machine file's text: UTF-8 (TOML's encoding), of a sane size."""
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise MachineError(describe(f"{path}: size [bytes]", size, f"<= {MAX_BYTES}"))
    data = path.read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MachineError(
            describe(
                f"{path}: encoding (byte {exc.start})",
                data[exc.start : exc.start + 4],
                "UTF-8 text (TOML files are UTF-8)",
            )
        ) from None


MachineLike = str | Path | MachineDescription | Mapping[str, Any]
"""What every function that takes a machine accepts: a built-in name, a TOML path, a
parsed TOML mapping or a description."""


def load_machine(machine: MachineLike) -> MachineDescription:
    """Load a machine: a built-in name, a TOML path, a parsed mapping or a description.

    Parameters
    ----------
    machine : str, Path, MachineDescription or mapping
        ``"festo-dsd"`` (see :func:`builtin_machines`), a path to a ``.toml`` file,
        an already parsed TOML mapping, or a description (returned as is).

    Returns
    -------
    MachineDescription

    Raises
    ------
    MachineError
        If the name is unknown, the file is missing or the description invalid.

    Examples
    --------
    >>> m = load_machine("festo-dsd")
    >>> len(m.actuators), len(m.steps)
    (9, 58)
    """
    if isinstance(machine, MachineDescription):
        return machine
    if isinstance(machine, Mapping):
        raw = machine if isinstance(machine, dict) else dict(machine)
        return parse_description(raw, "<dict>")
    if isinstance(machine, str) and machine in builtin_machines():
        return _builtin(machine)
    path = Path(machine)
    shown = str(machine) if len(str(machine)) <= 200 else f"{str(machine)[:197]}..."
    try:
        there = path.suffix.lower() == ".toml" or path.exists()
        if there and not path.is_file():
            raise MachineError(describe("machine file", shown, "an existing .toml file"))
    except OSError as exc:  # a name too long, a loop on the way
        raise MachineError(
            describe("machine", shown, f"a built-in name or a .toml file ({exc.strerror})")
        ) from None
    if there:
        return parse_description(_read_toml(_read_file(path), str(path)), str(path))
    raise MachineError(describe("machine", shown, [*builtin_machines(), "a path to a .toml file"]))
