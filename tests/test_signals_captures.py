"""Segmentation and draft robust to how recordings start and end (issue 33, item 3)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pneufdd.calibration.draft import draft_machine
from pneufdd.errors import InputError
from pneufdd.recording.model import Channel, Recording
from pneufdd.signals.events import StepSpec
from pneufdd.signals.quantisation import QUANTISATION_NOISE, channel_quanta, quantum
from pneufdd.signals.segmentation import learn_sequence, segment
from pneufdd.sim import as_exported, simulate
from pneufdd.sim.captures import quantize, simulate_captures

RIG = Path(__file__).parent / "data" / "triggered-rig.toml"


def _join(recs: list[Recording]) -> Recording:
    """Captures pasted end to end, as a user joins files by hand."""
    chans = []
    for name in recs[0].channels:
        i = recs[0].info(name)
        values = np.concatenate([r.info(name).values for r in recs])
        chans.append(Channel(name, values, i.rate_hz, i.unit, i.kind, i.t0))
    return as_exported(Recording(chans, metadata=recs[0].metadata))


@pytest.fixture(scope="module")
def captures() -> list[Recording]:
    # 2.6 s: each capture ends in the retract step's dwell, before the next trigger
    caps = simulate_captures(RIG, files=3, pre_trigger_s=0.2, capture_s=2.6, seed=4)
    return [quantize(c, {"P_In": 19_000.0}) for c in caps]


def test_solenoid_held_at_start_is_not_a_firing(captures: list[Recording]) -> None:
    for cap in captures:
        assert cap.channel("U_CYL_B")[1][0] == 1
        for rec in (cap, as_exported(cap)):  # described sequence; and as an export
            seg = segment(rec, None if rec is cap else segment(cap).sequence)
            first = seg.cycles[0]
            assert first.complete, first.reason
            assert first.steps[0].start_s == pytest.approx(0.2, abs=0.011)
            assert [c.complete for c in seg.cycles] == [True]


def test_joined_captures_learn_and_draft_the_right_steps(captures: list[Recording]) -> None:
    joined = _join(captures)
    seq = learn_sequence(joined)
    assert [sorted(s.valves) for s in seq] == [["U_CYL_A"], ["U_CYL_B"]]
    seg = segment(joined, seq)
    assert sum(c.complete for c in seg.cycles) == 3
    toml = draft_machine([joined]).to_toml()
    step1 = toml[toml.index("[[step]]  # 1") : toml.index("[[step]]  # 2")]
    assert 'set = "U_CYL_A"' in step1
    assert 'reset = "U_CYL_B"' in step1
    assert "dwell_s = 0.5" in step1  # the twin's 0.5 s (was 'set U_CYL_B, dwell 5.0 s')
    noise = float(toml.split('channel = "P_In"')[1].split("noise = ")[1].split()[0])
    assert noise >= 0.19 * QUANTISATION_NOISE - 1e-4  # bar: never below the quantum's


def test_draft_from_separate_one_cycle_captures(captures: list[Recording]) -> None:
    exported = [as_exported(c) for c in captures]
    toml = draft_machine(exported).to_toml()
    step1 = toml[toml.index("[[step]]  # 1") : toml.index("[[step]]  # 2")]
    assert 'set = "U_CYL_A"' in step1
    assert 'wait = ["S_CYL_B"]' in step1
    with pytest.raises(InputError, match="repeating pattern"):
        draft_machine(exported[:1])


def test_changeover_over_two_plc_scans_is_one_step() -> None:
    """1 kHz digital: the held solenoid is released one scan (5 ms) before the other fires."""
    n = 4000
    a = np.zeros(n, dtype=np.uint8)
    b = np.zeros(n, dtype=np.uint8)
    s_a = np.zeros(n, dtype=np.uint8)
    s_b = np.zeros(n, dtype=np.uint8)
    b[:500] = 1  # retract solenoid held from before the recording
    s_a[:700] = 1
    a[505:1500] = 1  # extend 5 ms after the release of B
    s_b[900:1700] = 1
    b[1500:2500] = 1  # changeover at one sample
    s_a[1900:2700] = 1
    a[2505:3500] = 1
    s_b[2900:3700] = 1
    b[3500:] = 1
    s_a[3900:] = 1
    digital = {"U_CYL_A": a, "U_CYL_B": b, "S_CYL_A": s_a, "S_CYL_B": s_b}
    rec = Recording.from_arrays(
        {"P_In": np.full(n, 6e5)}, 1000.0, digital, 1000.0, units={"P_In": "Pa"}
    )
    seq = (
        StepSpec(frozenset({"U_CYL_A", "U_CYL_B:off"}), frozenset({("S_CYL_B", 1)})),
        StepSpec(frozenset({"U_CYL_B", "U_CYL_A:off"}), frozenset({("S_CYL_A", 1)})),
    )
    seg = segment(rec, seq)
    starts = [round(s.start_s, 3) for c in seg.cycles for s in c.steps]
    assert starts == [0.505, 1.5, 2.505, 3.5]  # the release joins the firing: 4 steps, not 6
    assert [c.complete for c in seg.cycles][:1] == [True]
    learned = learn_sequence(rec)
    assert [sorted(s.valves) for s in learned] == [["U_CYL_A"], ["U_CYL_B"]]


def test_capture_ending_mid_step_rejects_only_its_fragment() -> None:
    caps = simulate_captures(RIG, files=2, pre_trigger_s=0.2, seed=5)  # ends in the next cycle
    for cap in caps:
        seg = segment(cap)
        assert [c.complete for c in seg.cycles] == [True, False]
        assert "truncated" in str(seg.cycles[1].reason)


def test_quantum_detected_only_where_it_is_coarser_than_the_noise() -> None:
    run = simulate("press-fit-cell", cycles=2, seed=1)
    assert channel_quanta([run]) == {}  # 12-bit sensors: resolution below the noise
    rough = quantize(run, {"P_In": 19_000.0, "Q_In": 1e-4})
    found = channel_quanta([rough])
    assert found["P_In"] == pytest.approx(19_000.0)
    assert quantum(np.zeros(100)) == 0.0
