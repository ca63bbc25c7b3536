"""Debouncing and edge detection of digital channels."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pneufdd.errors import InputError
from pneufdd.signals.digital import debounce, debounced_edges, debounced_edges_many, edges


def _runs(x: np.ndarray) -> np.ndarray:
    starts = np.flatnonzero(np.r_[True, x[1:] != x[:-1]])
    return np.diff(np.r_[starts, x.size])


@given(st.lists(st.integers(0, 1), min_size=1, max_size=300), st.integers(1, 5))
def test_debounced_runs_last_at_least_the_dwell(bits: list[int], n: int) -> None:
    fs = 100.0
    y = debounce(bits, fs, n / fs)
    runs = _runs(y)
    # Every run after the first lasts at least the dwell, except a final run cut
    # by the end of the data.
    assert np.all(runs[1:-1] >= n)
    assert y.size == len(bits)
    # Debouncing is idempotent.
    assert np.array_equal(debounce(y, fs, n / fs), y)


def _debounce_by_the_rule(bits: list[int], min_run: int) -> list[int]:
    """The documented rule, run by run in plain Python (the oracle)."""
    runs: list[list[int]] = []  # [value, length]
    for b in bits:
        if runs and runs[-1][0] == b:
            runs[-1][1] += 1
        else:
            runs.append([b, 1])
    accepted = [k == 0 or length >= min_run for k, (_, length) in enumerate(runs)]
    out: list[int] = []
    for k, (value, length) in enumerate(runs):
        if not accepted[k]:
            later = [runs[j][0] for j in range(k + 1, len(runs)) if accepted[j]]
            earlier = [runs[j][0] for j in range(k) if accepted[j]]
            value = later[0] if later else earlier[-1]
        out += [value] * length
    return out


@given(st.lists(st.integers(0, 1), min_size=0, max_size=300), st.integers(0, 5))
def test_debounce_and_edges_follow_the_rule(bits: list[int], n: int) -> None:
    fs = 100.0
    expected = _debounce_by_the_rule(bits, n) if n else bits
    clean = debounce(bits, fs, n / fs)
    assert clean.tolist() == expected
    both, e = debounced_edges(bits, fs, n / fs)
    assert both.tolist() == expected
    up = [k for k in range(1, len(expected)) if expected[k - 1] == 0 and expected[k] == 1]
    down = [k for k in range(1, len(expected)) if expected[k - 1] == 1 and expected[k] == 0]
    assert e.rising.tolist() == up == edges(clean).rising.tolist()
    assert e.falling.tolist() == down == edges(clean).falling.tolist()


@given(
    st.integers(1, 6).flatmap(
        lambda rows: st.integers(0, 60).flatmap(
            lambda n: st.lists(
                st.lists(st.integers(0, 1), min_size=n, max_size=n), min_size=rows, max_size=rows
            )
        )
    ),
    st.integers(0, 5),
)
def test_many_channels_at_once_equal_one_at_a_time(bits: list[list[int]], n: int) -> None:
    fs = 100.0
    clean, found = debounced_edges_many(
        np.array(bits, dtype=np.uint8).reshape(len(bits), -1), fs, n / fs
    )
    assert clean.shape == (len(bits), len(bits[0]))
    for row, row_clean, e in zip(bits, clean, found, strict=True):
        one_clean, one = debounced_edges(row, fs, n / fs)
        assert row_clean.tolist() == one_clean.tolist()
        assert e.rising.tolist() == one.rising.tolist()
        assert e.falling.tolist() == one.falling.tolist()


def test_chatter_at_switch_arrival_is_removed() -> None:
    clean = np.r_[np.zeros(20), np.ones(30), np.zeros(20)].astype(np.uint8)
    noisy = clean.copy()
    noisy[20:24] = [1, 0, 1, 0]  # reed bounce on arrival, one sample each
    noisy[50:53] = [1, 0, 1]  # and on release
    y = debounce(noisy, 100.0, 0.025)
    e = edges(y)
    # The transitions are dated at the first contact / first release.
    assert e.rising.tolist() == [20]
    assert e.falling.tolist() == [51]


def test_zero_dwell_is_identity_and_bad_arguments_raise() -> None:
    x = np.array([0, 1, 0, 1], dtype=np.uint8)
    assert np.array_equal(debounce(x, 100.0, 0.0), x)
    with pytest.raises(InputError, match="min_dwell_s"):
        debounce(x, 100.0, -1.0)
    with pytest.raises(InputError, match="fs"):
        debounce(x, 0.0, 0.01)


def test_edges_of_constant_signal_are_empty() -> None:
    e = edges(np.ones(10, dtype=np.uint8))
    assert e.rising.size == 0
    assert e.falling.size == 0
