"""Segmentation into cycles and steps (section 5.3.1.1, Fig. 3.4) on synthetic data."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pneufdd import Recording
from pneufdd.errors import ChannelError, InputError
from pneufdd.signals.segmentation import StepSpec, learn_sequence, segment
from synth import make_recording, valve_sets

MACHINE = [StepSpec(v) for v in valve_sets()]


def _starts(seg):
    return np.array([[s.start_s for s in c.steps] for c in seg.complete])


def test_100_cycles_58_steps_with_bounce_nan_and_truncation() -> None:
    rec, truth = make_recording(cycles=100, seed=3, bounce=True, nan_fraction=0.01)
    last = truth.step_starts[-1]
    cut, _ = make_recording(
        cycles=100, seed=3, bounce=True, nan_fraction=0.01, truncate_s=last[30] + 0.05
    )
    for r, complete in ((rec, 100), (cut, 99)):
        for seg in (segment(r, MACHINE), segment(r)):
            assert len(seg.complete) == complete
            assert all(len(c.steps) == 58 for c in seg.complete)
            # Step starts equal the true valve firings within one 100 Hz sample.
            err = np.abs(_starts(seg) - np.array(truth.step_starts[:complete]))
            assert err.max() <= 0.0100001
    seg = segment(cut, MACHINE)
    assert len(seg.rejected) == 1
    assert seg.rejected[0].reason == "truncated: the recording ends after step 31 of 58"


@settings(max_examples=12)
@given(
    seed=st.integers(0, 10_000),
    cycles=st.integers(2, 6),
    bounce=st.booleans(),
    nan_fraction=st.sampled_from([0.0, 0.01]),
    cut_step=st.integers(1, 57),
)
def test_segmentation_property(
    seed: int, cycles: int, bounce: bool, nan_fraction: float, cut_step: int
) -> None:
    _, truth = make_recording(cycles=cycles, seed=seed)
    rec, _ = make_recording(
        cycles=cycles,
        seed=seed,
        bounce=bounce,
        nan_fraction=nan_fraction,
        truncate_s=truth.step_starts[-1][cut_step] + 0.005,
    )
    seg = segment(rec, MACHINE)
    assert [len(c.steps) for c in seg.complete] == [58] * (cycles - 1)
    assert len(seg.rejected) == 1
    assert not seg.rejected[0].complete
    assert "truncated" in seg.rejected[0].reason or "recording ended" in seg.rejected[0].reason
    err = np.abs(_starts(seg) - np.array(truth.step_starts[: cycles - 1]))
    assert err.max() <= 0.0100001


def test_learned_sequence_equals_the_machine_sequence() -> None:
    rec, _ = make_recording(cycles=4, seed=1, bounce=True)
    learned = learn_sequence(rec)
    assert [s.valves for s in learned] == valve_sets()
    # DNC retracts in step 2 and extends in step 58: the learned awaited switches.
    assert ("S_DNC_A", 1) in learned[1].switches
    assert ("S_DNC_B", 1) in learned[57].switches
    assert ("S_DNC_B", 0) in learned[1].switches


def test_parallel_motions_form_one_step() -> None:
    rec, _ = make_recording(cycles=2, seed=2)
    step2 = segment(rec, MACHINE).complete[0].steps[1]
    assert step2.actuators == ("DNC", "DRQD", "HMPL_H")
    assert step2.motion("DNC") == "retract"
    assert step2.motion("HMPL_H") == "extend"


def test_stuck_switch_rejects_the_cycle_with_reason() -> None:
    _, truth = make_recording(cycles=4, seed=5)
    # S_DNC_A stuck at 0 during cycle 2: DNC never reports home in step 2.
    a, b = truth.step_starts[1][0], truth.step_starts[2][0]
    rec, _ = make_recording(cycles=4, seed=5, stuck=("S_DNC_A", 0, a, b))
    seg = segment(rec, MACHINE)
    assert [c.complete for c in seg.cycles] == [True, False, True, True]
    assert seg.cycles[1].reason == (
        "step 2: awaited switch S_DNC_A did not rise (stuck at 0 throughout the step)"
    )


def test_missing_step_is_not_merged() -> None:
    rec, truth = make_recording(cycles=4, seed=6)
    # Drop the valve firing of step 20 in cycle 2 (an aborted step).
    t = truth.step_starts[1][19]
    channels = []
    for name in rec.channels:
        ch = rec.info(name)
        if name in valve_sets()[19]:
            v = ch.values.copy()
            k = int(np.ceil(t * ch.rate_hz - 1e-9))
            v[k : k + 10] = 0
            ch = type(ch)(name, v, ch.rate_hz, ch.unit, ch.kind)
        channels.append(ch)
    seg = segment(Recording(channels, metadata=rec.metadata), MACHINE)
    assert [c.complete for c in seg.cycles] == [True, False, True, True]
    assert seg.cycles[1].reason.startswith("step 20: expected valves")
    assert len(seg.cycles[1].steps) == 57


def test_recording_starting_mid_cycle() -> None:
    rec, truth = make_recording(cycles=3, seed=7)
    t0 = truth.step_starts[0][10] - 0.01
    channels = []
    for name in rec.channels:
        ch = rec.info(name)
        k = round(t0 * ch.rate_hz)
        channels.append(type(ch)(name, ch.values[k:], ch.rate_hz, ch.unit, ch.kind))
    seg = segment(Recording(channels), MACHINE)
    assert [c.complete for c in seg.cycles] == [False, True, True]
    assert seg.cycles[0].reason.startswith("recording starts mid-cycle")


def test_to_dict_is_the_documented_json() -> None:
    rec, _ = make_recording(cycles=2, seed=8, truncate_s=None)
    d = json.loads(json.dumps(segment(rec, MACHINE).to_dict()))
    assert set(d) == {"cycles", "rejected"}
    c = d["cycles"][0]
    assert set(c) == {"index", "complete", "steps"}
    assert set(c["steps"][0]) == {"index", "start_s", "duration_s", "actuators"}
    assert c["steps"][1]["actuators"] == ["DNC", "DRQD", "HMPL_H"]


def test_errors_name_what_is_needed() -> None:
    rec = Recording.from_arrays({"P_In": np.ones(100)}, 1000.0, units={"P_In": "Pa"})
    with pytest.raises(ChannelError, match=r"U_<ACT>_A/B.*P_In"):
        segment(rec)
    quiet = Recording.from_arrays(
        {}, 1000.0, digital={"U_DNC_A": np.zeros(50, np.uint8)}, digital_rate_hz=100.0
    )
    with pytest.raises(InputError, match="valve firing"):
        segment(quiet)
    rec2, _ = make_recording(cycles=2)
    with pytest.raises(ChannelError, match="U_XYZ_A"):
        segment(rec2, [StepSpec(frozenset({"U_XYZ_A"}))])
    pulses = np.zeros((4, 100), dtype=np.uint8)
    for i in range(4):
        pulses[i, 10 + 20 * i : 15 + 20 * i] = 1
    distinct = Recording.from_arrays(
        {}, 1000.0, digital={f"U_A{i}_A": pulses[i] for i in range(4)}, digital_rate_hz=100.0
    )
    with pytest.raises(InputError, match="repeating pattern"):
        learn_sequence(distinct)


def test_release_of_a_held_valve_starts_a_step() -> None:
    rec, truth = make_recording(cycles=3, seed=11)
    from pneufdd.signals.segmentation import held_valves

    assert held_valves(rec) == frozenset({"U_VAC"})
    seg = segment(rec)
    step = seg.complete[0].steps[55]
    assert step.valves == ("U_VAC:off",)
    assert step.actuators == ("VAC",)
    assert abs(step.start_s - truth.step_starts[0][55]) <= 0.0100001


def test_sequence_from_a_machine_description_in_metadata() -> None:
    from pneufdd.signals.segmentation import sequence_from_machine

    rec, _ = make_recording(cycles=3, seed=12)
    raw = _toy_description()
    seq = sequence_from_machine(raw)
    assert [s.valves for s in seq] == valve_sets()
    assert seq[1].switches == {("S_DNC_A", 1), ("S_DRQD_A", 1), ("S_HMPL_H_B", 1)}
    described = rec.with_metadata({"machine": {"name": "toy", "description": raw}})
    seg = segment(described)
    assert seg.source == "machine"
    assert len(seg.complete) == 3
    with pytest.raises(InputError, match="machine"):
        sequence_from_machine(42)


def _toy_description() -> dict[str, list[dict[str, list[dict[str, str]]]]]:
    """The raw TOML mapping of the synthetic machine: set until the far switch, or reset."""
    steps = []
    for valves in valve_sets():
        do = []
        for v in sorted(valves):
            if v.endswith(":off"):
                do.append({"reset": v[:-4]})
            elif v == "U_VAC":
                do.append({"set": v})
            else:
                act, side = v[2:-2], v[-1]
                do.append({"set": v, "until": f"S_{act}_{'B' if side == 'A' else 'A'}"})
        steps.append({"do": do})
    return {"step": steps}


def test_plc_sequence_precedence_given_then_carried_then_learned() -> None:
    from pneufdd.signals.segmentation import plc_sequence

    rec, _ = make_recording(cycles=4, seed=1, bounce=True)
    raw = _toy_description()
    described = rec.with_metadata({"machine": {"name": "toy", "description": raw}})
    # 3. learned: step 2 (DNC retracts) also awaits S_DNC_B falling, seen in every cycle
    learned = plc_sequence(rec)
    assert [s.valves for s in learned] == valve_sets()
    assert {("S_DNC_A", 1), ("S_DNC_B", 0)} <= learned[1].switches
    assert learned == learn_sequence(rec)
    # 2. the carried description beats learning: only the `until` switches rising
    carried = plc_sequence(described)
    assert [s.valves for s in carried] == valve_sets()
    assert carried[1].switches == {("S_DNC_A", 1), ("S_DRQD_A", 1), ("S_HMPL_H_B", 1)}
    assert plc_sequence(described, carried=False) == learned
    # 1. a description or a sequence given beats the carried one
    only_valves = plc_sequence(described, MACHINE)
    assert only_valves == tuple(MACHINE)
    assert only_valves[1].switches == frozenset()
    short = {"step": raw["step"][:2]}
    assert [s.valves for s in plc_sequence(described, short)] == valve_sets()[:2]
    assert plc_sequence(machine=raw) == carried
    # segment() follows the same order and says where the sequence came from
    assert (segment(rec).source, segment(described).source) == ("learned", "machine")
    assert [s.valves for s in segment(described).sequence] == valve_sets()
    assert segment(described).sequence[1].switches == carried[1].switches
    with pytest.raises(InputError, match="neither a machine nor a recording"):
        plc_sequence()
    with pytest.raises(InputError, match="MachineDescription"):
        plc_sequence(rec, 42)  # type: ignore[arg-type]
