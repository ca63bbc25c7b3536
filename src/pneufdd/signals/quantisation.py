"""Quantised analog channels: the converter step a channel's values lie on.

A DAQ or PLC analog input delivers converter counts; when the converter's step is
coarser than the sensor's noise (a supply pressure in 0.19 bar steps) the recorded
values take a few levels and the sample-to-sample scatter is mostly zero. Noise
estimated from that scatter, and spreads estimated from few cycles, then come out
near zero and a one-step change looks like a fault. Rule (``docs/signals.md``,
"Quantised channels"):

* a channel is **quantised** when at least half of its sample-to-sample differences
  away from its extreme values (where a meter clips) are exactly zero, and all its
  distinct values lie on one grid (every gap an integer multiple of the smallest gap,
  within 1 %); the **quantum** is that smallest gap. A channel whose noise spans
  several converter steps (the twin's 12-bit sensors) is not quantised in this sense:
  its resolution is below its noise and nothing needs it.
* noise floors are never below the quantisation noise ``q / sqrt(12)`` (uniform
  error), and the spread of every feature of the channel in a reference is never
  below ``q`` (a change of one step is at most one standard deviation).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from pneufdd.recording.model import Recording

__all__ = ["QUANTISATION_NOISE", "channel_quanta", "quantum"]

QUANTISATION_NOISE = 12.0**-0.5
"""Standard deviation of a uniform rounding error, per quantum [-]."""


def quantum(values: npt.ArrayLike) -> float:
    """The converter step of a quantised channel, 0.0 when it is not quantised.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> p = 6e5 + 2e3 * rng.standard_normal(5000)
    >>> quantum(np.round(p / 19e3) * 19e3)
    19000.0
    >>> quantum(p)
    0.0
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size < 10:
        return 0.0
    lo, hi = v.min(), v.max()
    if hi <= lo:
        return 0.0
    inner = (v > lo) & (v < hi)
    pairs = inner[:-1] & inner[1:]
    d = np.diff(v)
    if np.count_nonzero(pairs) >= 10:
        d = d[pairs]
    if np.mean(d == 0.0) < 0.5:
        return 0.0
    levels = np.unique(v)
    gaps = np.diff(levels)
    q = float(gaps.min())
    ratio = gaps / q
    if np.any(np.abs(ratio - np.rint(ratio)) > 0.01):
        return 0.0
    return q


def channel_quanta(recordings: list[Recording] | tuple[Recording, ...]) -> dict[str, float]:
    """The quantum of every quantised analog channel of ``recordings`` (largest found) [SI].

    Channels that are not quantised are left out.
    """
    out: dict[str, float] = {}
    for rec in recordings:
        for name in rec.analog_channels:
            q = quantum(rec.info(name).values)
            if q > 0.0:
                out[name] = max(out.get(name, 0.0), q)
    return out
