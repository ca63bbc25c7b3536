"""Feature functions and the feature matrix on synthetic recordings with known values."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import pywt

from pneufdd import Recording
from pneufdd.errors import ChannelError, InputError, NoCompleteCycleError, UnitError
from pneufdd.features import (
    REGISTRY,
    TABLE_4_5,
    TABLE_44_NAMES,
    Options,
    feature_matrix,
    features_of,
    get,
)
from pneufdd.features.air import kg_to_sl
from pneufdd.signals import segment
from synth import BUMP_TAIL, P_SUPPLY, SLPM, T_P, make_recording


@pytest.fixture(scope="module")
def run():
    rec, truth = make_recording(cycles=8, seed=4)
    return rec, truth, feature_matrix(rec)


def test_stroke_times_match_ground_truth_within_10_ms(run) -> None:
    _, truth, df = run
    for motion, true in (("extend", truth.dnc_extend), ("retract", truth.dnc_retract)):
        # Cycle k's retract (step 2) and extend (step 58) are the k-th strokes.
        t_s = np.array([b - a for a, b in true])[: len(df)]
        assert np.max(np.abs(df[f"DNC.t_s_{motion}_s"].to_numpy() - t_s)) < 0.010
        assert np.max(np.abs(df[f"DNC.t_p_{motion}_s"].to_numpy() - T_P)) < 0.010
        total = df[f"DNC.t_p_{motion}_s"] + df[f"DNC.t_s_{motion}_s"]
        assert np.allclose(df[f"DNC.t_o_{motion}_s"], total)
    assert np.array_equal(df["DNC.t44_12_t_s_extend_s"], df["DNC.t_s_extend_s"])
    assert np.array_equal(df["DNC.t44_13_t_s_retract_s"], df["DNC.t_s_retract_s"])


def test_velocities_follow_eq_3_1(run) -> None:
    _, truth, df = run
    t_s = np.array([b - a for a, b in truth.dnc_extend])[: len(df)]
    # The toy profile's peak speed is stroke / (0.79 t_s); balancing speed the same.
    v_peak = 0.2 / (0.79 * t_s)
    # The peak picks up the residual noise of the filtered derivative (a few %).
    assert np.allclose(df["DNC.v_max_extend_m_s"], v_peak, rtol=0.06)
    assert np.all(df["DNC.v_max_extend_m_s"] >= df["DNC.v_balance_extend_m_s"])
    assert np.allclose(df["DNC.v_balance_extend_m_s"], v_peak, rtol=0.02)
    # Retract speeds are positive magnitudes too.
    assert np.all(df["DNC.v_max_retract_m_s"] > 0.4)


def test_air_per_stroke_is_the_integral_of_the_flow_bump(run) -> None:
    rec, truth, df = run
    t0, t1 = np.array(truth.dnc_extend[: len(df)]).T
    duration = t1 - t0 + T_P + BUMP_TAIL
    # Half-sine of 150 SLPM: 150 / 60 * 2 / pi * duration standard litres (eq. 4.17).
    expected = 150.0 / 60.0 * 2.0 / np.pi * duration
    assert np.allclose(df["DNC.air_extend_SL"], expected, rtol=0.01)
    assert np.allclose(df["DNC.t44_06_air_a_extend_SL"], expected, rtol=0.01)
    assert np.allclose(df["DNC.t44_07_exhaust_b_extend_SL"], 0.8 * expected, rtol=0.01)
    # Maximum exhaust flow: 0.8 x 150 SLPM.
    assert np.allclose(df["DNC.t44_11_exhaust_flow_max_b_extend_kg_s"], 120 * SLPM, rtol=0.01)
    # Minimum supply pressure of the extend step (step 58): the toy supply line
    # drops 2e7 Pa per kg/s of (noise-free) supply flow; P_In has 200 Pa noise.
    t, q = rec.channel("Q_In")
    p_min = [
        P_SUPPLY - 2.0e7 * q[(t >= s.start_s) & (t < s.end_s)].max()
        for s in (c.steps[57] for c in segment(rec).complete)
    ]
    assert np.allclose(df["DNC.p_supply_min_extend_Pa"], p_min, atol=1500.0)
    # Per-step air adds up to the cycle's air.
    steps = df.filter(regex=r"^step\d\d\.air_SL$")
    assert steps.shape[1] == 58
    assert np.allclose(steps.sum(axis=1), df["air_cycle_SL"], rtol=1e-3)


def test_kg_to_sl_uses_the_dissertation_basis() -> None:
    assert kg_to_sl(1.294e-3) == pytest.approx(1.0)


def test_wavelet_features_equal_pywavelets(run) -> None:
    rec, _, df = run
    step = segment(rec).complete[0].steps[57]
    t, p = rec.channel("P_DNC_A")
    x = p[(t >= step.start_s - 1e-9) & (t < step.end_s - 1e-9)]
    ca3, cd3, _, cd1 = pywt.wavedec(x, "db4", mode="symmetric", level=3)
    row = df.iloc[0]
    assert row["DNC.dwt_P_A_extend_cA3_energy_Pa2"] == pytest.approx(np.mean(ca3**2))
    assert row["DNC.dwt_P_A_extend_cD1_mean_Pa"] == pytest.approx(np.mean(cd1), abs=1e-6)
    assert row["DNC.dwt_P_A_extend_cD3_peak_Pa"] == pytest.approx(cd3[np.argmax(np.abs(cd3))])
    ca1 = pywt.dwt(x, "db4", mode="symmetric")[0]
    assert row["DNC.dwt_P_A_extend_cA1_mean_Pa"] == pytest.approx(np.mean(ca1))
    haar = feature_matrix(rec, groups=["wavelet"], options=Options(wavelet="haar"))
    assert haar.attrs["wavelet"] == "haar"
    assert not np.isclose(
        haar.iloc[0]["DNC.dwt_P_A_extend_cA3_energy_Pa2"], np.mean(ca3**2), rtol=1e-6
    )
    with pytest.raises(InputError, match="wavelet"):
        feature_matrix(rec, groups=["wavelet"], options=Options(wavelet="nope"))


def test_registry_has_stable_documented_names() -> None:
    names = set(REGISTRY)
    assert set(TABLE_44_NAMES) <= names
    assert len(TABLE_44_NAMES) == 13
    for motion in ("extend", "retract"):
        for stem in ("t_p", "t_s", "t_o"):
            assert get(f"{stem}_{motion}_s").unit == "s"
        assert get(f"v_max_{motion}_m_s").unit == "m/s"
        assert get(f"exhaust_flow_max_{motion}_kg_s").unit == "kg/s"
        assert get(f"air_{motion}_SL").unit == "SL"
        for side in "AB":
            assert get(f"p_balance_{side}_{motion}_Pa").unit == "Pa"
    assert len(features_of(["wavelet"])) == 4 * 2 * 6 * 3
    for f in REGISTRY.values():
        assert f.description, f.name
        unit_tag = {"SL": "_SL", "Pa": "_Pa", "s": "_s", "m/s": "_m_s", "kg/s": "_kg_s"}
        if f.unit in unit_tag:
            assert f.name.endswith(unit_tag[f.unit]), f.name
    assert {k: len(v) for k, v in TABLE_4_5.items()} == dict.fromkeys(TABLE_4_5, 13)
    with pytest.raises(InputError, match="feature"):
        get("no_such_feature")
    with pytest.raises(InputError, match="feature groups"):
        features_of(["bogus"])


def test_labels_come_from_metadata() -> None:
    a, _ = make_recording(cycles=3, seed=1)
    b, _ = make_recording(cycles=3, seed=2, leaks={"DNC_B": 4, "supply": 2})
    df = feature_matrix([a, b], groups=["motion"])
    assert df.index.names == ["recording", "cycle"]
    by_rec = df.groupby(level="recording")
    assert by_rec["leak_DNC_B"].first().tolist() == [0.0, 4.0]
    assert by_rec["leak_supply"].first().tolist() == [0.0, 2.0]
    assert by_rec["leak_class"].first().tolist() == ["none", "DNC_B+supply"]
    assert list(df.columns[-3:]) == ["leak_DNC_B", "leak_supply", "leak_class"]


def test_forward_only_meters_give_nan_exhaust_with_reason() -> None:
    rec, _ = make_recording(cycles=3, seed=1, forward_only=True)
    df = feature_matrix(rec, groups=["table44", "motion"])
    for col in ("DNC.t44_07_exhaust_b_extend_SL", "DNC.t44_10_exhaust_flow_max_a_retract_kg_s"):
        assert df[col].isna().all()
        assert "forward flow only" in df.attrs["nan_reasons"][col]
    assert df["DNC.t44_06_air_a_extend_SL"].notna().all()
    # Without the metadata declaration the direction is inferred from the data.
    inferred = feature_matrix(rec.with_metadata({}), groups=["table44"])
    assert inferred["DNC.t44_07_exhaust_b_extend_SL"].isna().all()


def test_without_lvdt_stroke_times_come_from_switches() -> None:
    rec, truth = make_recording(cycles=3, seed=1)
    no_x = rec.select([n for n in rec.channels if n != "X_DNC"])
    df = feature_matrix(no_x, groups=["table44"])
    t_s = np.array([b - a for a, b in truth.dnc_extend])[: len(df)]
    # Switch times are 100 Hz samples; the home switch releases 4 ms into the travel.
    assert np.max(np.abs(df["DNC.t44_12_t_s_extend_s"] - t_s)) < 0.015
    with pytest.raises(ChannelError, match=r"X_DNC.*which the recording lacks"):
        feature_matrix(no_x, groups=["motion"])
    lenient = feature_matrix(no_x, groups=["motion"], on_missing="nan")
    assert lenient["DNC.v_max_extend_m_s"].isna().all()
    assert lenient["DNC.t_s_extend_s"].notna().all()
    assert "X_DNC" in lenient.attrs["nan_reasons"]["DNC.v_max_extend_m_s"]


def test_nan_gaps_and_wrong_units() -> None:
    rec, _ = make_recording(cycles=4, seed=9, nan_fraction=0.01)
    df = feature_matrix(rec, groups=["table44", "air"])
    assert df["DNC.t44_06_air_a_extend_SL"].notna().mean() >= 0.75
    assert df["DNC.t44_12_t_s_extend_s"].notna().all()
    # A channel that is mostly NaN inside a window gives NaN and the reason.
    ch = rec.info("Q_DNC_A")
    v = ch.values.copy()
    v[: v.size // 2] = np.nan
    gappy = Recording(
        [
            ch if n != "Q_DNC_A" else type(ch)(n, v, ch.rate_hz, ch.unit)
            for n, ch in ((n, rec.info(n)) for n in rec.channels)
        ],
        metadata=rec.metadata,
    )
    # The gap rule (issue 14, docs/data-quality.md): a gap longer than 0.05 s skips
    # the cycles it touches; with 3 of 4 cycles gone the recording is refused, naming
    # the channel.
    with pytest.raises(NoCompleteCycleError, match=r"Q_DNC_A.*3 of 4"):
        feature_matrix(gappy, groups=["table44"])
    # A gap inside the last cycle only skips that cycle, reported with its channel.
    last = rec.info("Q_DNC_A")
    w = last.values.copy()
    w[-int(0.5 * last.rate_hz) :] = np.nan
    tail = Recording(
        [
            rec.info(n) if n != "Q_DNC_A" else type(last)(n, w, last.rate_hz, last.unit)
            for n in rec.channels
        ],
        metadata=rec.metadata,
    )
    df2 = feature_matrix(tail, groups=["table44"])
    gap_rows = [r for r in df2.attrs["rejected"] if "Q_DNC_A" in r["reason"]]
    assert len(df2) + len(gap_rows) == len(df)
    assert len(gap_rows) == 1
    # A pressure channel in volts is refused, naming the channel.
    chans = [rec.info(n) for n in rec.channels if n != "P_DNC_A"]
    p = rec.info("P_DNC_A")
    volts = Recording([*chans, type(p)("P_DNC_A", p.values / 1e5, p.rate_hz, "V")])
    with pytest.raises(UnitError, match=r"P_DNC_A.*'V'.*'Pa'"):
        feature_matrix(volts, groups=["table44"])


def test_feature_matrix_input_checks() -> None:
    with pytest.raises(InputError, match="recordings"):
        feature_matrix([])
    rec, _ = make_recording(cycles=2)
    with pytest.raises(InputError, match="on_missing"):
        feature_matrix(rec, on_missing="skip")
    assert isinstance(feature_matrix(rec, groups=["air"]), pd.DataFrame)
