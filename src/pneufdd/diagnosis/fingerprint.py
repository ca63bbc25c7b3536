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
at most ``max_leaks`` (1 or 2) locations the non-negative sizes minimise the
weighted residual exactly: the signatures are piecewise linear in size, so on every
combination of segments the fit is a box-constrained least-squares problem in one or
two unknowns, solved in closed form from one Gram matrix of the whitened signature
pieces (an exhaustive sparse subset search instead of :func:`scipy.optimize.nnls`,
whose linear model cannot follow saturating effects such as a line pressure that
drops to atmosphere). A larger subset is preferred only when it lowers the residual by
an information-criterion penalty and by a minimum relative gain. Before the choice,
the best additive pairs are refit with a bilinear interaction term
(:func:`pair_coupling`: a supply leak lowers the pressure every line leak sees, and a
line leak lowers the supply pressure in proportion to the air it draws), so their
effects are not taken as additive. When even that leaves a residual well above the
noise (typically two large leaks), the best explanations are simulated with the digital
twin and chosen among by their simulated residual (:mod:`pneufdd.diagnosis.verify`).

Ambiguity: for each leak of the chosen model, every other location is tried in its
place. Alternatives whose fit is nearly as good (Akaike-type weight
:math:`\\exp(-\\Delta RSS / 2 s^2)` at least ``group_ratio`` of the best, or a
residual at most ``1 + relative_tolerance`` times the best) or whose weighted
signature is nearly collinear with the chosen one form its ambiguity group;
the sensors cannot tell them apart and they are reported together. The confidence is
the weight of the group times the fraction of the observed deviation the model
explains. Explanations that share no location with the chosen one but fit about as
well are listed as alternatives (:class:`Explanation`); a supply leak is always
paired with the alternative "both lines of the best-fitting actuator", and of two
leaks on both lines of one actuator the smaller one's group includes ``supply``:
these explanations draw air alike and supply sensors hardly separate them.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pneufdd.diagnosis.signatures import SignatureSet
from pneufdd.diagnosis.verify import SimulatedEffect, refine_by_simulation, verify_explanations
from pneufdd.errors import InputError, describe
from pneufdd.physics.units import slpm_to_kg_s

