"""The .pnref reference file: exact round trip, validation, atomic write."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from _diag_synth import synth_description, synth_signatures, synth_table
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.reference.file import FORMAT_VERSION, load_reference, save_reference
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import FileFormatError, InputError


@pytest.fixture(scope="module")
def model():
    sig = synth_signatures()
    sig = SignatureSet(
        sig.locations,
        sig.sizes,
        sig.deltas,
        sig.feature_names,
        sig.nominal_pressure,
        np.full((len(sig.locations), len(sig.feature_names)), 0.5),
        np.array([1e-3, 6e-4]),
        sig.sizes * np.linspace(0.9, 0.1, len(sig.locations))[:, None],
        np.tile([-1e-5, -2e-6], (len(sig.locations), 1)),
        baseline=np.linspace(1.0, 2.0, len(sig.feature_names)),
        baseline_run=(2, 123),
    )
    return ReferenceModel.build(
        synth_table(20, seed=3),
        machine_description=synth_description(),
        signatures=sig,
        sources=["a.parquet", "b.parquet"],
        sequence=[{"valves": ["U_X_A"], "switches": [["S_X_B", 1]]}],
    )


def test_round_trip_is_exact(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    back = load_reference(path)
    assert back.machine == model.machine
    assert back.machine_description == model.machine_description
    assert back.channels == model.channels
    assert back.units == model.units
    assert back.sources == model.sources
    assert back.sequence == model.sequence
    assert back.settings == model.settings
    assert back.supply_pressure == model.supply_pressure
    for name in ("features", "band_mean", "band_std", "trace_offsets"):
        assert np.array_equal(getattr(back, name), getattr(model, name))
    assert back.signatures.locations == model.signatures.locations
    assert np.array_equal(back.signatures.deltas, model.signatures.deltas)
    assert np.array_equal(back.signatures.sizes, model.signatures.sizes)
    assert np.array_equal(back.signatures.interaction, model.signatures.interaction)
    assert np.array_equal(back.signatures.interaction_sizes, model.signatures.interaction_sizes)
    assert np.array_equal(back.signatures.mean_flow, model.signatures.mean_flow)
    assert np.array_equal(
        back.signatures.mean_flow_interaction, model.signatures.mean_flow_interaction
    )
    assert np.array_equal(back.signatures.baseline, model.signatures.baseline)
    assert back.signatures.baseline_run == (2, 123)
    assert np.array_equal(back.detector.threshold_, model.detector.threshold_)
    assert not list(tmp_path.glob(".*tmp"))


def test_a_reference_without_the_signatures_baseline_still_loads(model, tmp_path):
    # references saved before the leak-free baseline was kept: the check simulates it
    path = save_reference(model, tmp_path / "ref.pnref")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "sig_baseline"}
    header = json.loads(str(arrays["header"]))
    del header["signature_baseline_run"]
    arrays["header"] = np.array(json.dumps(header))
    old = tmp_path / "old.pnref"

    def write() -> None:
        with old.open("wb") as handle:
            np.savez_compressed(handle, **arrays)

    write()
    back = load_reference(old)
    assert back.signatures.baseline is None
    assert back.signatures.baseline_run is None
    # a damaged run description is refused, naming the file and the entry
    header["signature_baseline_run"] = ["2", 123]
    arrays["header"] = np.array(json.dumps(header))
    write()
    with pytest.raises(FileFormatError, match=r"old\.pnref.*signature_baseline_run"):
        load_reference(old)


def test_refuses_to_overwrite(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    with pytest.raises(InputError, match="exists"):
        save_reference(model, path)
    save_reference(model, path, overwrite=True)


def test_truncated_file_rejected(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(FileFormatError, match=r"ref\.pnref"):
        load_reference(path)


def test_not_a_reference_rejected(tmp_path):
    path = tmp_path / "junk.pnref"
    path.write_text("hello")
    with pytest.raises(FileFormatError, match=r"junk\.pnref"):
        load_reference(path)
    with pytest.raises(FileFormatError, match=r"missing\.pnref"):
        load_reference(tmp_path / "missing.pnref")


def _rewrite(path, out, edit):
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    edit(arrays)
    with open(out, "wb") as handle:
        np.savez(handle, **arrays)


def test_wrong_version_rejected(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")

    def bump(arrays):
        header = json.loads(str(arrays["header"]))
        header["version"] = 99
        arrays["header"] = np.array(json.dumps(header))

    _rewrite(path, tmp_path / "v99.pnref", bump)
    with pytest.raises(FileFormatError, match=r"v99.pnref.*version"):
        load_reference(tmp_path / "v99.pnref")


@pytest.mark.parametrize("version", [1, 2])
def test_old_versions_ask_for_a_rebuild(model, tmp_path, version):
    # version 1: before the mean leak flows were stored; version 2: before the machine
    # description travelled with the reference (signatures looked the machine up by name)
    path = save_reference(model, tmp_path / "ref.pnref")

    def downgrade(arrays):
        header = json.loads(str(arrays["header"]))
        header["version"] = version
        header["machine_description"] = {"name": "synth"}  # v2 kept the metadata form
        header.pop("localisation")
        arrays["header"] = np.array(json.dumps(header))
        if version == 1:
            arrays.pop("sig_mean_flow")
            arrays.pop("sig_mean_flow_interaction")

    _rewrite(path, tmp_path / "old.pnref", downgrade)
    with pytest.raises(FileFormatError) as info:
        load_reference(tmp_path / "old.pnref")
    message = str(info.value)
    assert "old.pnref" in message
    assert f"received {version}" in message
    assert f"version {FORMAT_VERSION}" in message
    assert FORMAT_VERSION == 3
    assert "rebuild the reference" in message
    assert "pneufdd reference build" in message
    assert "--machine" in message


def test_reference_keeps_its_machine_description(model, tmp_path):
    back = load_reference(save_reference(model, tmp_path / "ref.pnref"))
    assert back.description is not None
    assert back.description.actuator_ids == ("X", "Y")
    assert back.localisation == model.localisation


def test_invalid_machine_description_rejected(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")

    def damage(arrays):
        header = json.loads(str(arrays["header"]))
        header["machine_description"]["supply"]["regulator_set_psig"] = 200.0
        arrays["header"] = np.array(json.dumps(header))

    _rewrite(path, tmp_path / "bad.pnref", damage)
    with pytest.raises(FileFormatError, match=r"bad\.pnref.*regulator_set_psig"):
        load_reference(tmp_path / "bad.pnref")


def test_misshapen_mean_flow_rejected(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    _rewrite(
        tmp_path / "ref.pnref",
        tmp_path / "bad.pnref",
        lambda a: a.update(sig_mean_flow=a["sig_mean_flow"][:, :1]),
    )
    with pytest.raises(FileFormatError, match="sig_mean_flow"):
        load_reference(path.parent / "bad.pnref")


def test_missing_and_misshapen_entries_rejected(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    _rewrite(path, tmp_path / "nofeat.pnref", lambda a: a.pop("features"))
    with pytest.raises(FileFormatError, match="features"):
        load_reference(tmp_path / "nofeat.pnref")

    def shrink(arrays):
        arrays["sig_deltas"] = arrays["sig_deltas"][:, :, :-1]

    _rewrite(path, tmp_path / "shape.pnref", shrink)
    with pytest.raises(FileFormatError, match="sig_deltas"):
        load_reference(tmp_path / "shape.pnref")


def test_too_few_cycles_in_file_rejected(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")

    def cut(arrays):
        arrays["features"] = arrays["features"][:5]
        header = json.loads(str(arrays["header"]))
        header["n_cycles"] = 5
        arrays["header"] = np.array(json.dumps(header))

    _rewrite(path, tmp_path / "five.pnref", cut)
    with pytest.raises(FileFormatError, match=r"five.pnref.*received 5"):
        load_reference(tmp_path / "five.pnref")


def test_no_pickle_inside(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
    assert "header.npy" in names
    with np.load(path, allow_pickle=False) as data:
        assert all(data[k].dtype != object for k in data.files)


def test_cycle_recording_round_trips_and_groups_the_cross_validation(tmp_path):
    groups = np.repeat([0, 1, 2], [7, 7, 6])
    grouped = ReferenceModel.build(
        synth_table(20, seed=3),
        machine_description=synth_description(),
        sources=["a.parquet", "b.parquet", "c.parquet"],
        cycle_recording=groups,
    )
    back = load_reference(save_reference(grouped, tmp_path / "grouped.pnref"))
    assert np.array_equal(back.cycle_recording, groups)
    assert back.detector.grouped_cv_
    assert back.detector.threshold_ == grouped.detector.threshold_
    # leaving whole recordings out scores the reference differently from cycles in turn
    ungrouped = ReferenceModel.build(
        synth_table(20, seed=3), machine_description=synth_description()
    )
    assert ungrouped.cycle_recording is None
    assert not ungrouped.detector.grouped_cv_
    assert not np.array_equal(
        grouped.detector.reference_scores_, ungrouped.detector.reference_scores_
    )


def test_file_without_cycle_recording_reads_as_ungrouped(model, tmp_path):
    path = save_reference(model, tmp_path / "ref.pnref")
    assert model.cycle_recording is None
    with np.load(path) as data:
        assert "cycle_recording" not in data.files
    assert load_reference(path).cycle_recording is None


def test_cycle_recording_of_wrong_length_is_refused():
    with pytest.raises(InputError, match=r"cycle_recording .*received 'shape \(3,\)"):
        ReferenceModel.build(
            synth_table(20, seed=3),
            machine_description=synth_description(),
            cycle_recording=np.array([0, 1, 2]),
        )


def test_cycle_recording_of_fractions_is_refused_not_truncated():
    with pytest.raises(InputError, match=r"cycle_recording .*dtype float64"):
        ReferenceModel.build(
            synth_table(20, seed=3),
            machine_description=synth_description(),
            cycle_recording=np.repeat([0.0, 1.5, 2.0], [7, 7, 6]),
        )


@pytest.mark.parametrize(
    ("offset", "value"),
    [(8, 0), (8, 99), (6, 0x0800)],
    ids=["method_stored", "method_unknown", "flags_utf8_bit"],
)
def test_a_damaged_local_header_is_refused(model, tmp_path, offset, value):
    """A local header whose compression method or flags disagree with the archive's
    directory (zipfile reads by the directory and would not notice) or that names a
    method zipfile does not know (99) is a damaged file, refused like any other."""
    path = save_reference(model, tmp_path / "r.pnref")
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo("features.npy")
    assert data[info.header_offset : info.header_offset + 4] == b"PK\x03\x04"
    at = info.header_offset + offset
    data[at : at + 2] = value.to_bytes(2, "little")
    damaged = tmp_path / "damaged.pnref"
    damaged.write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match=r"features\.npy"):
        load_reference(damaged)
