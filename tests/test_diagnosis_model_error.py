"""The signatures' model uncertainty: plausible-plant deviations and the run weighting."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from _diag_synth import synth_signatures, synth_table
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.effects.twin import TwinLeakEffect
from pneufdd.diagnosis.engine import whitener
from pneufdd.diagnosis.localisation.search import LocalisationSettings, locate
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError
from pneufdd.location import SUPPLY, Location
from pneufdd.signals.segmentation import sequence_from_machine
from pneufdd.sim import load_machine


def _with_deviations(sig: SignatureSet, k: int = 6, seed: int = 0) -> SignatureSet:
    rng = np.random.default_rng(seed)
    sizes = sig.sizes[0, [0, -1]]
    base = np.stack([[sig.effect(i, s) for s in sizes] for i in range(len(sig.locations))])
    deviations = 0.1 * base[None] * rng.normal(size=(k, *base.shape))
    return sig.with_plant_deviations(deviations, sizes)


def test_deviations_interpolate_like_the_signatures():
    sig = _with_deviations(synth_signatures())
    d = sig.plant_deviations
    lo, hi = sig.deviation_sizes
    assert sig.deviations(2, lo) == pytest.approx(d[:, 2, 0])
    assert sig.deviations(2, hi) == pytest.approx(d[:, 2, 1])
    mid = 0.25 * lo + 0.75 * hi
    assert sig.deviations(2, mid) == pytest.approx(0.25 * d[:, 2, 0] + 0.75 * d[:, 2, 1])
    assert sig.deviations(2, 0.5 * lo) == pytest.approx(0.5 * d[:, 2, 0])  # through 0
    assert sig.n_plants == 6
    sub = sig.select(sig.feature_names[:12])
    assert sub.plant_deviations.shape == (6, 5, 2, 12)
    assert synth_signatures().deviations(0, lo) is None


def test_deviations_are_validated():
    sig = synth_signatures()
    with pytest.raises(InputError, match="both or neither"):
        sig.with_plant_deviations(np.zeros((2, 5, 1, sig.n_features)), None)
    with pytest.raises(InputError, match="shape of plant_deviations"):
        sig.with_plant_deviations(np.zeros((2, 4, 1, sig.n_features)), np.array([1e-3]))
    with pytest.raises(InputError, match="positive, increasing"):
        sig.with_plant_deviations(np.zeros((2, 5, 2, sig.n_features)), np.array([2e-3, 1e-3]))


@pytest.fixture(scope="module")
def reference():
    sig = _with_deviations(synth_signatures(), k=8, seed=3)
    return ReferenceModel.build(synth_table(60, seed=100), signatures=sig)


def test_without_model_error_the_weighting_is_the_detector_statistic(reference):
    det = reference.detector
    rng = np.random.default_rng(1)
    delta = rng.normal(size=(3, det.scale_.size)) * det.scale_
    gain = 1.0 / np.sqrt(1 / 10 + 1 / reference.n_cycles)
    expected = det.project(delta / det.scale_) * gain
    assert whitener(reference, 10)(delta) == pytest.approx(expected, abs=1e-9)


def test_weighted_model_error_has_unit_variance(reference):
    # draws of what the model says a correct explanation leaves (noise + the coherent
    # plant deviations of one leak + the floor) are white after the weighting
    det = reference.detector
    sig = reference.signatures
    loc, size = 1, 8e-4
    dev = sig.deviations(loc, size)
    magnitude = np.abs(sig.effect(loc, size))
    whiten = whitener(reference, 10, magnitude, [(loc, size)], 0.02)
    rng = np.random.default_rng(7)
    n = 20_000
    noise_sd = det.scale_ * np.sqrt(1 / 10 + 1 / reference.n_cycles)
    draws = rng.normal(size=(n, noise_sd.size)) * np.sqrt(
        noise_sd**2 + (0.02 * magnitude) ** 2
    ) + rng.normal(size=(n, dev.shape[0])) @ dev / np.sqrt(dev.shape[0])
    white = whiten(draws)
    # the fluctuation directions are projected out, everything else has unit variance
    dof = det.scale_.size - det.components_.shape[0]
    assert np.mean(np.sum(white**2, axis=1)) == pytest.approx(dof, rel=0.02)
    # and the coherent deviation of the leak is no longer large evidence
    plain = whitener(reference, 10)
    one = dev[0]
    assert float(np.sum(whiten(one) ** 2)) < 0.1 * float(np.sum(plain(one) ** 2))


def _supply_like_pair():
    """Signatures where a supply leak looks like X_A and X_B leaking together."""
    rng = np.random.default_rng(23)
    matrix = np.abs(rng.normal(size=(5, 50)))
    matrix[0] = matrix[1] + matrix[2]
    return matrix, SignatureSet(
        ("supply", "X_A", "X_B", "Y_A", "Y_B"),
        np.full((5, 1), 10.0),
        10.0 * matrix[:, None, :],
        tuple(f"f{j}" for j in range(50)),
        np.full(5, 6e5),
    )


def test_two_lines_standing_for_a_supply_leak_lower_its_confidence():
    matrix, sig = _supply_like_pair()
    result = locate(2.0 * matrix[0], LeakEffectModel(sig), lambda d: np.atleast_2d(d) * 50.0)
    (leak,) = result.leaks
    assert leak.location == SUPPLY
    assert leak.confidence < 0.6  # X_A + X_B fits as well: not a confident supply leak
    assert any(set(map(str, alt.locations)) == {"X_A", "X_B"} for alt in result.alternatives)
    distinct = locate(2.0 * matrix[3], LeakEffectModel(sig), lambda d: np.atleast_2d(d) * 50.0)
    assert distinct.leaks[0].confidence > 0.95


def _linear_signatures(rng: np.random.Generator) -> tuple[np.ndarray, SignatureSet]:
    """Random positive effects of five locations, linear in size (one ladder point)."""
    matrix = np.abs(rng.normal(size=(5, 50)))
    return matrix, SignatureSet(
        ("supply", "X_A", "X_B", "Y_A", "Y_B"),
        np.full((5, 1), 10.0),
        10.0 * matrix[:, None, :],
        tuple(f"f{j}" for j in range(50)),
        np.full(5, 6e5),
    )


def test_supply_beside_a_line_leak_may_be_the_other_line():
    rng = np.random.default_rng(24)
    matrix, sig = _linear_signatures(rng)
    observed = 3.0 * matrix[2] + 1.0 * matrix[0]  # X_B and a supply leak
    result = locate(observed, LeakEffectModel(sig), lambda d: np.atleast_2d(d) * 50.0)
    groups = {str(leak.location): [str(x) for x in leak.ambiguity_group] for leak in result.leaks}
    assert groups == {"X_B": ["X_B"], "supply": ["supply", "X_A"]}


def test_localisation_settings_round_trip_and_validation():
    settings = LocalisationSettings(max_leaks=1, model_error_floor=0.05)
    assert LocalisationSettings.from_dict(settings.to_dict()) == settings
    assert LocalisationSettings(max_leaks=3).max_leaks == 3  # any number up to the limit
    for wrong in (0, 33, 2.0, True):
        with pytest.raises(InputError, match="max_leaks"):
            LocalisationSettings(max_leaks=wrong)
    with pytest.raises(InputError, match="min_mass_flow"):
        LocalisationSettings(min_mass_flow=-1.0)
    with pytest.raises(InputError, match="colour"):
        LocalisationSettings.from_dict({"colour": 1})
    assert replace(settings, simulate_explanations=False).simulate_explanations is False


def test_an_unknown_leak_location_is_an_error_not_a_stall():
    machine = load_machine("press-fit-cell")
    twin = TwinLeakEffect(machine, ("duration@1",), sequence_from_machine(machine), ())
    assert twin({Location("FEED", "A"): 5e-4}) is not None
    with pytest.raises(InputError, match="NOPE_A"):
        twin({Location("NOPE", "A"): 5e-4})


def _imitating_reference(
    scales: np.ndarray, large: int, small: int, small_size: float, other: float = 0.0
):
    """Plant deviations of leak ``large``: ``scales[k]`` times leak ``small``'s effect,
    plus ``other`` times a random direction of the same norm."""
    sig = synth_signatures()
    sizes = sig.sizes[0, [0, -1]]
    effect = sig.effect(small, small_size)
    rng = np.random.default_rng(31)
    extra = rng.normal(size=(scales.size, sig.n_features))
    extra *= other * np.linalg.norm(effect) / np.linalg.norm(extra, axis=1, keepdims=True)
    deviations = np.zeros((scales.size, len(sig.locations), sizes.size, sig.n_features))
    deviations[:, large, :, :] = (scales[:, None] * effect[None, :] + extra)[:, None, :]
    sig = sig.with_plant_deviations(deviations, sizes)
    return ReferenceModel.build(synth_table(60, seed=100), signatures=sig), sizes


def test_imitated_size_is_the_rms_of_the_deviations_projected_on_the_second_leak():
    from pneufdd.diagnosis.engine import imitated_size

    scales = np.array([0.1, -0.3, 0.5, 0.2])
    ref, sizes = _imitating_reference(scales, large=1, small=3, small_size=4e-4)
    effects = ref.leak_effects()
    got = imitated_size(ref, effects, 10, (1, float(sizes[-1])), (3, 4e-4))
    assert got == pytest.approx(4e-4 * float(np.sqrt(np.mean(scales**2))), rel=1e-6)
    # no deviations, no estimate
    plain = ReferenceModel.build(synth_table(60, seed=100), signatures=synth_signatures())
    assert imitated_size(plain, plain.leak_effects(), 10, (1, 1e-3), (3, 4e-4)) is None


@pytest.mark.parametrize(("scale", "other", "expected"), [(0.6, 3.0, 1), (0.01, 0.0, 2)])
def test_a_second_leak_the_first_leaks_model_error_imitates_is_an_alternative(
    scale, other, expected
):
    from pneufdd.diagnosis.engine import _drop_doubtful_leaks, run_whitener

    ref, sizes = _imitating_reference(
        np.array([scale, -scale, 0.5 * scale]), large=1, small=3, small_size=3e-4, other=other
    )
    effects = ref.leak_effects()
    observed = effects.effect(1, float(sizes[-1])) + effects.effect(3, 3e-4)
    settings = replace(ref.localisation, simulate_explanations=False)
    whiten = run_whitener(ref, effects, observed, 10, settings)
    two = locate(observed, effects, whiten, settings)
    assert len(two.leaks) == 2
    notes: list[str] = []
    settings = replace(settings, min_leak_confidence=0.0)  # the imitation check alone
    result = _drop_doubtful_leaks(ref, effects, observed, 10, whiten, settings, two, notes)
    assert len(result.leaks) == expected
    if expected == 1:
        assert str(result.leaks[0].location) == str(effects.locations[1])
        assert {str(x) for x in result.alternatives[0].locations} == {
            str(effects.locations[1]),
            str(effects.locations[3]),
        }
        assert "imitates" in notes[0]
    else:
        assert result is two
        assert not notes


def test_references_saved_before_the_imitation_check_read_it_off():
    data = LocalisationSettings().to_dict()
    del data["imitation_z"]
    assert LocalisationSettings.from_dict(data).imitation_z == 0.0
    assert LocalisationSettings().imitation_z == 3.0


@pytest.mark.parametrize("margin", [1e-6, -1e-6])
def test_a_second_leak_less_likely_than_its_threshold_is_an_alternative(margin):
    from pneufdd.diagnosis.engine import _drop_doubtful_leaks, run_whitener

    ref = ReferenceModel.build(synth_table(60, seed=100), signatures=synth_signatures())
    effects = ref.leak_effects()
    observed = effects.effect(1, 2e-3) + effects.effect(3, 3e-4)
    settings = replace(ref.localisation, simulate_explanations=False)
    whiten = run_whitener(ref, effects, observed, 10, settings)
    two = locate(observed, effects, whiten, settings)
    assert len(two.leaks) == 2
    weakest = min(leak.confidence for leak in two.leaks)
    settings = replace(settings, min_leak_confidence=weakest + margin)
    notes: list[str] = []
    result = _drop_doubtful_leaks(ref, effects, observed, 10, whiten, settings, two, notes)
    if margin < 0:
        assert result is two
        assert not notes
        return
    (leak,) = result.leaks
    assert leak.location == two.leaks[0].location
    assert result.alternatives[0].locations == tuple(x.location for x in two.leaks)
    assert result.alternatives[0].mass_flows == tuple(x.mass_flow for x in two.leaks)
    assert f"({weakest:.2f}) is below" in notes[0]


def test_references_saved_before_the_confidence_check_read_it_off():
    data = LocalisationSettings().to_dict()
    del data["min_leak_confidence"]
    assert LocalisationSettings.from_dict(data).min_leak_confidence == 0.0
    assert LocalisationSettings().min_leak_confidence == 0.5


def test_a_detected_run_is_located_at_its_best_leak_even_when_that_explains_little():
    # a leak at Y_A plus a larger deviation no leak explains (another fault): the best
    # single leak lowers the residual by far less than min_relative_gain
    rng = np.random.default_rng(8)
    matrix, sig = _linear_signatures(rng)
    other = rng.normal(size=50)
    other -= matrix.T @ np.linalg.lstsq(matrix.T, other, rcond=None)[0]  # no leak's
    observed = 1.0 * matrix[3] + 2.0 * np.linalg.norm(matrix[3]) * other / np.linalg.norm(other)
    effects = LeakEffectModel(sig)

    def whiten(d):
        return np.atleast_2d(d) * 50.0

    (leak,) = locate(observed, effects, whiten, LocalisationSettings(max_leaks=1)).leaks
    assert str(leak.location) == "Y_A"
    assert leak.mass_flow == pytest.approx(1.0, rel=0.05)
    assert leak.confidence < 0.25  # it explains about a fifth of the deviation
    for gain in (0.25, 1.0):
        strict = LocalisationSettings(max_leaks=1, first_leak_gain=gain)
        assert locate(observed, effects, whiten, strict).leaks == ()
    data = LocalisationSettings().to_dict()
    del data["first_leak_gain"]
    assert LocalisationSettings.from_dict(data).first_leak_gain == 1.0  # saved before: off


def _line_held_all_but_one_step(seed: int, vented_share: float = 1.0):
    """A reference where X_B's signature is the supply's but in one step (its line is
    vented there), the twin does not know what X_B draws in that step, and every leak's
    signature shares the plausible plants' common error. Returns the reference and a
    run's change: an X_B leak whose plant draws ``vented_share`` of a supply leak's air
    in that step."""
    base = synth_signatures()
    held = np.array([n.startswith("Q_In") and n.endswith("@3") for n in base.feature_names])
    sup, xb = 0, 2
    deltas = np.array(base.deltas)
    deltas[xb] = deltas[sup] * ~held
    sig = replace(base, deltas=deltas)
    sizes = sig.sizes[0, [0, -1]]
    rng = np.random.default_rng(seed)
    supply = np.stack([sig.effect(sup, s) for s in sizes])
    common = 0.3 * rng.normal(size=(8, sig.n_features)) * (np.abs(supply[-1]) + 1e-12)
    deviations = common[:, None, None, :] * (sizes / sizes[-1])[None, None, :, None]
    deviations = np.repeat(deviations, len(sig.locations), axis=1)
    deviations[:, xb] += rng.normal(size=8)[:, None, None] * supply[None] * held
    sig = sig.with_plant_deviations(deviations, sizes)
    ref = ReferenceModel.build(synth_table(60, seed=100), signatures=sig)
    size = 8e-4
    observed = sig.effect(xb, size) + vented_share * sig.effect(sup, size) * held
    return ref, observed + common[0] * size / sizes[-1]


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_a_line_that_differs_from_the_supply_where_the_twin_is_unsure_stays_in_the_group(seed):
    from pneufdd.diagnosis.engine import run_whitener

    ref, observed = _line_held_all_but_one_step(seed)
    effects = ref.leak_effects()
    groups = {}
    for flag in (False, True):
        settings = replace(ref.localisation, simulate_explanations=False, group_model_error=flag)
        whiten = run_whitener(ref, effects, observed, 10, settings)
        (leak,) = locate(observed, effects, whiten, settings).leaks
        assert leak.mass_flow == pytest.approx(8e-4, rel=0.01)
        groups[flag] = {str(x) for x in leak.ambiguity_group}
    # weighted with the supply leak's model error alone, the one step rules X_B out;
    # with the model error of every contender, the run cannot tell them apart
    assert groups[False] == {"supply"}
    assert groups[True] == {"supply", "X_B"}


def _found(result):
    return {str(leak.location): {str(x) for x in leak.ambiguity_group} for leak in result.leaks}


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_one_leak_split_between_locations_the_run_cannot_tell_apart_is_one_leak(seed):
    from pneufdd.diagnosis.engine import _locate_weighted, run_whitener

    # the plant draws 80 % of a supply leak's air in the step the line is vented
    ref, observed = _line_held_all_but_one_step(seed, vented_share=0.8)
    effects = ref.leak_effects()
    settings = replace(ref.localisation, simulate_explanations=False)
    chosen = replace(settings, group_model_error=False)
    split = locate(observed, effects, run_whitener(ref, effects, observed, 10, chosen), chosen)
    assert set(_found(split)) == {"supply", "X_B"}  # with the supply's model error alone
    result, _ = _locate_weighted(ref, effects, observed, 10, settings)
    assert _found(result) == {"supply": {"supply", "X_B"}}
    assert result.leaks[0].mass_flow == pytest.approx(8e-4, rel=0.03)


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_a_second_leak_the_groups_model_error_would_hide_is_kept(seed):
    from pneufdd.diagnosis.engine import _locate_weighted, run_whitener

    ref, observed = _line_held_all_but_one_step(seed)
    sig = ref.signatures
    # X_B, in the supply's group, may on a real machine move the features as a Y_A
    # leak does; the run has a true Y_A leak beside the X_B one
    y_a = np.stack([sig.effect(3, s) for s in sig.deviation_sizes])
    deviations = np.array(sig.plant_deviations)
    deviations[:, 2] += 3.0 * np.random.default_rng(99).normal(size=(8, 1, 1)) * y_a[None]
    sig = sig.with_plant_deviations(deviations, sig.deviation_sizes)
    ref = ReferenceModel.build(synth_table(60, seed=100), signatures=sig)
    effects = ref.leak_effects()
    observed = observed + sig.effect(3, 2e-4)
    settings = replace(ref.localisation, simulate_explanations=False)
    hidden = locate(observed, effects, run_whitener(ref, effects, observed, 10, settings), settings)
    assert set(_found(hidden)) == {"supply"}
    result, _ = _locate_weighted(ref, effects, observed, 10, settings)
    assert set(_found(result)) == {"supply", "Y_A"}
    sizes = {str(leak.location): leak.mass_flow for leak in result.leaks}
    assert sizes["Y_A"] == pytest.approx(2e-4, rel=0.05)


def test_references_saved_before_the_group_model_error_keep_the_chosen_leaks():
    data = LocalisationSettings().to_dict()
    del data["group_model_error"]
    assert LocalisationSettings.from_dict(data).group_model_error is False
    assert LocalisationSettings().group_model_error is True
    with pytest.raises(InputError, match="group_model_error"):
        LocalisationSettings(group_model_error=1)  # type: ignore[arg-type]
