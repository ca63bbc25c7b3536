"""Compiled window summaries against the NumPy expressions they replace, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pneufdd.signals.windows import window_summaries


def _numpy_summaries(x: np.ndarray, s: np.ndarray, e: np.ndarray) -> np.ndarray:
    """A running sum and ``reduceat`` over ascending windows, as the step table did."""
    n = x.size
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf: NaN, as compiled
        csum = np.concatenate([[0.0], np.cumsum(x)])
        if not np.isfinite(csum[-1]):
            csum = np.concatenate([[0.0], np.cumsum(np.where(np.isnan(x), 0.0, x))])
        mean = (csum[e] - csum[s]) / (e - s)
    idx = np.stack([s, e], axis=1).ravel()
    idx[idx >= n] = n - 1
    lo = np.minimum.reduceat(x, idx)[0::2]
    hi = np.maximum.reduceat(x, idx)[0::2]
    return np.stack([mean, lo, hi], axis=-1)


values = st.one_of(
    st.floats(-1e6, 1e6),
    st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -0.0]),
)


@settings(max_examples=300)
@given(arrays(np.float64, st.integers(2, 200), elements=values), st.data())
def test_window_summaries_are_cumsum_and_reduceat(x: np.ndarray, data: st.DataObject) -> None:
    n = x.size
    cuts = sorted(data.draw(st.lists(st.integers(0, n), min_size=2, max_size=12)))
    s = np.array(cuts[:-1:2] if len(cuts) > 2 else cuts[:1], dtype=np.int64)
    e = np.array(cuts[1::2][: s.size], dtype=np.int64)
    s, e = s[: e.size], e[: s.size]
    # the step table's windows: at least one sample, inside the channel, ascending
    s = np.clip(s, 0, n - 1)
    e = np.maximum(np.clip(e, 1, n), s + 1)
    keep = np.concatenate([[True], s[1:] >= e[:-1]])
    s, e = s[keep], e[keep]
    got = window_summaries(x, s, e, np.minimum(e, n - 1))
    np.testing.assert_array_equal(got, _numpy_summaries(x, s, e))


def test_a_window_mean_min_and_max() -> None:
    x = np.array([1.0, 2.0, 3.0, 4.0, 10.0, np.nan, 7.0])
    got = window_summaries(x, np.array([0, 2]), np.array([2, 5]), np.array([2, 5]))
    assert got.tolist() == [[1.5, 1.0, 2.0], [17.0 / 3.0, 3.0, 10.0]]
    # a NaN in a window: its minimum and maximum are NaN, the means count it as 0
    got = window_summaries(x, np.array([4]), np.array([7]), np.array([6]))
    assert got[0, 0] == 17.0 / 3.0
    assert np.isnan(got[0, 1:]).all()
