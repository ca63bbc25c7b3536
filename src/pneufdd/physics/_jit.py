"""Typed wrappers around numba, and the input checks the public physics functions share.

Every physical law in :mod:`pneufdd.physics` is written once, as a scalar kernel
compiled with :func:`njit`. The public array functions wrap that kernel in a
numba ufunc built by :func:`elementwise`, so the simulator's compiled code and the
user-facing functions evaluate literally the same code. Kernels are cached on disk
(``NUMBA_CACHE_DIR``); nothing here keeps global state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe

__all__ = [
    "FloatArray",
    "FloatOrArray",
    "as_float_array",
    "elementwise",
    "njit",
    "njit_inline",
    "require",
    "scalar_or_array",
]

F = TypeVar("F", bound=Callable[..., Any])

FloatOrArray = float | FloatArray


def njit(func: F) -> F:
    """Compile ``func`` with numba in nopython mode, cached on disk.

    Parameters
    ----------
    func : callable
        A scalar function of float64 arguments.

    Returns
    -------
    callable
        The compiled dispatcher; callable from Python and from other numba code.
    """
    return cast(F, numba.njit(cache=True)(func))


def njit_inline(func: F) -> F:
    """Like :func:`njit`, and inlined into every compiled caller.

    For the small helpers of the kernels the simulator calls in its inner loop
    (numba inlines them at the IR level, ``inline="always"``): a call from compiled
    code to a separately compiled function costs a call, a status check and, from
    numba's on-disk cache, an indirect jump, which for these one-line laws is more
    than the arithmetic. Called from Python, it behaves exactly like :func:`njit`.

    Parameters
    ----------
    func : callable
        A scalar function of float64 arguments.

    Returns
    -------
    callable
        The compiled dispatcher.
    """
    return cast(F, numba.njit(cache=True, inline="always")(func))


class _Elementwise:
    """A float64 numba ufunc over a scalar kernel, compiled on first call.

    Building the ufunc compiles (or loads from cache) machine code; doing that
    lazily keeps ``import pneufdd`` fast for code that never evaluates physics.
    """

    def __init__(self, kernel: Callable[..., float], n_args: int) -> None:
        self._kernel = kernel
        self._signature = "float64(" + ", ".join(["float64"] * n_args) + ")"
        self._ufunc: Callable[..., Any] | None = None

    def __call__(self, *args: Any) -> Any:
        if self._ufunc is None:
            self._ufunc = cast(
                Callable[..., Any],
                numba.vectorize([self._signature], cache=True)(self._kernel),  # type: ignore[no-untyped-call]
            )
        return self._ufunc(*args)


def elementwise(kernel: Callable[..., float], n_args: int) -> Callable[..., Any]:
    """Build a float64 numba ufunc that applies a scalar kernel element by element.

    Parameters
    ----------
    kernel : callable
        A compiled scalar kernel of ``n_args`` float64 arguments.
    n_args : int
        Number of arguments of ``kernel``.

    Returns
    -------
    callable
        A ufunc broadcasting its ``n_args`` arguments like numpy, compiled on first call.
    """
    return _Elementwise(kernel, n_args)


def as_float_array(value: npt.ArrayLike, name: str) -> FloatArray:
    """Convert an argument to a float64 array and reject NaN or infinite entries.

    Parameters
    ----------
    value : array_like
        The argument as given.
    name : str
        Parameter name used in the error message.

    Returns
    -------
    ndarray
        ``value`` as float64.

    Raises
    ------
    InputError
        If ``value`` is not numeric or holds a NaN or infinity.
    """
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InputError(describe(f"parameter {name!r}", value, "real numbers")) from error
    if not np.all(np.isfinite(array)):
        raise InputError(describe(f"parameter {name!r}", value, "finite real numbers"))
    return array


def require(array: FloatArray, ok: npt.NDArray[np.bool_] | bool, name: str, allowed: str) -> None:
    """Raise :class:`InputError` unless every entry of ``ok`` is true.

    Parameters
    ----------
    array : ndarray
        The checked values, quoted in the message (first offending entry).
    ok : ndarray of bool or bool
        Per-entry verdict.
    name : str
        Parameter name.
    allowed : str
        Human description of the allowed range, e.g. ``">= 0 Pa (absolute)"``.
    """
    verdict = np.broadcast_to(np.asarray(ok, dtype=bool), array.shape)
    if not np.all(verdict):
        bad = array[~verdict].flat[0] if array.ndim else array
        raise InputError(describe(f"parameter {name!r}", float(bad), allowed))


def scalar_or_array(result: Any) -> FloatOrArray:
    """Return a Python float for a 0-d result and a float64 ndarray otherwise.

    Parameters
    ----------
    result : float or ndarray
        Output of a ufunc.

    Returns
    -------
    float or ndarray
        ``float`` for scalar input, ``ndarray`` for array input.
    """
    array = np.asarray(result, dtype=np.float64)
    if array.ndim == 0:
        return float(array)
    return array
