"""The settings of leak location and sizing, stored with the reference (``.pnref``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields

import numpy as np

from pneufdd.errors import InputError, describe
from pneufdd.limits import MAX_LEAKS

__all__ = ["LocalisationSettings", "leak_limit"]


_SWITCHES = ("simulate_explanations", "group_model_error")
"""The settings that are on or off (the rest are numbers)."""

_FILE_KEYS = {"min_mass_flow": "min_flow"}
"""Settings stored under another key in ``.pnref`` files (the key files have always had)."""


@dataclass(frozen=True)
class LocalisationSettings:
    """Tuning of leak location and sizing, stored with the reference.

    Attributes
    ----------
    max_leaks : int or None
        Largest number of simultaneous leaks considered [-]. None (the default): as
        many as the evidence supports, up to every location and at most
        :data:`~pneufdd.limits.MAX_LEAKS`; references saved before issue 38 hold 1
        or 2 and keep them (:func:`leak_limit`).
    min_relative_gain : float
        A model with one more leak must lower the weighted residual by at least this
        fraction: on development plants (seeds 7,800,000+, model error weighted), a
        spurious second leak lowered it by at most 32 % and most true second leaks by
        more than 26 %; 0.25 removed nearly all spurious ones and few true ones [-].
    first_leak_gain : float
        When no model passes ``min_relative_gain``, the best single leak is still
        reported if it passes the information criterion and lowers the residual by
        this fraction (:func:`~pneufdd.diagnosis.localisation.model_choice.choose_leak_count`); its
        confidence is then low. 0: in acceptance testing on a scale-2 press-fit-cell
        plant, a 230 SLPM PRESS_A leak was detected, and PRESS_A fitted best, but it
        explained 20 % of the deviation and nothing was located. 1 turns the
        fallback off (references saved before) [-].
    group_ratio : float
        Alternatives whose Akaike-type weight is at least this fraction of the best
        join the ambiguity group [-].
    collinear_cos : float
        Alternatives whose weighted signature has at least this cosine similarity
        with the chosen one join the group [-].
    min_mass_flow : float
        Smallest leak reported; a model needing a smaller leak is not considered
        (2 SLPM by default, below the leak valve's first turn); ``min_flow`` in the
        ``.pnref`` file [kg/s].
    relative_tolerance : float
        Alternatives whose weighted residual is at most ``1 + relative_tolerance``
        times the best join the group, and disjoint explanations within it are listed:
        the fit barely changes when they are swapped in, which matters when the
        residual is dominated by model error rather than noise [-].
    max_extrapolation : float
        Largest size considered, as a multiple of the largest simulated size: beyond
        the ladder the effects are extrapolated linearly, and an unbounded
        extrapolation lets one huge leak absorb a second, real one [-].
    refine_top : int
        Number of best additive pairs refined with their bilinear interaction before
        the model is chosen [-].
    max_alternatives : int
        Largest number of disjoint alternative explanations reported, and of "both
        lines of one actuator" explanations of a supply leak [-].
    both_lines_max_ratio : float
        A supply leak's alternative "both lines of one actuator" is offered only when
        the additive residual of those two leaks is at most this multiple of the
        chosen model's (the largest multiple among development pairs where it held
        the truth was 27.6) [-].
    simulate_explanations : bool
        Check explanations by simulation when the signatures misfit (needs the
        machine's description) [-].
    misfit_ratio : float
        Residual per component above which the signature model is deemed not to
        describe the run, when the signatures chose two leaks [-].
    severe_misfit_ratio : float
        The same when the signatures chose one leak: single leaks are interpolated
        from simulations of that very leak and fit well (development: at most 51 for
        6-turn leaks), a pair whose interaction the signatures miss leaves 30-1,500 [-].
    added_leak_gain : float
        When the signatures chose one leak, simulated explanations add a second only
        if it lowers the residual by this fraction (on development single leaks a
        spurious 3-7 SLPM second leak lowered it by 10-44 %) [-].
    group_checks : int
        With simulated explanations, alternatives simulated per leak for its
        ambiguity group (the signature model's best in that slot). 1: on 60
        development runs of festo-dsd with two leaks and only supply sensors, 1
        instead of 3 reported the same leaks, groups, sizes, confidences and
        alternatives with fewer simulations (references saved before keep their 3) [-].
    probes : int
        With simulated explanations, second leaks probed by simulation beside the
        best single leak: the locations whose signature-model pair with it fits best
        (0: every location). 6 with ``group_checks`` 1 cut the simulations of those
        60 runs from 2,968 to 1,681 (max per run 89 to 52) with the same results;
        references saved before probe every location [-].
    model_error_floor : float
        Independent model error of every feature, as a fraction of the leak's effect
        on it, beside the coherent error sampled on plausible plants
        (:func:`pneufdd.diagnosis.engine.whitener`): 2 %, the calibration class of the
        sensors (``docs/plant-variation.md``) [-].
    imitation_z : float
        A second leak is reported only when its size exceeds this many times the size
        of it that the larger leak's model error imitates: the RMS over the plausible
        plants of the size a fit of the second leak gives to a plant's deviation from
        the larger leak's signature (:func:`pneufdd.diagnosis.engine.imitated_size`).
        Below it, the two-leak explanation is listed as an alternative. 3: three
        standard deviations, as the band of eq. 5.3; 0 turns the check off (references
        saved before it existed) [-].
    min_leak_confidence : float
        Of two leaks, each must be at least this likely to lie in its ambiguity group
        to be reported; otherwise one leak is reported and the pair is listed as an
        alternative. 0.5: a reported leak is more likely there than not (without the
        check, a scale-2 carton-sorter run in acceptance testing reported a 5 SLPM
        second leak at confidence 0.00005); 0 turns the check off (references saved
        before it) [-].
    group_model_error : bool
        The run's weighting holds the model error of every location in the ambiguity
        groups of the first, noise-weighted explanation, not only of its chosen leaks
        (:func:`pneufdd.diagnosis.engine.run_whitener`). A line held pressurised all
        but one step (a 5/2 monostable valve's B line) differs from the supply only in
        that step, where the twin of a drafted cylinder is least sure; weighted with
        the supply leak's model error alone, that step ruled the line out. When that
        weighting finds one leak, the run is located again with the chosen leaks'
        model error, and two leaks found so are kept unless both lie in the one
        leak's group (``engine._locate_weighted``). False: references saved before [-].
    keep_within : float
        With simulated explanations, one stops being sized by simulation when neither
        its simulated residual nor the one a linear model predicts for its next step
        comes within this multiple of the best simulated residual so far
        (:func:`pneufdd.diagnosis.localisation.check.refine_all`); its start is judged by the
        signature model's slopes before its difference steps are simulated. Beyond
        2 an explanation changes no reported leak, group or alternative (an
        alternative or group member needs at most ``1 + relative_tolerance`` = 1.5
        times the best, a single leak outweighs a pair from 1 / (1 -
        ``added_leak_gain``) = 2 times), though a group member forced in by
        :func:`_forced_member` reports the flow of its pair's fit, stopped or not; 4
        leaves a factor 2 for what the linear model misses. 0 turns it off
        (references saved before) [-].

    Examples
    --------
    >>> LocalisationSettings.from_dict(LocalisationSettings(max_leaks=1).to_dict()).max_leaks
    1
    >>> LocalisationSettings.from_dict(LocalisationSettings().to_dict()).max_leaks is None
    True
    """

    max_leaks: int | None = None
    min_relative_gain: float = 0.25
    first_leak_gain: float = 0.0
    group_ratio: float = 0.05
    collinear_cos: float = 0.995
    min_mass_flow: float = 4.3e-5
    relative_tolerance: float = 0.5
    max_extrapolation: float = 1.25
    refine_top: int = 20
    max_alternatives: int = 3
    both_lines_max_ratio: float = 30.0
    simulate_explanations: bool = True
    misfit_ratio: float = 3.0
    severe_misfit_ratio: float = 20.0
    added_leak_gain: float = 0.5
    group_checks: int = 1
    model_error_floor: float = 0.02
    imitation_z: float = 3.0
    probes: int = 6
    min_leak_confidence: float = 0.5
    group_model_error: bool = True
    keep_within: float = 4.0

    def __post_init__(self) -> None:
        if self.max_leaks is not None and (
            isinstance(self.max_leaks, bool)
            or not isinstance(self.max_leaks, int)
            or not 1 <= self.max_leaks <= MAX_LEAKS
        ):
            raise InputError(
                describe(
                    "max_leaks",
                    self.max_leaks,
                    f"None (as many as the evidence supports) or an integer from 1 to {MAX_LEAKS}",
                )
            )
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("max_leaks", *_SWITCHES):
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(describe(f"localisation setting {f.name}", value, "a number"))
            if not np.isfinite(value) or value < 0:
                raise InputError(
                    describe(f"localisation setting {f.name}", value, "a finite number >= 0")
                )
        for name in _SWITCHES:
            if not isinstance(getattr(self, name), bool):
                raise InputError(describe(name, getattr(self, name), [True, False]))
        if 0 < self.keep_within < 1:
            raise InputError(
                describe("localisation setting keep_within", self.keep_within, "0 (off) or >= 1")
            )

    def to_dict(self) -> dict[str, float | int | bool | None]:
        """JSON-compatible form, with the keys of the ``.pnref`` file.

        Examples
        --------
        >>> LocalisationSettings(min_mass_flow=1e-4).to_dict()["min_flow"]
        0.0001
        """
        return {_FILE_KEYS.get(name, name): value for name, value in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, object]) -> LocalisationSettings:
        """Inverse of :meth:`to_dict`; unknown keys are an error."""
        known = {_FILE_KEYS.get(f.name, f.name) for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise InputError(describe("localisation settings", unknown, sorted(known)))
        attribute = {key: name for name, key in _FILE_KEYS.items()}
        data = {attribute.get(key, key): value for key, value in data.items()}
        # settings added later take, for references saved before, the behaviour
        # those references were built with
        before = {
            "imitation_z": 0.0,
            "probes": 0,
            "group_checks": 3,
            "min_leak_confidence": 0.0,
            "first_leak_gain": 1.0,
            "group_model_error": False,
            "keep_within": 0.0,
        }
        return cls(**{**before, **data})  # type: ignore[arg-type]


def leak_limit(settings: LocalisationSettings, n_locations: int) -> int:
    """Most leaks one explanation may hold: ``max_leaks``, the locations, the limit.

    >>> leak_limit(LocalisationSettings(), 19), leak_limit(LocalisationSettings(max_leaks=2), 19)
    (19, 2)
    """
    wanted = MAX_LEAKS if settings.max_leaks is None else settings.max_leaks
    return max(0, min(wanted, n_locations, MAX_LEAKS))
