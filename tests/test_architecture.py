"""The package's shape (issue 31): imports flow one way, modules and functions stay small.

The layers follow the ISO 13374 chain of the README's package map (acquire, condition,
detect, assess, advise)::

    physics -> catalogue -> recording -> identification -> sim -> signals -> features
    -> diagnosis -> standstill -> calibration -> energy -> classifiers -> evaluation
    -> monitor -> report -> web -> cli

and inside :mod:`pneufdd.diagnosis`: detection -> effects -> localisation -> reference
-> the diagnosis's own modules (engine, diagnoser, recordings, cost, ...). A module may
import its own layer and the layers left of it; the shared helpers at the bottom
(``errors``, ``array_types``, ``location``, ``parallel``, ``progress``, ``_lazy``)
import only each other. Every import counts: at module level, inside a function, or
under ``TYPE_CHECKING``. The root package may be imported only for ``__version__``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "pneufdd"

BASE = ("_lazy", "errors", "array_types", "files", "limits", "location", "parallel", "progress")
LAYERS: tuple[str, ...] = (
    "physics",
    "catalogue",
    "recording",
    "identification",
    "sim",
    "signals",
    "features",
    "diagnosis.detection",
    "diagnosis.effects",
    "diagnosis.localisation",
    "diagnosis.reference",
    "diagnosis",
    "standstill",
    "calibration",
    "energy",
    "classifiers",
    "evaluation",
    "monitor",
    "report",
    "web",
    "cli",
)
"""The layers, lowest first (the README's package map)."""

MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 150
COMPILED_KERNELS = {("sim/kernel.py", "run_cycle")}
"""Functions exempt from the length limit: the twin's compiled loop, kept in one body
because splitting it into stages measured slower (docs/twin.md)."""


def _layer(module: str) -> str:
    """The layer of a dotted module name inside the package (``pneufdd.x.y``)."""
    parts = module.split(".")
    if len(parts) == 1:
        return "pneufdd"
    top = parts[1]
    if top == "diagnosis" and len(parts) > 2 and (SRC / "diagnosis" / parts[2]).is_dir():
        return f"diagnosis.{parts[2]}"
    return top


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _sources() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def _imports(path: Path) -> Iterator[tuple[int, str, list[str]]]:
    """(line, imported module, imported names) of every import of the package."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.split(".")[0] == "pneufdd":
                yield node.lineno, node.module, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "pneufdd":
                    yield node.lineno, alias.name, []


def _rank(layer: str) -> int:
    return -1 if layer in BASE else LAYERS.index(layer)


def test_every_package_folder_has_a_layer() -> None:
    folders = {p.name for p in SRC.iterdir() if (p / "__init__.py").is_file()}
    folders |= {f"diagnosis.{p.parent.name}" for p in (SRC / "diagnosis").glob("*/__init__.py")}
    modules = {p.stem for p in SRC.glob("*.py")} - {"__init__"}
    assert folders <= set(LAYERS), folders - set(LAYERS)
    assert modules <= set(BASE), modules - set(BASE)


def _violations() -> list[str]:
    found: list[str] = []
    for path in _sources():
        module = _module_name(path)
        here = _layer(module) if module != "pneufdd" else "pneufdd"
        if path.parent == SRC and path.stem != "__init__":
            here = path.stem
        for line, target, names in _imports(path):
            there = _layer(target)
            where = f"{path.relative_to(SRC)}:{line} imports {target}"
            if here == "pneufdd":
                continue  # the root's lazy names (imported on first use, by name)
            if there == "pneufdd":
                if names != ["__version__"]:
                    found.append(f"{where} (only __version__ may come from the root)")
                continue
            if _rank(there) > _rank(here):
                found.append(f"{where}: {here} may not import {there}")
    return found


def test_imports_flow_one_way() -> None:
    assert _violations() == []


def test_the_check_would_catch_an_upward_import() -> None:
    """The rule itself: a signal-layer module importing the diagnosis is refused."""
    assert _rank(_layer("pneufdd.diagnosis.engine")) > _rank(_layer("pneufdd.signals.digital"))
    assert _rank(_layer("pneufdd.diagnosis.effects.model")) < _rank(
        _layer("pneufdd.diagnosis.reference.model")
    )
    assert _layer("pneufdd.diagnosis.localisation.check") == "diagnosis.localisation"
    assert _rank("errors") < _rank("physics")


@pytest.mark.parametrize("path", _sources(), ids=lambda p: str(p.relative_to(SRC)))
def test_modules_and_functions_stay_small(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    rel = path.relative_to(SRC).as_posix()
    assert text.count("\n") <= MAX_MODULE_LINES, f"{rel}: {text.count(chr(10))} lines"
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            if (rel, node.name) in COMPILED_KERNELS:
                continue
            assert node.end_lineno is not None
            length = node.end_lineno - node.lineno + 1
            assert length <= MAX_FUNCTION_LINES, f"{rel}: {node.name} has {length} lines"
