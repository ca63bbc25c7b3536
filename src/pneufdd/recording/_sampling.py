"""Sample-rate helpers shared by the CSV and TDMS readers."""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["snap_rate"]


def snap_rate(rate_hz: float, fits: Callable[[float], bool]) -> float:
    """Return the shortest decimal spelling of ``rate_hz`` that still ``fits`` the data.

    Sample rates are computed from float times or increments, so 1000 Hz may come out
    as 999.9999999999999 Hz. The rig's rates are round numbers (1000 Hz analog, 100 Hz
    digital, section 3.2.4), so the rate with the fewest significant digits that
    describes the data as well is returned; otherwise ``rate_hz`` itself.

    Parameters
    ----------
    rate_hz : float
        Rate computed from the data [Hz].
    fits : callable
        ``fits(candidate)`` is true when a candidate rate describes the data as well [Hz].

    Returns
    -------
    float
        The snapped rate [Hz].

    Examples
    --------
    >>> increment = 1.0 / 3000.0
    >>> snap_rate(1.0 / increment, lambda r: 1.0 / r == increment)
    3000.0
    """
    for digits in range(1, 16):
        candidate = float(f"{rate_hz:.{digits}g}")
        if candidate > 0.0 and fits(candidate):
            return candidate
    return rate_hz