__all__ = ["Explanation", "LeakEstimate", "Localisation", "locate", "pair_coupling"]

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
class Explanation:
    """An alternative set of one or two leaks that explains the data about as well.

    Attributes
    ----------
    locations : tuple of str
        Leak locations of the explanation.
    mass_flows : tuple of float
        Their fitted flows [kg/s].
    rss : float
        Weighted residual sum of squares of the explanation [-].
    """

    locations: tuple[str, ...]
    mass_flows: tuple[float, ...]
    rss: float


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
    alternatives : tuple of Explanation
        Other explanations that share no location with the chosen one yet fit about
        as well (e.g. one supply leak versus leaks on both lines of an actuator
        without line sensors), best first; empty when the chosen one stands alone.
    simulated : bool
        True when the explanations were checked and sized by simulation
        (:mod:`pneufdd.diagnosis.verify`); ``rss`` is then the simulated residual.
    """

    leaks: tuple[LeakEstimate, ...]
    rss_null: float
    rss: float
    dof: int
    explained: float
    alternatives: tuple[Explanation, ...] = ()
    simulated: bool = False


class _PiecewiseModel:
    """Whitened leak effects as piecewise-linear functions of size, with a Gram matrix.

    On segment ``k`` of location ``l`` the whitened effect is ``V[l, k] + a S[l, k]``;
    the last segment extends to infinity. Every residual norm of every subset of one
    or two locations follows from inner products among the target, the ``V`` and the
    ``S``; all subsets and segment combinations are solved at once, vectorised.
    """

    def __init__(
        self,
        signatures: SignatureSet,
        whiten: Whitener,
        target: FloatArray,
        max_extrapolation: float = np.inf,
    ):
        n_loc, n_seg = signatures.sizes.shape
        knots = np.concatenate([np.zeros((n_loc, 1)), signatures.sizes], axis=1)
        values = np.stack(
            [
                np.vstack([np.zeros(target.size), whiten(signatures.deltas[loc])])
                for loc in range(n_loc)
            ]
        )  # (n_loc, n_seg + 1, n)
        S = np.diff(values, axis=1) / np.diff(knots, axis=1)[:, :, None]
        V = values[:, :-1, :] - knots[:, :-1, None] * S
        self.S, self.V = S, V
        self.target = target
        self.lo = knots[:, :-1]
        self.hi = knots[:, 1:].copy()
        self.hi[:, -1] = knots[:, -1] * max_extrapolation
        Vf, Sf = V.reshape(-1, target.size), S.reshape(-1, target.size)
        shape = (n_loc, n_seg)
        yy = float(target @ target)
        yV, yS = (Vf @ target).reshape(shape), (Sf @ target).reshape(shape)
        VV = (Vf @ Vf.T).reshape(*shape, *shape)
        VS = (Vf @ Sf.T).reshape(*shape, *shape)  # [V index, S index]
        SS = (Sf @ Sf.T).reshape(*shape, *shape)
        self.rss_null = yy
        self.single_sizes, self.single_rss = self._singles(yy, yV, yS, VV, VS, SS)
        self.pair_sizes, self.pair_rss = self._pairs(yy, yV, yS, VV, VS, SS)

    def _singles(
        self,
        yy: float,
        yV: FloatArray,
        yS: FloatArray,
        VV: FloatArray,
        VS: FloatArray,
        SS: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        n_loc, n_seg = yV.shape
        li, ki = np.meshgrid(np.arange(n_loc), np.arange(n_seg), indexing="ij")
        cc = yy - 2 * yV + VV[li, ki, li, ki]
        b = yS - VS[li, ki, li, ki]
        g = SS[li, ki, li, ki]
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(g > 0, b / g, self.lo)
        a = np.clip(a, self.lo, self.hi)
        rss = cc - 2 * a * b + a * a * g
        k = np.argmin(rss, axis=1)
        rows = np.arange(n_loc)
        return a[rows, k], np.maximum(rss[rows, k], 0.0)

    def _pairs(
        self,
        yy: float,
        yV: FloatArray,
        yS: FloatArray,
        VV: FloatArray,
        VS: FloatArray,
        SS: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        n_loc, n_seg = yV.shape
        li, ki = np.meshgrid(np.arange(n_loc), np.arange(n_seg), indexing="ij")
        dVV, dVS, dSS = VV[li, ki, li, ki], VS[li, ki, li, ki], SS[li, ki, li, ki]
        # axes: (l, k1, m, k2)
        A = (slice(None), slice(None), None, None)
        B = (None, None, slice(None), slice(None))
        cc = yy - 2 * yV[A] - 2 * yV[B] + dVV[A] + dVV[B] + 2 * VV
        b1 = yS[A] - dVS[A] - np.transpose(VS, (2, 3, 0, 1))
        b2 = yS[B] - VS - dVS[B]
        g11, g22, g12 = dSS[A] * np.ones_like(cc), dSS[B] * np.ones_like(cc), SS
        lo1, hi1 = self.lo[A] * np.ones_like(cc), self.hi[A] * np.ones_like(cc)
        lo2, hi2 = self.lo[B] * np.ones_like(cc), self.hi[B] * np.ones_like(cc)

        def value(a1: FloatArray, a2: FloatArray) -> FloatArray:
            ok = np.isfinite(a1) & np.isfinite(a2)
            x1, x2 = np.where(ok, a1, 0.0), np.where(ok, a2, 0.0)
            out = x1 * x1 * g11 + 2 * x1 * x2 * g12 + x2 * x2 * g22 - 2 * x1 * b1 - 2 * x2 * b2
            return np.where(ok, out, np.inf)

        def clip1(g: FloatArray, b: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
            with np.errstate(divide="ignore", invalid="ignore"):
                a = np.where(g > 0, b / g, lo)
            return np.clip(a, lo, hi)

        det = g11 * g22 - g12 * g12
        with np.errstate(divide="ignore", invalid="ignore"):
            a1u = (g22 * b1 - g12 * b2) / det
            a2u = (g11 * b2 - g12 * b1) / det
        inside = (
            (det > 1e-12 * np.maximum(g11 * g22, 1e-300))
            & (a1u >= lo1)
            & (a1u <= hi1)
            & (a2u >= lo2)
            & (a2u <= hi2)
        )
        cands = [(np.where(inside, a1u, np.inf), np.where(inside, a2u, np.inf))]
        for fixed2 in (lo2, hi2):
            cands.append(
                (clip1(g11, b1 - g12 * np.where(np.isfinite(fixed2), fixed2, 0), lo1, hi1), fixed2)
            )
        for fixed1 in (lo1, hi1):
            cands.append(
                (fixed1, clip1(g22, b2 - g12 * np.where(np.isfinite(fixed1), fixed1, 0), lo2, hi2))
            )
        vals = np.stack([value(a1, a2) for a1, a2 in cands])
        pick = np.argmin(vals, axis=0)
        a1 = np.choose(pick, [c[0] for c in cands])
        a2 = np.choose(pick, [c[1] for c in cands])
        rss = cc + np.min(vals, axis=0)
        flat = rss.transpose(0, 2, 1, 3).reshape(n_loc, n_loc, n_seg * n_seg)
        best = np.argmin(flat, axis=2)
        k1, k2 = np.divmod(best, n_seg)
        l_idx, m_idx = np.meshgrid(np.arange(n_loc), np.arange(n_loc), indexing="ij")
        sizes = np.stack(
            [a1[l_idx, k1, m_idx, k2], a2[l_idx, k1, m_idx, k2]], axis=-1
        )  # (l, m, 2): size at l, size at m
        best_rss = np.maximum(np.take_along_axis(flat, best[..., None], axis=2)[..., 0], 0.0)
        best_rss[np.arange(n_loc), np.arange(n_loc)] = np.inf
        return sizes, best_rss

    def fit(self, subset: tuple[int, ...]) -> tuple[FloatArray, float]:
        """Sizes and residual of the best fit of a subset of 1 or 2 locations."""
        if len(subset) == 1:
            (loc,) = subset
            return np.array([self.single_sizes[loc]]), float(self.single_rss[loc])
        first, second = subset
        return np.asarray(self.pair_sizes[first, second], dtype=np.float64), float(
            self.pair_rss[first, second]
        )

    def effect(self, loc: int, size: float) -> FloatArray:
        """Whitened effect of location ``loc`` at ``size``."""
        seg = int(
            np.clip(np.searchsorted(self.lo[loc], size, side="right") - 1, 0, self.lo.shape[1] - 1)
        )
        return np.asarray(self.V[loc, seg] + size * self.S[loc, seg], dtype=np.float64)

    def _best_1d(self, loc: int, target: FloatArray, extra: FloatArray) -> tuple[float, float]:
        best_a, best_rss = 0.0, np.inf
        for k in range(self.lo.shape[1]):
            c = target - self.V[loc, k]
            slope = self.S[loc, k] + extra
            g = float(slope @ slope)
            a = float(
                np.clip(
                    (c @ slope) / g if g > 0 else self.lo[loc, k], self.lo[loc, k], self.hi[loc, k]
                )
            )
            r = c - a * slope
            rss = float(r @ r)
            if rss < best_rss:
                best_a, best_rss = a, rss
        return best_a, best_rss

    def refine_pair(
        self,
        line: int,
        supply: int,
        coupling: FloatArray,
        sizes: tuple[float, float],
        iterations: int = 30,
    ) -> tuple[float, float, float]:
        """Sizes of two leaks with their bilinear interaction ``K``.

        Minimises ``|y - E_line(a) - E_supply(b) - a b K|`` by alternating exact
        one-dimensional fits (each piecewise linear in its own size). ``supply`` may be
        any second location (see :func:`pair_coupling`).

        Returns
        -------
        a, b : float
            Sizes of ``line`` and ``supply`` [kg/s].
        rss : float
            Whitened residual [-].
        """
        a, b = sizes
        rss = np.inf
        for _ in range(iterations):
            a_old, b_old = a, b
            a, _ = self._best_1d(line, self.target - self.effect(supply, b), b * coupling)
            b, rss = self._best_1d(supply, self.target - self.effect(line, a), a * coupling)
            if abs(a - a_old) <= 1e-4 * max(a, 1e-12) and abs(b - b_old) <= 1e-4 * max(b, 1e-12):
                break
        return a, b, rss

    def column(self, loc: int, size: float) -> FloatArray:
        """Whitened effect of location ``loc`` at ``size``, per unit size (secant)."""
        seg = int(
            np.clip(np.searchsorted(self.lo[loc], size, side="right") - 1, 0, self.lo.shape[1] - 1)
        )
        return np.asarray(
            (self.V[loc, seg] + size * self.S[loc, seg]) / max(size, 1e-300), dtype=np.float64
        )


def pair_coupling(
    signatures: SignatureSet, reference_size: float | None = None
) -> Callable[[int, int], FloatArray | None] | None:
    r"""Bilinear interaction of two simultaneous leaks, per unit of both sizes.

    A supply leak lowers the pressure every line leak sees; its interaction with line
    ``m`` is simulated and stored (``SignatureSet.interaction_slope``, :math:`K_m`).
    A line leak ``l`` lowers the supply pressure too, in proportion to the supply air
    it draws: the fraction :math:`f_l` of a supply leak of the same nominal size,
    measured on the signatures as the ratio of their supply-flow (``Q_In.mean``)
    changes. Two leaks then interact as (an extension of the vector sum of eqs.
    5.23-5.24 with the supply-pressure coupling of section 5.3.1.5)

    .. math::

        \Delta x = e_l(a_l) + e_m(a_m) + a_l a_m (f_l K_m + f_m K_l),
        \qquad f_{supply} = 1,\; K_{supply} = 0.

    Parameters
    ----------
    signatures : SignatureSet
        Signatures with their supply interaction.
    reference_size : float, optional
        Size at which :math:`f_l` is measured; the supply ladder's point nearest
        30 SLPM by default [kg/s].

    Returns
    -------
    callable or None
        ``coupling(l, m)`` -> interaction per unit of both sizes
        [feature unit / (kg/s)^2], or None for a pair it cannot model (two line leaks
        without a supply-flow feature); None when the signatures carry no interaction
        or no supply location.
    """
    if signatures.interaction is None or "supply" not in signatures.locations:
        return None
    supply = signatures.locations.index("supply")
    if reference_size is None:
        ladder = signatures.sizes[supply]
        reference_size = float(ladder[np.argmin(np.abs(ladder - float(slpm_to_kg_s(30.0))))])
    flow = np.array([name.startswith("Q_In.mean") for name in signatures.feature_names])
    share: FloatArray | None = None
    if np.any(flow):
        base = float(np.sum(signatures.effect(supply, reference_size)[flow]))
        if base > 0:
            share = np.array(
                [
                    float(np.sum(signatures.effect(loc, reference_size)[flow])) / base
                    for loc in range(len(signatures.locations))
                ]
            )
            share[supply] = 1.0
    slopes = [
        np.zeros(signatures.n_features) if loc == supply else signatures.interaction_slope(loc)
        for loc in range(len(signatures.locations))
    ]

    def coupling(first: int, second: int) -> FloatArray | None:
        k1, k2 = slopes[first], slopes[second]
        if k1 is None or k2 is None:
            return None
        if supply in (first, second):
            return k1 + k2
        if share is None:
            return None
        return np.asarray(share[first] * k2 + share[second] * k1, dtype=np.float64)

    return coupling


def locate(
    observed: FloatArray,
    signatures: SignatureSet,
    whiten: Whitener,
    max_leaks: int = 2,
    min_relative_gain: float = 0.1,
    group_ratio: float = 0.05,
    collinear_cos: float = 0.995,
    min_flow: float = 4.3e-5,
    relative_tolerance: float = 0.5,
    max_extrapolation: float = 1.25,
    refine_top: int = 20,
    max_alternatives: int = 3,
    both_lines_max_ratio: float = 30.0,
    simulate: SimulatedEffect | None = None,
    misfit_ratio: float = 3.0,
    severe_misfit_ratio: float = 20.0,
    added_leak_gain: float = 0.5,
    group_checks: int = 3,
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
    relative_tolerance : float
        Alternatives whose weighted residual is at most ``1 + relative_tolerance``
        times the best join the group: the fit barely changes when they are swapped
        in, which matters when the residual is dominated by model error (effects of
        simultaneous leaks are only approximately additive) rather than noise [-].
    max_extrapolation : float
        Largest size considered, as a multiple of the largest simulated size: beyond
        the ladder the effects are extrapolated linearly, and an unbounded
        extrapolation lets one huge leak absorb a second, real one [-].
    refine_top : int
        Number of best additive pairs whose sizes are refined with their bilinear
        interaction (:func:`pair_coupling`) before the model is chosen [-].
    max_alternatives : int
        Largest number of alternative explanations reported: sets of one or two
        locations, disjoint from the chosen ones, whose residual is at most
        ``1 + relative_tolerance`` times the chosen one [-].
    both_lines_max_ratio : float
        A supply leak's alternative "both lines of one actuator" is offered only when
        the additive residual of those two leaks is at most this multiple of the
        chosen model's: their joint effect is far from additive, so a generous
        multiple, but an explanation 100 times worse is no explanation (30: the
        largest multiple among development pairs where it held the truth was 27.6) [-].
    min_flow : float
        Smallest leak reported; a model needing a smaller leak is not considered
        (2 SLPM by default, below the leak valve's first turn) [kg/s].
    simulate : callable, optional
        Whitened effect of a set of leaks ``{location index: size [kg/s]}`` simulated
        with the digital twin (None when the machine cannot run with them). When
        given and the best signature fit leaves ``rss > misfit_ratio * dof``, the best
        explanations are simulated and sized against the simulator
        (:func:`~pneufdd.diagnosis.verify.verify_explanations`) and the choice, the
        ambiguity groups and the alternatives are made among simulated explanations
        only.
    misfit_ratio : float
        Residual per component above which the signature model is deemed not to
        describe the run and ``simulate`` is used, when the signatures chose two
        leaks [-].
    severe_misfit_ratio : float
        The same when the signatures chose one leak: single leaks are interpolated
        from simulations of that very leak and fit well (development: at most 51 for
        6-turn leaks), a pair whose interaction the signatures miss leaves 30-1,500 [-].
    added_leak_gain : float
        When the signatures chose one leak, simulated explanations add a second only
        if it lowers the residual by this fraction (on development single leaks a
        spurious 3-7 SLPM second leak lowered it by 10-44 %; on development pairs
        true second leaks mostly lowered it by more than 90 %) [-].
    group_checks : int
        With simulated explanations, alternatives simulated per leak for its
        ambiguity group (the signature model's best in that slot) [-].

    Returns
    -------
    Localisation
        The leaks, largest first, with ambiguity groups and confidences.

    Examples
    --------
    >>> names = ("f1", "f2", "f3")
    >>> sig = SignatureSet(("supply", "X_A"), np.array([[4.0], [4.0]]),
    ...     np.array([[[4.0, 4.0, 4.0]], [[0.0, 8.0, 0.0]]]), names, np.array([6e5, 6e5]))
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
    if max_leaks > 2:
        raise InputError(describe("max_leaks", max_leaks, "1 or 2"))
    target = whiten(obs)[0]
    n_loc = len(signatures.locations)
    model = _PiecewiseModel(signatures, whiten, target, max_extrapolation)

    def column(loc: int, size: float) -> FloatArray:
        return model.column(loc, size)

    rss_null = float(target @ target)
    dof = int(target.size)
    best: dict[int, tuple[tuple[int, ...], FloatArray, float]] = {0: ((), np.zeros(0), rss_null)}
    fits: dict[tuple[int, ...], tuple[FloatArray, float]] = {}
    for k in range(1, min(max_leaks, n_loc) + 1):
        for subset in itertools.combinations(range(n_loc), k):
            coef, rss = model.fit(subset)
            fits[subset] = (coef, rss)
            if np.any(coef < min_flow):
                continue
            if k not in best or rss < best[k][2]:
                best[k] = (subset, coef, rss)
    coupling = pair_coupling(signatures)
    if coupling is not None and 2 in best:
        ranked = sorted(
            (fit[1], sub)
            for sub, fit in fits.items()
            if len(sub) == 2 and np.all(fit[0] >= min_flow)
        )
        for _, sub in ranked[:refine_top]:
            term = coupling(*sub)
            if term is None:
                continue
            a, b, rss_i = model.refine_pair(
                sub[0], sub[1], whiten(term)[0], (float(fits[sub][0][0]), float(fits[sub][0][1]))
            )
            if rss_i < fits[sub][1] and min(a, b) >= min_flow:
                fits[sub] = (np.array([a, b]), rss_i)
                if rss_i < best[2][2]:
                    best[2] = (sub, fits[sub][0], rss_i)
    chosen = _choose(best, dof, min(max_leaks, n_loc), min_relative_gain)
    simulated = False
    misfit = best[chosen][2] / max(dof, 1)
    if (
        simulate is not None
        and chosen > 0
        and misfit > misfit_ratio
        and (chosen > 1 or misfit > severe_misfit_ratio)
    ):
        pairs_too = max_leaks > 1
        if pairs_too:
            for sub in itertools.combinations(range(n_loc), 2):
                fits.setdefault(sub, model.fit(sub))
        checked = verify_explanations(
            target,
            fits,
            n_loc,
            simulate,
            model.hi[:, -1],
            min_flow,
            top_pairs=3 if pairs_too else 0,
            partners=3 if pairs_too else 0,
        )
        if checked:
            simulated = True
            fits = {sub: (fit.sizes, fit.rss) for sub, fit in checked.items()}
            best = {0: best[0]}
            for cand, (cand_sizes, cand_rss) in fits.items():
                k = len(cand)
                if (
                    k <= max_leaks
                    and np.all(cand_sizes >= min_flow)
                    and (k not in best or cand_rss < best[k][2])
                ):
                    best[k] = (cand, cand_sizes, cand_rss)
            # a second leak the signatures did not ask for must explain much more:
            # the simulated residual also holds the run's own random conditions,
            # which a small extra leak can partly absorb
            gain = min_relative_gain if chosen > 1 else max(min_relative_gain, added_leak_gain)
            chosen = _choose(best, dof, min(max_leaks, n_loc), gain)
    subset, coef, rss = best[chosen]
    s2 = max(1.0, rss / max(dof - len(subset), 1))
    explained = 0.0 if rss_null <= 0 else max(0.0, 1.0 - rss / rss_null)
    leaks: list[LeakEstimate] = []
    for slot, loc in enumerate(subset):
        others = tuple(x for x in subset if x != loc)
        alternatives: list[tuple[float, int, float]] = []
        if simulated:
            # only simulated explanations are compared: check the alternatives the
            # signature model ranks best in this slot
            ranked_alts = sorted(
                (model.fit(tuple(sorted((*others, alt))))[1], alt)
                for alt in range(n_loc)
                if alt not in subset
            )
            for _, alt in ranked_alts[:group_checks]:
                trial = tuple(sorted((*others, alt)))
                if trial not in fits:
                    start = np.array(
                        [coef[subset.index(i)] if i in others else coef[slot] for i in trial]
                    )
                    assert simulate is not None
                    refined = refine_by_simulation(
                        trial, start, target, simulate, model.hi[list(trial), -1]
                    )
                    if refined is not None:
                        fits[trial] = (refined.sizes, refined.rss)
        for alt in range(n_loc):
            if alt in others:
                continue
            trial = tuple(sorted((*others, alt)))
            if trial not in fits:
                if simulated:
                    continue
                fits[trial] = model.fit(trial)
            alt_coef, alt_rss = fits[trial]
            alt_size = float(alt_coef[trial.index(alt)])
            alternatives.append((alt_rss, alt, alt_size))
        rss_min = min(a[0] for a in alternatives)
        weights = {alt: np.exp(-(r - rss_min) / (2.0 * s2)) for r, alt, _ in alternatives}
        rss_of = {alt: r for r, alt, _ in alternatives}
        sizes = {alt: size for _, alt, size in alternatives}
        chosen_col = column(loc, float(coef[slot]))
        members = []
        for alt, w in weights.items():
            if sizes[alt] < min_flow and alt != loc:
                continue
            alt_col = column(alt, sizes[alt])
            norm = float(np.linalg.norm(chosen_col) * np.linalg.norm(alt_col))
            cos = float(chosen_col @ alt_col) / norm if norm > 0 else 0.0
            close = rss_of[alt] <= (1.0 + relative_tolerance) * rss_min
            if (
                alt == loc
                or w >= group_ratio * max(weights.values())
                or close
                or cos >= collinear_cos
            ):
                members.append(alt)
        members.sort(key=lambda a: -weights[a])
        if (
            slot == int(np.argmin(coef))
            and _same_actuator(signatures.locations, subset)
            and "supply" in signatures.locations
        ):
            # Both lines of one actuator draw air like a supply leak: the smaller one
            # may stand for a supply leak (see _both_lines_alternative).
            supply = signatures.locations.index("supply")
            if supply not in members:
                members.append(supply)
            if supply not in sizes:  # not simulated: the signature model's size
                trial = tuple(sorted((*others, supply)))
                sizes[supply] = float(model.fit(trial)[0][trial.index(supply)])
                weights[supply] = 0.0
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
    disjoint = sorted(
        (fit[1], sub, fit[0])
        for sub, fit in fits.items()
        if subset
        and not set(sub) & set(subset)
        and np.all(fit[0] >= min_flow)
        and fit[1] <= (1.0 + relative_tolerance) * rss
    )[:max_alternatives]
    explanations = [
        Explanation(
            tuple(signatures.locations[i] for i in sub),
            tuple(float(x) for x in flows),
            float(r),
        )
        for r, sub, flows in disjoint
    ]
    both_lines = _both_lines_alternative(
        signatures, subset, coef, model, rss, min_flow, both_lines_max_ratio
    )
    if both_lines is not None and all(
        set(both_lines.locations) != set(e.locations) for e in explanations
    ):
        explanations.append(both_lines)
    return Localisation(
        tuple(leaks),
        rss_null,
        float(rss),
        dof,
        float(explained),
        tuple(explanations),
        simulated,
    )


def _choose(
    best: dict[int, tuple[tuple[int, ...], FloatArray, float]],
    dof: int,
    max_leaks: int,
    min_relative_gain: float,
) -> int:
    """Number of leaks: one more only when the residual drops by the penalty and gain."""
    chosen = 0
    for k in range(1, max_leaks + 1):
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
    return chosen


def _same_actuator(locations: tuple[str, ...], subset: tuple[int, ...]) -> bool:
    """True when ``subset`` is the extend and the retract line of one actuator."""
    names = sorted(locations[i] for i in subset)
    return (
        len(names) == 2
        and names[0].endswith("_A")
        and names[1].endswith("_B")
        and names[0][:-2] == names[1][:-2]
    )


def _both_lines_alternative(
    signatures: SignatureSet,
    subset: tuple[int, ...],
    sizes: FloatArray,
    model: _PiecewiseModel,
    chosen_rss: float,
    min_flow: float,
    max_ratio: float,
) -> Explanation | None:
    """A supply leak re-explained as leaks on both lines of one actuator.

    Leaks on the extend and the retract line of one actuator draw air in every step,
    like a supply leak; with supply sensors (and without line sensors on that
    actuator) the two explanations are physically near-indistinguishable, and their
    simultaneous effect is far from the additive model, so residuals cannot separate
    them. When the chosen model holds a supply leak, the actuator whose two lines fit
    best (additive residual, the same model for every actuator) replaces it; the
    chosen model's other leaks are kept (a kept leak on one of those lines adds to
    its flow). An actuator whose fit needs a size at the size cap cannot produce the
    supply leak's effect and is not offered, nor one whose additive residual exceeds
    ``max_ratio`` times the chosen model's ``rss`` (only the residual of the two line
    leaks is compared, not the kept leaks).
    """
    if "supply" not in signatures.locations:
        return None
    supply = signatures.locations.index("supply")
    if supply not in subset:
        return None
    keep = [i for i in subset if i != supply]
    best: tuple[float, int, int] | None = None
    for a, name in enumerate(signatures.locations):
        partner = name[:-2] + "_B"
        if not name.endswith("_A") or partner not in signatures.locations:
            continue
        b = signatures.locations.index(partner)
        flows, rss = model.fit((a, b))
        at_cap = np.any(flows >= (1.0 - 1e-9) * model.hi[[a, b], -1])
        if np.all(flows >= min_flow) and not at_cap and (best is None or rss < best[0]):
            best = (rss, a, b)
    if best is None:
        return None
    rss, a, b = best
    if rss > max_ratio * chosen_rss:
        return None
    pair_flows = model.fit((a, b))[0]
    fitted = {a: float(pair_flows[0]), b: float(pair_flows[1])}
    for i in keep:
        fitted[i] = fitted.get(i, 0.0) + float(sizes[subset.index(i)])
    return Explanation(
        tuple(signatures.locations[i] for i in fitted),
        tuple(fitted.values()),
        float(rss),
    )
