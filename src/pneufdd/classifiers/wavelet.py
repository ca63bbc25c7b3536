"""Wavelet feature transformer (section 5.3.3): rows of samples -> DWT band summaries.

Each row of ``X`` is one signal segment (a step's pressure or flow samples, equally
spaced). It is decomposed to ``level`` (3 in the dissertation, Fig. 5.3) with the
mother wavelet ``wavelet``; every band (approximations cA1..cA_level, details
cD1..cD_level) is summarised by the statistics of
:func:`pneufdd.features.wavelet.summarise` (``mean``, ``energy``, ``peak``), which
are fixed in number whatever the segment's length. A segment shorter than the
wavelet needs for that level is extended symmetrically (the ``symmetric`` signal
extension PyWavelets uses at the borders), so that short inputs still give finite,
if border-dominated, coefficients.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pywt
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from pneufdd.array_types import FloatArray
from pneufdd.features.wavelet import SUMMARIES, summarise

__all__ = ["WaveletTransformer"]

MODE = "symmetric"


class WaveletTransformer(TransformerMixin, BaseEstimator):  # type: ignore[misc]
    """DWT band summaries of each row (section 5.3.3).

    Parameters
    ----------
    wavelet : str
        Discrete mother wavelet of PyWavelets (``db4``, ``haar``, ...).
    level : int
        Decomposition level (3 in the dissertation) [-].
    summaries : tuple of str
        Of ``mean``, ``energy``, ``peak``.

    Attributes
    ----------
    band_names_ : tuple of str
        ``cA1..cA<level>, cD1..cD<level>``.
    n_features_in_ : int
        Samples per row seen in ``fit``.

    Examples
    --------
    >>> wt = WaveletTransformer(wavelet="haar", summaries=("mean",)).fit(np.ones((1, 64)))
    >>> wt.get_feature_names_out()[:2].tolist()
    ['cA1_mean', 'cA2_mean']
    >>> np.round(wt.transform(np.ones((1, 64))), 3).tolist()
    [[1.414, 2.0, 2.828, 0.0, 0.0, 0.0]]
    """

    def __init__(
        self,
        wavelet: str = "db4",
        level: int = 3,
        summaries: tuple[str, ...] = ("mean", "energy", "peak"),
    ):
        self.wavelet = wavelet
        self.level = level
        self.summaries = summaries

    def _check(self) -> pywt.Wavelet:
        if self.wavelet not in pywt.wavelist(kind="discrete"):
            raise ValueError(f"wavelet: received {self.wavelet!r}; allowed: pywt.wavelist()")
        if isinstance(self.level, bool) or not isinstance(self.level, int) or self.level < 1:
            raise ValueError(f"level: received {self.level!r}; allowed: integer >= 1")
        bad = [s for s in self.summaries if s not in SUMMARIES]
        if bad or not self.summaries:
            raise ValueError(f"summaries: received {self.summaries!r}; allowed: {SUMMARIES}")
        return pywt.Wavelet(self.wavelet)

    def fit(self, X: npt.ArrayLike, y: object = None) -> WaveletTransformer:
        """Check the settings and remember the row length."""
        self._check()
        validate_data(self, X, dtype=np.float64)
        self.band_names_ = tuple(
            [f"cA{i}" for i in range(1, self.level + 1)]
            + [f"cD{i}" for i in range(1, self.level + 1)]
        )
        return self

    def _bands(self, row: FloatArray, w: pywt.Wavelet) -> list[FloatArray]:
        need = (w.dec_len - 1) * 2**self.level
        if row.size < need:
            row = np.pad(row, (0, need - row.size), mode="symmetric")
        coeffs = pywt.wavedec(row, w, mode=MODE, level=self.level)
        details = [np.asarray(c) for c in coeffs[:0:-1]]  # cD1 .. cD_level
        approx = [
            np.asarray(pywt.downcoef("a", row, w, mode=MODE, level=i)) for i in range(1, self.level)
        ] + [np.asarray(coeffs[0])]
        return approx + details

    def transform(self, X: npt.ArrayLike) -> FloatArray:
        """Band summaries of every row, in :meth:`get_feature_names_out` order."""
        check_is_fitted(self, "band_names_")
        w = self._check()
        data = validate_data(self, X, dtype=np.float64, reset=False)
        out = np.empty((data.shape[0], len(self.band_names_) * len(self.summaries)))
        for r, row in enumerate(data):
            values = [summarise(c) for c in self._bands(row, w)]
            out[r] = [v[s] for v in values for s in self.summaries]
        return out

    def get_feature_names_out(self, input_features: object = None) -> npt.NDArray[np.object_]:
        """``<band>_<summary>`` for every band and summary."""
        check_is_fitted(self, "band_names_")
        return np.asarray(
            [f"{b}_{s}" for b in self.band_names_ for s in self.summaries], dtype=object
        )
