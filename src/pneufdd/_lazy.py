"""Attributes of a package imported on first use (PEP 562), so ``import pneufdd`` stays light."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module
from typing import Any

__all__ = ["lazy_getattr"]


def lazy_getattr(
    package: str, where: Mapping[str, str], namespace: dict[str, Any]
) -> Callable[[str], Any]:
    """A module ``__getattr__`` that imports ``name`` from the module ``where[name]``.

    The value is stored in ``namespace`` (the package's globals), so it is looked up
    once and stays what it was even when a submodule of the same name is imported later.

    >>> ns: dict[str, Any] = {}
    >>> get = lazy_getattr("demo", {"sqrt": "math"}, ns)
    >>> get("sqrt")(4.0), "sqrt" in ns
    (2.0, True)
    """

    def attribute(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(module), name)
        namespace[name] = value
        return value

    return attribute
