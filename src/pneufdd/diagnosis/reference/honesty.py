"""What a reference's own cycles can vouch for (issue 33, item 5).

A reference's false-alarm rate is estimated by cross-validation on its own cycles, so
it is only as good as their number and independence:

* the rate is reported with the number of **independent** cycles behind it and the
  number of recordings, and with its exact binomial (Clopper-Pearson) 95 % confidence
  interval, ``scipy.stats.beta``: ``k`` held-out cycles above the threshold out of
  ``n`` give ``[B(0.025; k, n - k + 1), B(0.975; k + 1, n - k)]`` (0 and 1 at the
  ends). 0 false alarms in 20 cycles is an upper bound of 17 %, not "0.00 %";
* a **warning** when the threshold is far outside the spread of the reference's own
  held-out statistics: above 10 times their largest, or below their median (the
  statistic's distribution was fitted on something other than what the cycles show:
  repeated cycles, a constant channel, a quantised channel without its floor);
* how many cycles a good reference needs (:data:`RECOMMENDED_REFERENCE_CYCLES`, in
  several recordings) and how many it got;
* the **sessions** of triggered captures
  (:func:`pneufdd.diagnosis.captures.capture_sessions`), and a warning when the
  captures come from fewer sessions than the cross-validation needs to leave one out
  (:data:`~pneufdd.diagnosis.detection.statistic.MIN_GROUPS_FOR_GROUPED_CV`): the
  variation between sessions, which a new run's captures carry, is then not measured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pneufdd.diagnosis.detection.statistic import MIN_GROUPS_FOR_GROUPED_CV
from pneufdd.diagnosis.reference.model import RECOMMENDED_REFERENCE_CYCLES, ReferenceModel

__all__ = ["FAR_OUTSIDE", "ReferenceHonesty", "clopper_pearson", "reference_honesty"]

FAR_OUTSIDE = 10.0
"""Threshold over the largest held-out reference statistic that draws a warning [-]."""


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Exact binomial confidence interval of a rate seen ``k`` times in ``n`` trials [-].

    Examples
    --------
    >>> lo, hi = clopper_pearson(0, 20)
    >>> lo, round(hi, 4)
    (0.0, 0.1684)
    """
    from scipy.stats import beta

    if n <= 0 or not 0 <= k <= n:
        return 0.0, 1.0
    alpha = 1.0 - confidence
    lo = 0.0 if k == 0 else float(beta.ppf(alpha / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - alpha / 2, k + 1, n - k))
    return lo, hi


@dataclass(frozen=True)
class ReferenceHonesty:
    """What the reference's cycles vouch for.

    Attributes
    ----------
    cycles, recordings : int
        Independent reference cycles, and the recordings they come from.
    false_alarms : int
        Held-out reference cycles above the per-cycle threshold.
    rate, rate_low, rate_high : float
        Cross-validated false-alarm rate per cycle and its 95 % interval [-].
    threshold : float
        Per-cycle threshold [-].
    statistics : tuple of float
        Median and largest held-out reference statistic [-].
    warnings : tuple of str
        Threshold far outside the statistics; too few cycles; too few sessions.
    sessions : int
        Sessions the recordings form (:attr:`ReferenceModel.recording_session`; the
        recordings' number when each is its own).
    """

    cycles: int
    recordings: int
    false_alarms: int
    rate: float
    rate_low: float
    rate_high: float
    threshold: float
    statistics: tuple[float, float]
    warnings: tuple[str, ...]
    sessions: int = 0

    def _in_sessions(self) -> str:
        if not self.sessions or self.sessions == self.recordings:
            return ""
        return f" of {self.sessions} session(s)"

    def lines(self) -> list[str]:
        """The report, one line per fact."""
        return [
            f"cross-validated false-alarm rate per cycle {100 * self.rate:.2f} % "
            f"({self.false_alarms} of {self.cycles} independent cycles in "
            f"{self.recordings} recording(s){self._in_sessions()}; "
            f"95 % interval {100 * self.rate_low:.2f}-"
            f"{100 * self.rate_high:.2f} %, Clopper-Pearson)",
            f"threshold {self.threshold:.3g}; held-out reference statistics median "
            f"{self.statistics[0]:.3g}, largest {self.statistics[1]:.3g}",
            f"a good reference needs at least {RECOMMENDED_REFERENCE_CYCLES} leak-free cycles "
            f"in several recordings; this one has {self.cycles} in {self.recordings}",
        ]


def _sessions_warning(recordings: int, sessions: int) -> list[str]:
    if sessions >= min(recordings, MIN_GROUPS_FOR_GROUPED_CV):
        return []
    return [
        f"the reference's {recordings} captures come from {sessions} session(s) (captures "
        "taken one after the other): the variation between sessions, which the captures of "
        "a later run carry, is not measured and the false-alarm rate may be higher than "
        f"stated; record the reference's captures in at least {MIN_GROUPS_FOR_GROUPED_CV} "
        "sessions (other hours or days; docs/captures.md, 'Sessions')"
    ]


def reference_honesty(model: ReferenceModel) -> ReferenceHonesty:
    """The false-alarm rate with its interval, and warnings, of ``model``."""
    det = model.detector
    scores = np.asarray(det.reference_scores_, dtype=np.float64)
    n = int(scores.size)
    k = int(np.count_nonzero(scores > det.threshold_))
    lo, hi = clopper_pearson(k, n)
    groups = model.cycle_recording
    recordings = int(np.unique(groups).size) if groups is not None else max(len(model.sources), 1)
    sessions = len(set(model.recording_session)) if model.recording_session else recordings
    median, largest = float(np.median(scores)), float(np.max(scores))
    threshold = float(det.threshold_)
    warnings = []
    if threshold > FAR_OUTSIDE * largest or threshold < median:
        warnings.append(
            f"the threshold {threshold:.3g} is far outside the spread of the reference's own "
            f"held-out statistics (median {median:.3g}, largest {largest:.3g}): the fitted "
            "distribution does not describe these cycles; check for repeated or constant data"
        )
    if n < RECOMMENDED_REFERENCE_CYCLES:
        warnings.append(
            f"{n} reference cycles: the false-alarm rate is known only to within "
            f"{100 * lo:.1f}-{100 * hi:.1f} %; at least {RECOMMENDED_REFERENCE_CYCLES} "
            "cycles in several recordings are recommended (docs/reference.md, "
            "'Reference length')"
        )
    warnings += _sessions_warning(recordings, sessions)
    return ReferenceHonesty(
        n,
        recordings,
        k,
        k / n if n else 0.0,
        lo,
        hi,
        threshold,
        (median, largest),
        tuple(warnings),
        sessions,
    )
