"""The isolability table (issue 34): which faults a sensor set can tell apart.

One press-fit-cell reference per sensor set from the same two leak-free recordings, the
fault signatures simulated once on the full set's features. The weighting is checked
against the diagnosis's own (:func:`pneufdd.diagnosis.engine.whitener`), and the table
against what the physics says the sensors can and cannot see.
"""

from __future__ import annotations

import numpy as np
import pytest

from pneufdd.diagnosis.engine import whitener
from pneufdd.diagnosis.fault_choice import FAULT_MODEL_ERROR
from pneufdd.diagnosis.isolability import (
    _excess,
    _weights,
    fault_signatures,
    isolability,
)
from pneufdd.diagnosis.recordings import build_reference_from_recordings
from pneufdd.errors import InputError
from pneufdd.sim import as_exported, simulate

SEED = 34_700  # this file's seeds: SEED + k


@pytest.fixture(scope="module")
def tables():
    recs = [as_exported(simulate("press-fit-cell", cycles=8, seed=SEED + k)) for k in (1, 2)]
    refs = {
        label: build_reference_from_recordings(
            recs, channels, ["a", "b"], machine="press-fit-cell", with_signatures=False, workers=1
        )
        for label, channels in (
            ("full", None),
            ("supply-only", ["P_In", "Q_In"]),
            ("digital-only", []),
        )
    }
    signatures = fault_signatures(refs["full"], plants=2)
    return refs, signatures, {k: isolability(r, signatures) for k, r in refs.items()}


def _index(table, kind, location):
    return next(i for i, m in enumerate(table.members) if (m.kind, m.location) == (kind, location))


def test_weighting_is_the_diagnosis_whitener(tables):
    refs, signatures, _ = tables
    ref = refs["full"]
    e = signatures.select(ref.feature_names).changes
    i, j = 0, e.shape[0] - 1
    variance, nuisance = _weights(ref, 12, 2)
    mine = _excess(e[i], 0.7 * e[j][None, :], variance, nuisance)[0]
    magnitude = np.maximum(np.abs(e[i]), np.abs(0.7 * e[j]))
    w = whitener(ref, 12, magnitude, (), FAULT_MODEL_ERROR, 2)
    r = w(e[i] - 0.7 * e[j])[0]
    assert mine == pytest.approx(float(r @ r), rel=1e-8)


def test_every_hypothesis_explains_itself(tables):
    _, signatures, by_set = tables
    # 53 fault hypotheses (docs/faults.md: 45 before the opened throttles were searched)
    # and one leak per leak location
    assert len(signatures.members) + len(signatures.stalled) == 53 + 9
    for table in by_set.values():
        assert np.allclose(np.diag(table.distance), 0.0, atol=1e-9)
        assert np.all(table.distance >= -1e-9)
        assert table.threshold == pytest.approx(2.0 * np.log(20.0))


def test_a_line_meter_tells_a_spool_leak_from_a_line_leak(tables):
    _, _, by_set = tables
    # the spool leak to exhaust sits upstream of Q_PRESS_B, the line leak downstream:
    # the full set sees the difference; the supply meter sees the same air lost from
    # the same chamber (docs/faults.md, "Internal leakage")
    full, supply = by_set["full"], by_set["supply-only"]
    leak, spool = _index(full, "leak", "PRESS_B"), _index(full, "valve-leak-out", "PRESS_B")
    assert full.detectable[leak]
    assert full.detectable[spool]
    assert spool not in full.group(leak)
    assert leak not in full.group(spool)
    # a run with the spool leak can be explained by the line's leak: a leak invented
    assert leak in supply.group(spool)


def test_a_regulator_drift_is_no_leak_where_the_supply_pressure_is_measured(tables):
    _, _, by_set = tables
    for label in ("full", "supply-only"):
        table = by_set[label]
        reg = _index(table, "regulator", "supply")
        assert table.detectable[reg]
        assert all(table.members[j].fault_type != "leak" for j in table.group(reg)), label


def test_fewer_sensors_tell_fewer_apart(tables):
    _, _, by_set = tables
    full, digital = by_set["full"].summary(), by_set["digital-only"].summary()
    assert full["isolable"] > digital["isolable"]
    assert full["type_isolable"] >= digital["type_isolable"]
    frame = by_set["supply-only"].to_pandas()
    assert len(frame) == full["hypotheses"]
    assert set(frame.columns) >= {"type", "kind", "location", "detectable", "cannot_tell_from"}


def test_a_reference_without_a_description_is_refused(tables):
    refs, _, _ = tables
    from dataclasses import replace

    bare = replace(refs["full"], machine_description={})
    with pytest.raises(InputError, match="isolability"):
        fault_signatures(bare)


def test_plant_deviations_weigh_as_a_dense_covariance(tables):
    # the Woodbury form against the covariance written out: noise and floor on the
    # diagonal, two plants' deviations, the house air with a huge variance
    refs, signatures, _ = tables
    ref = refs["supply-only"]
    e = signatures.select(ref.feature_names).changes
    rng = np.random.default_rng(SEED)
    dev = 0.3 * e[3][None, :] * rng.normal(size=(2, e.shape[1]))
    variance, nuisance = _weights(ref, 12, 2)
    mine = _excess(e[3], 0.5 * e[7][None, :], variance, nuisance, dev)[0]
    magnitude = np.maximum(np.abs(e[3]), np.abs(0.5 * e[7]))
    cov = np.diag(variance + (FAULT_MODEL_ERROR * magnitude) ** 2) + dev.T @ dev / 2.0
    cov = cov + 1e9 * nuisance.T @ nuisance
    r = e[3] - 0.5 * e[7]
    assert mine == pytest.approx(float(r @ np.linalg.solve(cov, r)), rel=1e-4)


def test_smaller_faults_are_told_apart_no_better(tables):
    refs, signatures, by_set = tables
    big = by_set["supply-only"]
    small = isolability(refs["supply-only"], signatures, truth_scale=1.0 / 3.0)
    assert small.truth_scale == pytest.approx(1.0 / 3.0)
    assert [m.size for m in small.members] == pytest.approx([m.size / 3.0 for m in big.members])
    # a third of the effect: less evidence against "no explanation"
    assert np.sum(small.detectable) <= np.sum(big.detectable)
    assert np.median(small.strength) < np.median(big.strength)
