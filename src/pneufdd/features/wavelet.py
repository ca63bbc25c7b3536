"""Wavelet features: DWT to level 3 of the line signals of each stroke (section 5.3.3).

Section 5.3.3 decomposes a step's signal to level 3 (approximations cA1..cA3,
details cD1..cD3, Fig. 5.3) with a chosen mother wavelet and uses single
coefficients as features (Figs. 5.15-5.17). Coefficient counts depend on the step's
length, so pneufdd summarises each band to fixed-length numbers:

* ``mean``: mean of the band's coefficients [signal unit];
* ``energy``: mean of their squares [signal unit^2] (energy per coefficient, so
  comparable between steps of different lengths);
* ``peak``: the coefficient of largest magnitude, with its sign [signal unit].

Signals: ``P_<ACT>_A``, ``P_<ACT>_B``, ``Q_<ACT>_A``, ``Q_<ACT>_B`` over the extend
and the retract step (valve firing to next step start). NaN gaps are bridged by
linear interpolation when at least ``min_valid`` of the samples are finite. The
decomposition is :func:`pywt.wavedec` (cA3, cD3..cD1) and :func:`pywt.downcoef`
(cA1, cA2), signal-extension mode ``symmetric``; the wavelet is
:attr:`~pneufdd.features.context.Options.wavelet` (``db4`` by default).
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt
import pywt

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError, describe
from pneufdd.features.context import CycleView
from pneufdd.features.motion import MOTIONS
from pneufdd.features.registry import Unavailable, register
from pneufdd.signals.filtering import fill_gaps

__all__ = ["BANDS", "LEVEL", "SIGNALS", "SUMMARIES", "check_wavelet", "decompose", "summarise"]


LEVEL = 3
BANDS = ("cA1", "cA2", "cA3", "cD1", "cD2", "cD3")
SUMMARIES = ("mean", "energy", "peak")
SIGNALS = ("P_A", "P_B", "Q_A", "Q_B")
MODE = "symmetric"


@functools.cache
def check_wavelet(name: str) -> pywt.Wavelet:
    """Return the discrete PyWavelets wavelet ``name`` or raise InputError."""
    if name not in pywt.wavelist(kind="discrete"):
        raise InputError(describe("wavelet", name, "a discrete wavelet of pywt.wavelist()"))
    return pywt.Wavelet(name)


def decompose(x: npt.ArrayLike, wavelet: str = "db4") -> dict[str, FloatArray]:
    """Level-3 DWT bands of ``x``: cA1, cA2, cA3, cD1, cD2, cD3 (Fig. 5.3).

    Examples
    --------
    >>> bands = decompose(np.ones(64), "haar")
    >>> [round(float(bands[b][0]), 3) for b in ("cA1", "cA3", "cD1")]
    [1.414, 2.828, 0.0]
    """
    w = check_wavelet(wavelet)
    a = np.asarray(x, dtype=np.float64)
    if pywt.dwt_max_level(a.size, w.dec_len) < LEVEL:
        raise Unavailable(f"{a.size} samples are too few for a level-{LEVEL} DWT with {wavelet}")
    ca3, cd3, cd2, cd1 = pywt.wavedec(a, w, mode=MODE, level=LEVEL)
    return {
        "cA1": np.asarray(pywt.downcoef("a", a, w, mode=MODE, level=1)),
        "cA2": np.asarray(pywt.downcoef("a", a, w, mode=MODE, level=2)),
        "cA3": np.asarray(ca3),
        "cD1": np.asarray(cd1),
        "cD2": np.asarray(cd2),
        "cD3": np.asarray(cd3),
    }


def summarise(coefficients: npt.ArrayLike) -> dict[str, float]:
    """The band summaries: ``mean``, ``energy`` (mean square) and signed ``peak``.

    Examples
    --------
    >>> summarise([1.0, -3.0, 2.0])
    {'mean': 0.0, 'energy': 4.666666666666667, 'peak': -3.0}
    """
    c = np.asarray(coefficients, dtype=np.float64)
    return {
        "mean": float(np.mean(c)),
        "energy": float(np.dot(c, c) / c.size),
        "peak": float(c[int(np.argmax(np.abs(c)))]),
    }


def _summaries(view: CycleView, act: str, signal: str, motion: str) -> dict[str, dict[str, float]]:
    key = ("dwt", act, signal, motion)
    if key not in view._cache:
        step = view.stroke(act, motion).step
        kind, side = signal.split("_")
        seg = view.window(f"{kind}_{act}_{side}", step.start_s, step.end_s)
        filled, _ = fill_gaps(seg)
        bands = decompose(filled, view.options.wavelet)
        view._cache[key] = {band: summarise(c) for band, c in bands.items()}
    out: dict[str, dict[str, float]] = view._cache[key]
    return out


_UNITS = {
    ("P", False): ("Pa", "Pa"),
    ("P", True): ("Pa^2", "Pa2"),
    ("Q", False): ("kg/s", "kg_s"),
    ("Q", True): ("(kg/s)^2", "kg2_s2"),
}


def _register(signal: str, motion: str, band: str, how: str) -> None:
    kind, side = signal.split("_")
    unit, suffix = _UNITS[(kind, how == "energy")]
    text = f"DWT {band} {how} of {kind}_<ACT>_{side} over the {motion} step [{unit}] (5.3.3)."

    @register(
        f"dwt_{signal}_{motion}_{band}_{how}_{suffix}",
        "actuator",
        unit,
        "wavelet",
        (f"{kind}_{{act}}_{side}",),
        description=text,
    )
    def feature(view: CycleView, act: str) -> float:
        return _summaries(view, act, signal, motion)[band][how]


for _s in SIGNALS:
    for _m in MOTIONS:
        for _b in BANDS:
            for _h in SUMMARIES:
                _register(_s, _m, _b, _h)
