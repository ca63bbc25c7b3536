"""Locate and size leaks: a non-negative decomposition into leak signatures.

The observed change of the per-step features of a run against the leak-free
reference, :math:`\\Delta x`, is explained as the vector sum of the effects of one or
several leaks (eqs. 5.23-5.24, generalised from the 2-D vectorized map to all
features):

.. math::

    \\Delta x \\approx \\sum_{l \\in M} a_l\\, s_l(a_l), \\qquad a_l \\ge 0,

where :math:`s_l(a)` is location ``l``'s signature per unit leak flow at size ``a``
(:class:`~pneufdd.diagnosis.signatures.SignatureSet`). The fit is weighted by the
reference noise: each feature is divided by its reference standard deviation, the
house-air fluctuation directions are projected out (the same space as
:class:`~pneufdd.diagnosis.statistic.CycleDistanceDetector`), and the residual
is scaled to unit variance for a run mean of ``m`` cycles. For every subset ``M`` of
at most ``max_leaks`` locations the sizes come from :func:`scipy.optimize.nnls`,
refined a few times with the secant signature at the current size (the effects are
not exactly linear). A larger subset is preferred only when it lowers the residual by
more than an information-criterion penalty and by a minimum relative gain.

Ambiguity: for each leak of the chosen model, every other location is tried in its
place. Alternatives whose fit is nearly as good (Akaike-type weight
:math:`\\exp(-\\Delta RSS / 2 s^2)` at least ``group_ratio`` of the best) or whose
weighted signature is nearly collinear with the chosen one form its ambiguity group;
the sensors cannot tell them apart and they are reported together. The confidence is
the weight of the group times the fraction of the observed deviation the model
explains.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import nnls

from pneufdd.diagnosis.signatures import SignatureSet
from pneufdd.errors import InputError, describe

__all__ = ["LeakEstimate", "Localisation", "locate"]

FloatArray = npt.NDArray[np.float64]
Whitener = Callable[[FloatArray], FloatArray]


@dataclass(frozen=True)
class LeakEstimate:
    """One leak found by the decomposition.

    Attributes
    ----------
    location : str
        Most likely location.
    mass_flow : float
        Estimated leak flow at the location's nominal pressure [kg/s].
    ambiguity_group : tuple of str
        Locations the sensors cannot tell apart from ``location`` (best first,
        ``location`` included); one element when unambiguous.
    group_mass_flows : tuple of float
        Leak flow each group member would need to explain the data [kg/s].
    confidence : float
        Probability-like confidence that a leak lies in the ambiguity group [-].
    """

    location: str
    mass_flow: float
    ambiguity_group: tuple[str, ...]
    group_mass_flows: tuple[float, ...]
    confidence: float


@dataclass(frozen=True)
class Localisation:
    """Result of :func:`locate`.

    Attributes
    ----------
    leaks : tuple of LeakEstimate
        Leaks found, largest flow first.
    rss_null : float
        Weighted residual sum of squares without any leak [-].
    rss : float
        Weighted residual sum of squares of the chosen model [-].
    dof : int
        Number of weighted residual components [-].
    explained : float
        ``1 - rss / rss_null``, the fraction of the deviation explained [-].
    """

    leaks: tuple[LeakEstimate, ...]
    rss_null: float
    rss: float
    dof: int
    explained: float


def _fit_subset(
    target: FloatArray,
    columns: Callable[[int, float | None], FloatArray],
    subset: tuple[int, ...],
    refinements: int,
) -> tuple[FloatArray, float]:
    sizes: list[float | None] = [None] * len(subset)
    coef = np.zeros(len(subset))
    rss = float(target @ target)
    for _ in range(refinements + 1):
        A = np.column_stack([columns(loc, s) for loc, s in zip(subset, sizes, strict=True)])
        coef, norm = nnls(A, target)
        rss = float(norm) ** 2
        new = [float(c) if c > 0 else None for c in coef]
        if new == sizes:
            break
        sizes = new
    return np.asarray(coef, dtype=np.float64), rss


def locate(
    observed: FloatArray,
    signatures: SignatureSet,
    whiten: Whitener,
    max_leaks: int = 2,
    min_relative_gain: float = 0.1,
    group_ratio: float = 0.05,
    collinear_cos: float = 0.995,
    refinements: int = 3,
) -> Localisation:
    """Decompose an observed feature change into non-negative leak contributions.

    Parameters
    ----------
    observed : ndarray, shape (n_features,)
        Mean feature change of the run against the leak-free reference
        [feature unit].
    signatures : SignatureSet
        Signatures over the same features.
    whiten : callable
        Maps feature-change vectors (rows, feature unit) to weighted residual
        components of unit noise variance [-]: standardisation by the reference
        spread, the supply-fluctuation projection and the run-length scaling.
    max_leaks : int
        Largest number of simultaneous leaks considered [-].
    min_relative_gain : float
        A model with one more leak must lower the weighted residual by at least this
        fraction [-].
    group_ratio : float
        Alternatives whose Akaike-type weight is at least this fraction of the best
        join the ambiguity group [-].
    collinear_cos : float
        Alternatives whose weighted signature has at least this cosine similarity
        with the chosen one join the group [-].
    refinements : int
        Secant refinements of the signatures at the current size estimate [-].

    Returns
    -------
    Localisation
        The leaks, largest first, with ambiguity groups and confidences.

    Examples
    --------
    >>> names = ("f1", "f2", "f3")
    >>> sig = SignatureSet(("supply", "X_A"), np.array([[1.0], [1.0]]),
    ...     np.array([[[1.0, 1.0, 1.0]], [[0.0, 2.0, 0.0]]]), names, np.array([6e5, 6e5]))
    >>> result = locate(np.array([3.0, 7.0, 3.0]), sig, lambda d: np.atleast_2d(d) * 100.0)
    >>> [(leak.location, round(leak.mass_flow, 6)) for leak in result.leaks]
    [('supply', 3.0), ('X_A', 2.0)]
    """
    obs = np.asarray(observed, dtype=np.float64)
    if obs.shape != (signatures.n_features,):
        raise InputError(
            describe("shape of observed feature change", obs.shape, [(signatures.n_features,)])
        )
    if not np.all(np.isfinite(obs)):
        raise InputError(describe("observed feature change", "NaN or infinite", "finite"))
    if max_leaks < 1:
        raise InputError(describe("max_leaks", max_leaks, ">= 1"))
    target = whiten(obs)[0]
    n_loc = len(signatures.locations)
    cache: dict[tuple[int, float | None], FloatArray] = {}

    def column(loc: int, size: float | None) -> FloatArray:
        key = (loc, None if size is None else round(size, 15))
        if key not in cache:
            cache[key] = whiten(signatures.slope(loc, size))[0]
        return cache[key]

    rss_null = float(target @ target)
    dof = int(target.size)
    best: dict[int, tuple[tuple[int, ...], FloatArray, float]] = {0: ((), np.zeros(0), rss_null)}
    fits: dict[tuple[int, ...], tuple[FloatArray, float]] = {}
    for k in range(1, min(max_leaks, n_loc) + 1):
        for subset in itertools.combinations(range(n_loc), k):
            coef, rss = _fit_subset(target, column, subset, refinements)
            fits[subset] = (coef, rss)
            if np.any(coef <= 0):
                continue
            if k not in best or rss < best[k][2]:
                best[k] = (subset, coef, rss)
    chosen = 0
    for k in range(1, min(max_leaks, n_loc) + 1):
        if k not in best:
            break
        rss_prev = best[chosen][2]
        rss_k = best[k][2]
        s2 = max(1.0, rss_k / max(dof - k, 1))
        penalty = 2.0 * np.log(max(dof, 2)) * s2
        if rss_prev - rss_k > penalty and rss_k < (1.0 - min_relative_gain) * rss_prev:
            chosen = k
        else:
            break
    subset, coef, rss = best[chosen]
    s2 = max(1.0, rss / max(dof - len(subset), 1))
    explained = 0.0 if rss_null <= 0 else max(0.0, 1.0 - rss / rss_null)
    leaks: list[LeakEstimate] = []
    for slot, loc in enumerate(subset):
        others = tuple(x for x in subset if x != loc)
        alternatives: list[tuple[float, int, float]] = []
        for alt in range(n_loc):
            if alt in others:
                continue
            trial = tuple(sorted((*others, alt)))
            if trial not in fits:
                fits[trial] = _fit_subset(target, column, trial, refinements)
            alt_coef, alt_rss = fits[trial]
            alt_size = float(alt_coef[trial.index(alt)])
            alternatives.append((alt_rss, alt, alt_size))
        rss_min = min(a[0] for a in alternatives)
        weights = {alt: np.exp(-(r - rss_min) / (2.0 * s2)) for r, alt, _ in alternatives}
        sizes = {alt: size for _, alt, size in alternatives}
        chosen_col = column(loc, float(coef[slot]))
        members = []
        for alt, w in weights.items():
            if sizes[alt] <= 0:
                continue
            alt_col = column(alt, sizes[alt])
            norm = float(np.linalg.norm(chosen_col) * np.linalg.norm(alt_col))
            cos = float(chosen_col @ alt_col) / norm if norm > 0 else 0.0
            if alt == loc or w >= group_ratio * max(weights.values()) or cos >= collinear_cos:
                members.append(alt)
        members.sort(key=lambda a: -weights[a])
        total = float(sum(weights.values()))
        mass = float(sum(weights[a] for a in members)) / total if total > 0 else 0.0
        best_member = members[0]
        leaks.append(
            LeakEstimate(
                location=signatures.locations[best_member],
                mass_flow=float(sizes[best_member]),
                ambiguity_group=tuple(signatures.locations[a] for a in members),
                group_mass_flows=tuple(float(sizes[a]) for a in members),
                confidence=float(np.clip(mass * explained, 0.0, 1.0)),
            )
        )
    leaks.sort(key=lambda leak: -leak.mass_flow)
    return Localisation(tuple(leaks), rss_null, float(rss), dof, float(explained))
