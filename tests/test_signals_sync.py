"""Synchronisation (Figs. 5.6 -> 5.7) and ensemble statistics (eq. 5.21)."""

from __future__ import annotations

import numpy as np
import pytest

from pneufdd import Recording
from pneufdd.errors import InputError
from pneufdd.signals import (
    align_cycles,
    ensemble,
    reference_lengths,
    sample_bounds,
    segment,
    select_window,
    step_ensembles,
    synchronise,
)
from synth import SLPM, make_recording


@pytest.fixture(scope="module")
def runs():
    ref, _ = make_recording(cycles=20, seed=1)
    leak, _ = make_recording(cycles=20, seed=2, leaks={"DNC_B": 4, "supply": 2})
    sref = segment(ref)
    sleak = segment(leak, sref.sequence)
    return ref, sref, leak, sleak


def test_fig_5_6_raw_difference_negative_and_fig_5_7_synchronised_positive(runs) -> None:
    ref, sref, leak, sleak = runs
    raw_ref = ensemble(align_cycles(ref, "Q_In", sref.complete)).mean
    raw_leak = ensemble(align_cycles(leak, "Q_In", sleak.complete)).mean
    s, e = sample_bounds(sref.complete, 1000.0)
    a = int(np.median(s[:, 2] - s[:, 0]))
    b = int(np.median(e[:, 2] - s[:, 0]))
    raw = (raw_leak[a:b] - raw_ref[a:b]) / SLPM
    assert raw.min() < -10.0  # Fig. 5.6: the lag makes the leaky run look smaller
    ref3 = step_ensembles(ref, "Q_In", sref.complete)[2].mean
    leak3 = step_ensembles(leak, "Q_In", sleak.complete)[2].mean
    n = min(ref3.size, leak3.size)
    synced = (leak3[:n] - ref3[:n]) / SLPM
    # Fig. 5.7: after synchronisation the difference is never negative and is
    # dominated by the supply leak (20 SLPM per turn in the toy data, 2 turns); the
    # slower motions of the leaky run shift it by a few SLPM.
    assert np.nanmin(synced) > 0.0
    assert abs(np.nanmedian(synced) - 40.0) < 8.0


def test_synchronised_steps_start_at_their_valve_firing(runs) -> None:
    _, _, leak, sleak = runs
    steps = synchronise(leak, "Q_In", sleak.complete)
    assert len(steps) == 58
    assert steps[2].shape[0] == 20
    # Row lengths (non-NaN) are each cycle's own step-3 length.
    s, e = sample_bounds(sleak.complete, 1000.0)
    assert np.array_equal(np.isfinite(steps[2]).sum(axis=1), e[:, 2] - s[:, 2])


def test_time_normalisation_to_reference_lengths(runs) -> None:
    _ref, sref, leak, sleak = runs
    n = reference_lengths(sref.complete, 1000.0)
    steps = synchronise(leak, "Q_In", sleak.complete, lengths=n)
    assert [a.shape[1] for a in steps] == n.tolist()
    # Resampling keeps the end points of each step.
    x = leak.channel("Q_In")[1]
    s, e = sample_bounds(sleak.complete, 1000.0)
    assert np.allclose(steps[5][:, 0], x[s[:, 5]])
    assert np.allclose(steps[5][:, -1], x[e[:, 5] - 1])
    with pytest.raises(InputError, match="lengths"):
        synchronise(leak, "Q_In", sleak.complete, lengths=[10, 20])


def test_ensemble_matches_numpy_on_full_columns_and_counts_ragged() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 30))
    e = ensemble(a)
    assert np.allclose(e.mean, a.mean(axis=0))
    assert np.allclose(e.std, a.std(axis=0))
    e1 = ensemble(a, ddof=1)
    assert np.allclose(e1.std, a.std(axis=0, ddof=1))
    a[10:, 20:] = np.nan  # ragged: only 10 cycles are that long
    e = ensemble(a)
    assert e.count[25] == 10
    assert e.mean[25] == pytest.approx(a[:10, 25].mean())
    empty = ensemble(np.full((3, 4), np.nan))
    assert np.all(np.isnan(empty.mean))
    assert np.all(empty.count == 0)
    with pytest.raises(InputError, match="stack shape"):
        ensemble(np.zeros(3))


def test_averaging_window_of_section_4_4_1(runs) -> None:
    _, sref, _, _ = runs
    cycles = sref.complete
    total = cycles[-1].end_s - cycles[0].start_s
    last = select_window(cycles, total / 2)
    first = select_window(cycles, total / 2, which="first")
    assert 0 < len(last) < len(cycles)
    assert all(c.start_s >= cycles[-1].end_s - total / 2 for c in last)
    assert all(c.end_s <= cycles[0].start_s + total / 2 for c in first)
    assert len(select_window(cycles, None)) == len(cycles)
    with pytest.raises(InputError, match="which"):
        select_window(cycles, 10.0, which="middle")


def test_missing_channel_is_named(runs) -> None:
    ref, sref, _, _ = runs
    bare = Recording([ref.info(n) for n in ref.digital_channels])
    with pytest.raises(InputError, match=r"Q_In.*U_DNC_A"):
        synchronise(bare, "Q_In", sref.complete)


def test_reference_averages_use_the_window_and_every_channel(runs) -> None:
    from pneufdd.signals import reference_averages

    ref, sref, _, _ = runs
    cycles = sref.complete
    total = cycles[-1].end_s - cycles[0].start_s
    avg = reference_averages(ref, ["Q_In", "P_In"], cycles, window_s=total / 2)
    assert set(avg) == {"Q_In", "P_In"}
    assert len(avg["Q_In"]) == 58
    n_last = len(select_window(cycles, total / 2))
    assert avg["Q_In"][2].count.max() == n_last < len(cycles)
    # Equal to eq. 5.21 computed directly on the same synchronised cycles.
    direct = step_ensembles(ref, "P_In", select_window(cycles, total / 2))[10]
    assert np.array_equal(avg["P_In"][10].mean, direct.mean, equal_nan=True)
    with pytest.raises(InputError, match="averaging window"):
        reference_averages(ref, ["Q_In"], cycles, window_s=1e-3)
