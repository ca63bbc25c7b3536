"""End-to-end engine on the synthetic machine: detect, locate, size, false alarms."""

from __future__ import annotations

import numpy as np
import pytest

from _diag_synth import LOCATIONS, synth_signatures, synth_table
from pneufdd.diagnosis.cost import (
    COST_BASIS_AVERAGE,
    COST_BASIS_CONTINUOUS,
    CostSettings,
    annual_cost,
)
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.findings import LeakFinding
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import ChannelError, InputError, MachineError
from pneufdd.location import Location
from pneufdd.physics.units import kg_s_to_slpm


@pytest.fixture(scope="module")
def reference():
    return ReferenceModel.build(synth_table(60, seed=100), signatures=synth_signatures())


@pytest.fixture(scope="module")
def supply_only():
    return ReferenceModel.build(
        synth_table(60, seed=100), channels=["P_In", "Q_In"], signatures=synth_signatures()
    )


def test_leak_free_runs_are_quiet(reference):
    flagged = [diagnose(reference, synth_table(10, seed=1000 + s)).detected for s in range(60)]
    assert sum(flagged) <= 1
    assert 0.0 <= reference.detector.reference_false_alarm_rate_ <= 0.05


def test_supply_fluctuation_alone_does_not_alarm(reference):
    # a run whose house air sits 2.5 reference standard deviations off for all its
    # cycles (section 4.4.1): every pressure, flow and duration moves together
    for offset in (-2.5, 2.5):
        run = synth_table(10, seed=7, fluctuation=0.2, level_offset=offset)
        assert not diagnose(reference, run).detected
    # the same run without the projection of the fluctuation would alarm
    det = reference.detector
    run = synth_table(10, seed=7, fluctuation=0.2, level_offset=2.5)
    z = det.standardize(run.features())
    assert np.mean(z**2) > 3.0 * det.run_threshold(10)


@pytest.mark.parametrize("location", LOCATIONS)
def test_single_leak_located_and_sized(reference, location):
    size = 5e-4
    result = diagnose(reference, synth_table(10, {location: size}, seed=42))
    assert result.detected
    assert len(result.leaks) == 1
    (leak,) = result.leaks
    assert str(leak.location) == location
    assert leak.mass_flow == pytest.approx(size, rel=0.1)
    assert leak.ambiguity_group == (Location.parse(location),)


def test_two_simultaneous_leaks(reference):
    truth = {"supply": 6.5e-4, "X_B": 1.2e-3}  # the 5.3.1.5 pattern: supply + rod side
    result = diagnose(reference, synth_table(10, truth, seed=43))
    found = {str(leak.location): leak.mass_flow for leak in result.leaks}
    assert found.keys() == truth.keys()
    for loc, size in truth.items():
        assert found[loc] == pytest.approx(size, rel=0.1)
    assert result.total_annual_cost == pytest.approx(sum(x.annual_cost for x in result.leaks))
    assert result.leaks[0].annual_cost >= result.leaks[1].annual_cost


def test_supply_only_sensor_set_groups_what_it_cannot_separate(supply_only):
    # With P_In and Q_In only, X_A and a supply leak differ only by which steps carry
    # the extra flow; that is still visible. The engine must at least contain the
    # true location in the reported group.
    for location in LOCATIONS:
        result = diagnose(supply_only, synth_table(10, {location: 8e-4}, seed=44))
        assert result.detected
        assert Location.parse(location) in result.leaks[0].ambiguity_group


def test_json_has_required_fields(reference):
    result = diagnose(
        reference, synth_table(10, {"X_A": 7e-4}, seed=45), CostSettings(hours=4000.0)
    )
    data = result.to_dict()
    assert data["detected"] is True
    assert data["cycles_analyzed"] == 10
    (leak,) = data["leaks"]
    assert set(leak) == {
        "location",
        "flow_slpm",
        "average_flow_slpm",
        "orifice_mm",
        "annual_cost",
        "cost_basis",
        "confidence",
        "ambiguity_group",
        "flow_slpm_interval",
        "repair_cost",
        "repair",
        "payback_days",
    }
    assert leak["flow_slpm"] == pytest.approx(7e-4 / 1.294 * 60_000, rel=0.1)
    low, high = leak["flow_slpm_interval"]
    assert low < leak["flow_slpm"] < high
    # one leak: its interval is the total's, its repair the only one
    assert data["totals"]["flow_slpm_interval"] == pytest.approx([low, high])
    assert data["repair_order"] == ["X_A"]
    assert data["remainder"]["explained_fraction"] == pytest.approx(
        data["fit"]["explained_fraction"]
    )
    assert data["cost_settings"]["hours"] == 4000.0
    # the synthetic signatures hold no mean flows per cycle: continuous leakage assumed,
    # and said so
    assert leak["average_flow_slpm"] == leak["flow_slpm"]
    assert leak["cost_basis"] == COST_BASIS_CONTINUOUS
    assert any("continuously" in note for note in data["notes"])
    # a single leak the signatures explain is not checked by simulation (and the
    # synthetic machine is unknown to the simulator anyway)
    assert data["fit"]["checked_by_simulation"] is False
    assert not any("digital twin" in note for note in data["notes"])


