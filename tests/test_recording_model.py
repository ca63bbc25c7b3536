"""The existing Recording model: channel access, to_pandas sample-and-hold, select, errors."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pytest

from pneufdd.errors import ChannelError, InputError, UnitError
from pneufdd.recording import Channel, Recording


def _rig() -> Recording:
    """20 ms of a 1 kHz pressure beside a 100 Hz valve signal (section 3.2.4 rates)."""
    return Recording.from_arrays(
        analog={"P_In": np.arange(20, dtype=np.float64) * 1000.0 + 6.0e5},
        analog_rate_hz=1000.0,
        digital={"U_DNC_A": np.array([0, 1], dtype=np.uint8)},
        digital_rate_hz=100.0,
        units={"P_In": "Pa"},
    )


def test_channel_returns_time_at_its_own_rate() -> None:
    rec = _rig()
    t_p, p = rec.channel("P_In")
    t_u, u = rec.channel("U_DNC_A")
    assert t_p.size == 20
    assert t_p[1] == 0.001
    assert t_u.tolist() == [0.0, 0.01]
    assert u.dtype == np.uint8
    assert p[19] == 619000.0
    assert not p.flags.writeable
    assert rec.rate("U_DNC_A") == 100.0
    assert rec.unit("U_DNC_A") == "1"
    assert rec.duration == 0.02


def test_to_pandas_holds_the_100_hz_channel_on_the_1_khz_base() -> None:
    frame = _rig().to_pandas()
    assert frame.index.name == "time_s"
    assert len(frame) == 20
    assert frame.index[10] == 0.01
    # sample and hold: the 100 Hz value at 0 s holds for 10 ms, the next from 10 ms on
    assert frame["U_DNC_A"].tolist() == [0.0] * 10 + [1.0] * 10
    assert frame["P_In"].iloc[7] == 607000.0


def test_to_pandas_with_offset_pads_with_nan() -> None:
    rec = Recording(
        [
            Channel("P_In", np.ones(20), 1000.0, "Pa"),
            Channel("S_DNC_B", np.array([1, 0], np.uint8), 100.0, "1", "digital", t0=0.005),
        ]
    )
    frame = rec.to_pandas()
    assert len(frame) == 25  # until the digital channel ends at 25 ms
    column = frame["S_DNC_B"].to_numpy()
    assert np.isnan(column[:5]).all()
    assert column[5:15].tolist() == [1.0] * 10
    assert column[15:].tolist() == [0.0] * 10
    assert np.isnan(frame["P_In"].to_numpy()[20:]).all()


def test_select_keeps_the_given_order_and_requires_channels() -> None:
    rec = _rig()
    picked = rec.select(["U_DNC_A", "P_In"])
    assert picked.channels == ("U_DNC_A", "P_In")
    with pytest.raises(ChannelError) as info:
        rec.select(["P_In", "Q_In"])
    assert str(info.value) == (
        "select needs channel(s) ['Q_In'] which the recording lacks; it has: ['P_In', 'U_DNC_A']"
    )


def test_require_names_purpose_and_missing_channels() -> None:
    rec = _rig()
    rec.require(["P_In"], "leak detection")  # present: no error
    with pytest.raises(
        ChannelError, match=r"leak detection needs channel\(s\) \['Q_In', 'P_DNC_A'\]"
    ):
        rec.require(["Q_In", "P_In", "P_DNC_A"], "leak detection")


def test_missing_channel_lists_those_present() -> None:
    with pytest.raises(ChannelError, match=r"received 'Q_In'; allowed: 'P_In', 'U_DNC_A'"):
        _rig().channel("Q_In")


def test_duplicate_channel_names_are_refused() -> None:
    channels = [
        Channel("P_In", np.ones(3), 1000.0, "Pa"),
        Channel("P_In", np.ones(3), 1000.0, "Pa"),
    ]
    with pytest.raises(ChannelError, match="duplicate channel name: received 'P_In'"):
        Recording(channels)


def test_units_must_be_si_and_known() -> None:
    with pytest.raises(UnitError, match=r"received 'bar'.*'Pa'"):
        Channel("P_In", np.ones(3), 1000.0, "bar")
    with pytest.raises(UnitError, match=r"unit of analog channel 'P_In'"):
        Recording.from_arrays({"P_In": np.ones(3)}, 1000.0)
    with pytest.raises(UnitError, match=r"digital channel 'U_DNC_A'"):
        Channel("U_DNC_A", np.ones(3, np.uint8), 100.0, "Pa", "digital")


def test_digital_values_must_be_zero_or_one() -> None:
    with pytest.raises(ChannelError, match="values of digital channel 'U_DNC_A'"):
        Channel("U_DNC_A", np.array([0, 2]), 100.0, "1", "digital")
    with pytest.raises(ChannelError):
        Channel("U_DNC_A", np.array([0.0, np.nan]), 100.0, "1", "digital")
    assert Channel("U", np.array([0.0, 1.0]), 100.0, "1", "digital").values.dtype == np.uint8


def test_rate_and_metadata_checks() -> None:
    with pytest.raises(ChannelError, match="sample rate"):
        Channel("P_In", np.ones(3), 0.0, "Pa")
    with pytest.raises(InputError, match="JSON"):
        Recording([], metadata={"x": float("nan")})


def test_naive_start_time_is_utc_and_default_marks_simulation() -> None:
    assert Recording([]).start_time == datetime(1970, 1, 1, tzinfo=UTC)
    naive = Recording([], start_time=datetime(2011, 6, 14, 9, 30))
    assert naive.start_time.tzinfo is UTC
