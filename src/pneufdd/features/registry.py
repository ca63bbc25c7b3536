"""The feature registry: stable names -> documented functions.

Each feature is a function of one complete cycle (a :class:`~pneufdd.features.context.CycleView`)
and, depending on its scope, of an actuator or a step number. Its column name in a
feature matrix is

* scope ``"cycle"``: ``name``;
* scope ``"actuator"``: ``"<ACT>.name"`` (e.g. ``DNC.t_s_extend_s``);
* scope ``"step"``: ``"stepNN.name"`` (e.g. ``step03.air_SL``).

Names end with their unit (``_s``, ``_Pa``, ``_m_s``, ``_kg_s``, ``_SL``, ``_1``);
:attr:`Feature.unit` repeats it. A feature that cannot be computed for a cycle
raises :class:`Unavailable` with the reason; the builder records NaN and the reason.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from pneufdd.errors import InputError, describe

if TYPE_CHECKING:
    from pneufdd.features.context import CycleView

__all__ = ["REGISTRY", "Feature", "Scope", "Unavailable", "column_name", "get", "register"]

Scope = Literal["cycle", "actuator", "step"]


class Unavailable(Exception):  # noqa: N818 - a signal, not an error of the caller
    """A feature that cannot be computed for this cycle; the message says why."""


@dataclass(frozen=True)
class Feature:
    """One registered feature.

    Attributes
    ----------
    name : str
        Stable name, ending with the unit.
    scope : {"cycle", "actuator", "step"}
        What the feature is computed for, besides the cycle.
    unit : str
        Unit of the value (``"SL"``: standard litres, 0 degC, 1013 mbar, 1.294 kg/m^3).
    group : str
        Family: ``"motion"``, ``"air"``, ``"table44"``, ``"wavelet"``.
    needs : tuple of str
        Channels required; ``{act}`` stands for the actuator.
    func : callable
        ``func(view, target) -> float``; target is the actuator, the 1-based step
        number, or None.
    description : str
        One line, with the dissertation reference.
    """

    name: str
    scope: Scope
    unit: str
    group: str
    needs: tuple[str, ...]
    func: Callable[[CycleView, Any], float]
    description: str

    def channels(self, actuator: str | None) -> tuple[str, ...]:
        """The channels this feature needs for ``actuator``."""
        return tuple(n.format(act=actuator) for n in self.needs)


REGISTRY: dict[str, Feature] = {}


def register(
    name: str,
    scope: Scope,
    unit: str,
    group: str,
    needs: tuple[str, ...] = (),
    description: str | None = None,
) -> Callable[[Callable[[CycleView, Any], float]], Callable[[CycleView, Any], float]]:
    """Decorator adding a feature function to :data:`REGISTRY` under ``name``.

    The description defaults to the function's docstring.
    """

    def wrap(func: Callable[[CycleView, Any], float]) -> Callable[[CycleView, Any], float]:
        text = description if description is not None else (func.__doc__ or "").strip()
        add(Feature(name, scope, unit, group, needs, func, text))
        return func

    return wrap


def add(feature: Feature) -> None:
    """Add ``feature`` to the registry; names are unique."""
    if feature.name in REGISTRY:
        raise InputError(describe("feature name", feature.name, "a name not yet registered"))
    REGISTRY[feature.name] = feature


def get(name: str) -> Feature:
    """Look a feature up by name."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise InputError(describe("feature", name, sorted(REGISTRY))) from None


def column_name(feature: Feature, target: str | int | None) -> str:
    """Column name of ``feature`` for ``target`` in a feature matrix.

    Examples
    --------
    >>> f = Feature("air_SL", "step", "SL", "air", (), lambda v, t: 0.0, "")
    >>> column_name(f, 3)
    'step03.air_SL'
    """
    if feature.scope == "actuator":
        return f"{target}.{feature.name}"
    if feature.scope == "step":
        return f"step{int(target or 0):02d}.{feature.name}"
    return feature.name