def test_cost_uses_the_average_flow_over_the_cycle(reference):
    sig = reference.signatures
    # a leak that loses on average 10 % of its nominal flow at the smallest size and
    # 5 % at the largest (it drains its line faster when larger)
    duty = np.linspace(0.10, 0.05, sig.sizes.shape[1])
    with_mean = SignatureSet(
        sig.locations,
        sig.sizes,
        sig.deltas,
        sig.feature_names,
        sig.nominal_pressure,
        mean_flow=sig.sizes * duty,
    )
    ref = reference.with_signatures(with_mean)
    settings = CostSettings(hours=4000.0)
    result = diagnose(ref, synth_table(10, {"X_A": 1.5e-3}, seed=45), settings)
    plain = diagnose(reference, synth_table(10, {"X_A": 1.5e-3}, seed=45), settings)
    (leak,) = result.leaks
    assert leak.mass_flow == plain.leaks[0].mass_flow  # sizing is unchanged
    row = sig.sizes[sig.locations.index(Location("X", "A"))]
    expected = np.interp(leak.mass_flow, row, duty) * leak.mass_flow
    assert leak.average_mass_flow == pytest.approx(expected, rel=1e-9)
    assert leak.cost_basis == COST_BASIS_AVERAGE
    assert leak.annual_cost == pytest.approx(annual_cost(expected, settings), rel=1e-12)
    assert leak.annual_cost == pytest.approx(plain.leaks[0].annual_cost * expected / leak.mass_flow)
    assert not any("continuously" in note for note in result.notes)


def test_band_method_sees_a_large_leak(reference):
    quiet = diagnose(reference, synth_table(10, seed=46))
    loud = diagnose(reference, synth_table(10, {"supply": 1.5e-3}, seed=46))
    assert quiet.band_alarms == 0
    assert loud.band_alarms == 10


def test_incompatible_runs_rejected(reference):
    with pytest.raises(MachineError, match="another machine"):
        diagnose(reference, synth_table(10, seed=1, machine="other"))
    with pytest.raises(ChannelError, match="Q_X_A"):
        diagnose(reference, synth_table(10, seed=1).select(["P_In", "Q_In", "P_X_A"]))


def test_reference_needs_ten_cycles():
    with pytest.raises(InputError, match="reference cycles: received 9"):
        ReferenceModel.build(synth_table(9))


def test_digital_only_reference_builds_and_detects_timing_change():
    ref = ReferenceModel.build(
        synth_table(60, seed=100), channels=[], signatures=synth_signatures()
    )
    assert ref.feature_names == tuple(f"duration@{j + 1}" for j in range(12))
    assert diagnose(ref, synth_table(10, {"X_A": 1.5e-3}, seed=47)).detected
    assert not np.any([diagnose(ref, synth_table(10, seed=48 + s)).detected for s in range(10)])


@pytest.mark.parametrize("location", ["supply", "X_A", "Y_B"])
def test_supply_check_says_a_leak_raised_flow_and_lowered_pressure(reference, location):
    result = diagnose(reference, synth_table(10, {location: 5e-4}, seed=42))
    assert result.supply is not None
    assert result.supply.verdict == "leak (eq. 4.21 holds)"
    assert result.supply.flow_change > 1e-4  # [kg/s]
    assert result.supply.pressure_change < -5e3  # [Pa]
    assert result.to_dict()["supply_check"]["verdict"] == "leak (eq. 4.21 holds)"


def test_supply_check_tells_house_air_from_a_leak(reference):
    # the house air 4 reference standard deviations up: flow and pressure rise together
    up = diagnose(reference, synth_table(10, seed=7, fluctuation=0.2, level_offset=4.0))
    assert up.supply is not None
    assert up.supply.verdict == "not a leak (pressure rose too)"
    assert up.supply.cycles == {"not a leak (pressure rose too)": 10}
    free = diagnose(reference, synth_table(10, seed=1001))
    assert free.supply is not None
    assert free.supply.verdict == "no leak"


def test_supply_check_needs_supply_sensors():
    lines_only = ReferenceModel.build(
        synth_table(60, seed=100), channels=["P_X_A", "Q_X_A"], signatures=synth_signatures()
    )
    result = diagnose(lines_only, synth_table(10, {"X_A": 5e-4}, seed=42))
    assert result.supply is None
    assert result.to_dict()["supply_check"] is None


def test_one_finding_per_leak_in_si(reference):
    # Diagnosis.leaks holds one LeakFinding per leak, the located one costed: the
    # localisation's sized locations are the same leaks, not a second result to read
    result = diagnose(reference, synth_table(10, {"X_A": 7e-4}, seed=45))
    assert result.localisation is not None
    (leak,) = result.leaks
    (sized,) = result.localisation.leaks
    assert isinstance(leak, LeakFinding)
    assert (leak.location, leak.mass_flow, leak.confidence) == (
        sized.location,
        sized.mass_flow,
        sized.confidence,
    )
    assert leak.ambiguity_group == sized.ambiguity_group
    assert leak.group_mass_flows == sized.group_mass_flows
    assert leak.mass_flow == pytest.approx(7e-4, rel=0.1)  # [kg/s]
    assert 5e-4 < leak.orifice_diameter < 5e-3  # [m]
    # the JSON and the table show the finding's SLPM and mm properties, unrounded
    (row,) = result.to_dict()["leaks"]
    assert row["flow_slpm"] == leak.flow_slpm == float(kg_s_to_slpm(leak.mass_flow))
    assert row["orifice_mm"] == leak.orifice_mm == 1e3 * leak.orifice_diameter
    assert row["average_flow_slpm"] == leak.average_flow_slpm
    table = result.to_pandas()
    assert table.loc[0, "flow_slpm"] == leak.flow_slpm
    assert table.loc[0, "annual_cost"] == leak.annual_cost == result.total_annual_cost
