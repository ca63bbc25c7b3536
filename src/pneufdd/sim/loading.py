"""Find and load machine descriptions: built-in names or TOML files."""

from __future__ import annotations

import tomllib
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


def _read_toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MachineError(f"{source}: not valid TOML: {exc}") from None


def load_machine(
    machine: str | Path | MachineDescription | dict[str, Any],
) -> MachineDescription:
    """Load a machine: a built-in name, a TOML path, a parsed mapping or a description.

    Parameters
    ----------
    machine : str, Path, MachineDescription or dict
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
    if isinstance(machine, dict):
        return parse_description(machine, "<dict>")
    if isinstance(machine, str) and machine in builtin_machines():
        return _builtin(machine)
    path = Path(machine)
    if path.suffix.lower() == ".toml" or path.exists():
        if not path.is_file():
            raise MachineError(describe("machine file", str(path), "an existing .toml file"))
        return parse_description(_read_toml(path.read_text("utf-8"), str(path)), str(path))
    raise MachineError(
        describe("machine", str(machine), [*builtin_machines(), "a path to a .toml file"])
    )
