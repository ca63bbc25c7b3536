"""Leak effects as piecewise-linear functions of the leak size.

A leak's effect on the features is simulated at a ladder of sizes
(:class:`~pneufdd.diagnosis.effects.signatures.SignatureSet`); between them it is interpolated
linearly, through the origin (no leak, no effect), and beyond the largest size the
last segment is extended. :class:`PiecewiseLinear` is that one interpolation, used
for the raw signatures and for their whitened form alike.

On segment ``k`` of location ``l`` the effect is ``V[l, k] + a S[l, k]`` for sizes
``lo[l, k] <= a <= hi[l, k]``, so every least-squares fit of one or two leaks on one
combination of segments is a box-constrained problem in one or two unknowns.
:class:`WhitenedEffects` solves all of them at once from one Gram matrix of the
whitened pieces (eqs. 5.23-5.24 generalised: an exhaustive sparse subset search).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray

__all__ = ["PiecewiseLinear", "WhitenedEffects", "box_least_squares"]

Whitener = Callable[[FloatArray], FloatArray]


def _off(k: int) -> FloatArray:
    """``k x k`` ones with a zero diagonal: the pairs of a set of ``k`` leaks."""
    return np.ones((k, k)) - np.eye(k)


def box_least_squares(
    A: FloatArray, b: FloatArray, lo: FloatArray, hi: FloatArray, start: FloatArray
) -> FloatArray:
    """``argmin |A x - b|`` with ``lo <= x <= hi``, for a few unknowns.

    The bounded-variable least-squares active-set method (Stark & Parker 1995) on the
    normal equations: the unconstrained solution of the free variables, a step that
    would leave the box stopping at the first bound and fixing that variable; once
    the free variables are solved inside the box, the fixed variable whose gradient
    points most into the box is freed. In the few cases it does not settle within
    its iterations (near-collinear columns), :func:`scipy.optimize.lsq_linear`
    solves it. This is the small, repeated problem of :meth:`WhitenedEffects.fit_set`
    without scipy's per-call overhead.

    Examples
    --------
    >>> A = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    >>> box_least_squares(A, np.array([2.0, -1.0, 1.0]), np.zeros(2), np.full(2, 5.0),
    ...                   np.zeros(2)).round(6).tolist()
    [1.5, 0.0]
    """
    G = A.T @ A
    g = A.T @ b
    k = g.size
    ridge = 1e-12 * max(float(np.max(np.diag(G), initial=0.0)), 1e-300)
    x = np.clip(np.asarray(start, dtype=np.float64), lo, hi)
    free = (x > lo) & (x < hi)
    for _ in range(6 * k + 10):
        solved = False
        for _ in range(k + 1):  # solve the free variables inside the box
            F = np.flatnonzero(free)
            if F.size == 0:
                solved = True
                break
            rhs = g[F] - G[np.ix_(F, ~free)] @ x[~free]
            z = np.linalg.solve(G[np.ix_(F, F)] + ridge * np.eye(F.size), rhs)
            if np.all((z > lo[F]) & (z < hi[F])):
                x[F] = z
                solved = True
                break
            d = z - x[F]
            with np.errstate(divide="ignore", invalid="ignore"):
                room = np.where(d > 0, (hi[F] - x[F]) / d, np.where(d < 0, (lo[F] - x[F]) / d, 1.0))
            alpha = float(np.clip(np.min(room), 0.0, 1.0))
            x[F] = np.clip(x[F] + alpha * d, lo[F], hi[F])
            free[F] = (x[F] > lo[F]) & (x[F] < hi[F])
        if not solved:
            continue
        w = g - G @ x  # minus the gradient
        gain = np.where(~free & (x <= lo), w, np.where(~free & (x >= hi), -w, 0.0))
        if float(np.max(gain, initial=0.0)) <= 1e-12 * max(float(np.max(np.abs(g))), 1e-300):
            return x
        free[int(np.argmax(gain))] = True
    from scipy.optimize import lsq_linear

    return np.asarray(lsq_linear(A, b, bounds=(lo, np.maximum(hi, lo + 1e-300))).x)


class PiecewiseLinear:
    """Vector-valued piecewise-linear functions through the origin and given knots.

    Parameters
    ----------
    knots : array_like, shape (n_functions, n_knots)
        Increasing positive abscissae of every function [size unit].
    values : array_like, shape (n_functions, n_knots, n_outputs)
        Function values at the knots [output unit].
    upper : float
        The last segment extends to ``upper`` times the last knot (``inf``: without
        bound); :attr:`hi` holds the resulting segment ends [-].

    Attributes
    ----------
    lo, hi : ndarray, shape (n_functions, n_knots)
        Segment ends [size unit].
    slope, intercept : ndarray, shape (n_functions, n_knots, n_outputs)
        On segment ``k``: ``f(x) = intercept[k] + x slope[k]``.

    Examples
    --------
    >>> f = PiecewiseLinear([[1.0, 2.0]], [[[1.0, 10.0], [3.0, 20.0]]])
    >>> f(0, 1.5).tolist(), f(0, 0.5).tolist(), f(0, 4.0).tolist()
    ([2.0, 15.0], [0.5, 5.0], [7.0, 40.0])
    """

    def __init__(self, knots: npt.ArrayLike, values: npt.ArrayLike, upper: float = np.inf):
        x = np.asarray(knots, dtype=np.float64)
        y = np.asarray(values, dtype=np.float64)
        n_fun, n_knots = x.shape
        xs = np.concatenate([np.zeros((n_fun, 1)), x], axis=1)
        ys = np.concatenate([np.zeros((n_fun, 1, y.shape[2])), y], axis=1)
        self.slope = np.diff(ys, axis=1) / np.diff(xs, axis=1)[:, :, None]
        self.intercept = ys[:, :-1, :] - xs[:, :-1, None] * self.slope
        self.lo = xs[:, :-1]
        self.hi = xs[:, 1:].copy()
        self.hi[:, -1] = xs[:, -1] * upper
        self.n_segments = n_knots

    def segment(self, function: int, x: float) -> int:
        """Index of the segment of ``function`` that holds ``x``."""
        k = int(np.searchsorted(self.lo[function], x, side="right")) - 1
        return min(max(k, 0), int(self.n_segments) - 1)

    def __call__(self, function: int, x: float) -> FloatArray:
        """Value of ``function`` at ``x`` (negative ``x`` is taken as 0)."""
        x = max(float(x), 0.0)
        k = self.segment(function, x)
        return np.asarray(self.intercept[function, k] + x * self.slope[function, k])

    def derivative(self, function: int, x: float) -> FloatArray:
        """Slope of ``function`` on the segment that holds ``x`` (``x`` floored at 0).

        >>> f = PiecewiseLinear([[1.0, 2.0]], [[[1.0, 10.0], [3.0, 20.0]]])
        >>> f.derivative(0, 1.5).tolist(), f.derivative(0, 0.5).tolist()
        ([2.0, 10.0], [1.0, 10.0])
        """
        return np.asarray(self.slope[function, self.segment(function, max(float(x), 0.0))])

    def secant(self, function: int, x: float) -> FloatArray:
        """``f(x) / x``, the effect per unit size at ``x`` (``x`` floored at 1e-300)."""
        return np.asarray(self(function, x) / max(float(x), 1e-300), dtype=np.float64)


class WhitenedEffects(PiecewiseLinear):
    """Whitened leak effects with the least-squares fits of every one or two leaks.

    Parameters
    ----------
    sizes : ndarray, shape (n_locations, n_sizes)
        Simulated sizes of each location [kg/s].
    deltas : ndarray, shape (n_locations, n_sizes, n_features)
        Feature changes at those sizes [feature unit].
    whiten : callable
        Maps feature-change rows to whitened residual components [-].
    target : ndarray
        Whitened observed change [-].
    max_extrapolation : float
        Largest size searched, as a multiple of the largest simulated size [-].

    Attributes
    ----------
    single_sizes, single_rss : ndarray, shape (n_locations,)
        Best size [kg/s] and whitened residual [-] of each single leak.
    pair_sizes : ndarray, shape (n_locations, n_locations, 2)
        Best sizes of each pair ``(l, m)``: at ``l``, at ``m`` [kg/s].
    pair_rss : ndarray, shape (n_locations, n_locations)
        Their whitened residual (inf on the diagonal) [-].
    """

    def __init__(
        self,
        sizes: FloatArray,
        deltas: FloatArray,
        whiten: Whitener,
        target: FloatArray,
        max_extrapolation: float = np.inf,
    ):
        whitened = np.stack([whiten(deltas[loc]) for loc in range(sizes.shape[0])])
        super().__init__(sizes, whitened, max_extrapolation)
        self.target = target
        S, V = self.slope, self.intercept
        n_loc, n_seg = sizes.shape
        Vf, Sf = V.reshape(-1, target.size), S.reshape(-1, target.size)
        shape = (n_loc, n_seg)
        yy = float(target @ target)
        yV, yS = (Vf @ target).reshape(shape), (Sf @ target).reshape(shape)
        VV = (Vf @ Vf.T).reshape(*shape, *shape)
        VS = (Vf @ Sf.T).reshape(*shape, *shape)  # [V index, S index]
        SS = (Sf @ Sf.T).reshape(*shape, *shape)
        self.rss_null = yy
        li, ki = np.meshgrid(np.arange(n_loc), np.arange(n_seg), indexing="ij")
        # the Gram matrix's diagonal blocks: what fits of one leak to any residual need
        self._own = (VV[li, ki, li, ki], VS[li, ki, li, ki], SS[li, ki, li, ki])
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

    @property
    def size_cap(self) -> FloatArray:
        """Largest size searched at each location [kg/s]."""
        return np.asarray(self.hi[:, -1], dtype=np.float64)

    def fit(self, subset: tuple[int, ...]) -> tuple[FloatArray, float]:
        """Sizes [kg/s] and whitened residual [-] of the best fit of 1 or 2 locations."""
        if len(subset) == 1:
            (loc,) = subset
            return np.array([self.single_sizes[loc]]), float(self.single_rss[loc])
        first, second = subset
        return np.asarray(self.pair_sizes[first, second], dtype=np.float64), float(
            self.pair_rss[first, second]
        )

    def additions(self, residual: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The best leak at each location added to what ``residual`` leaves.

        For every location, the size minimising ``|residual - e(a)|`` over its
        piecewise-linear effect, exactly (every segment, clipped to its ends), in one
        pass from the stored Gram blocks: the step of a forward search over sets of
        leaks (:mod:`pneufdd.diagnosis.localisation.subsets`).

        Returns
        -------
        sizes : ndarray, shape (n_locations,)
            Best size at each location [kg/s].
        rss : ndarray, shape (n_locations,)
            The whitened residual left [-].

        Examples
        --------
        >>> model = WhitenedEffects(np.array([[1.0], [1.0]]),
        ...     np.array([[[1.0, 0.0]], [[0.0, 2.0]]]), lambda d: np.atleast_2d(d),
        ...     np.array([3.0, 4.0]))
        >>> sizes, rss = model.additions(np.array([3.0, 4.0]))
        >>> sizes.tolist(), rss.tolist()
        ([3.0, 2.0], [16.0, 9.0])
        """
        r = np.asarray(residual, dtype=np.float64)
        n_loc, n_seg = self.lo.shape
        rV = (self.intercept.reshape(n_loc * n_seg, -1) @ r).reshape(n_loc, n_seg)
        rS = (self.slope.reshape(n_loc * n_seg, -1) @ r).reshape(n_loc, n_seg)
        vv, vs, ss = self._own
        b = rS - vs
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(ss > 0, b / ss, self.lo)
        a = np.clip(a, self.lo, self.hi)
        rss = float(r @ r) - 2 * rV + vv - 2 * a * b + a * a * ss
        k = np.argmin(rss, axis=1)
        rows = np.arange(n_loc)
        return a[rows, k], np.maximum(rss[rows, k], 0.0)

    def set_effect(
        self, subset: tuple[int, ...], sizes: FloatArray, coupling: FloatArray | None = None
    ) -> FloatArray:
        """Whitened effect of a set of leaks, their pairwise interaction included [-]."""
        total = np.zeros_like(self.target)
        for loc, x in zip(subset, sizes, strict=True):
            total = total + self(loc, float(x))
        if coupling is not None:
            a = np.asarray(sizes, dtype=np.float64)
            total = total + 0.5 * np.einsum("i,j,ijn->n", a, a, coupling * _off(a.size)[..., None])
        return total

    def fit_set(
        self,
        subset: tuple[int, ...],
        start: FloatArray,
        coupling: FloatArray | None = None,
        iterations: int = 20,
        tolerance: float = 1e-3,
    ) -> tuple[FloatArray, float]:
        """Sizes of any number of leaks, with their pairwise bilinear interaction.

        Minimises

        .. math::

            \\left| y - \\sum_i E_{l_i}(a_i) - \\sum_{i<j} a_i a_j K_{ij} \\right|^2,
            \\qquad a_i \\ge 0,

        from ``start``: on the segments that hold the current sizes every effect is
        affine, so one step is a bounded linear least-squares problem in all sizes at
        once (:func:`box_least_squares`, the sizes bounded to their segments; the
        interaction linearised at the current sizes, a step that raises the residual
        halved). A size that ends on a segment end moves to the
        neighbouring segment in the next step. It stops when no size moves by more
        than ``tolerance`` of itself and no segment is left to try: a local minimum,
        the generalisation of :meth:`fit` (exact for one or two leaks) and
        :meth:`refine_pair` to sets of leaks.

        Parameters
        ----------
        subset : tuple of int
            Location indices.
        start : ndarray
            Starting sizes [kg/s].
        coupling : ndarray, shape (k, k, n_components), optional
            Whitened interaction per unit of both sizes of each pair (symmetric, the
            diagonal unused) [1/(kg/s)^2]; None: additive.
        iterations : int
            Steps at most [-].
        tolerance : float
            Relative size change that ends the steps [-].

        Returns
        -------
        sizes : ndarray
            Sizes of ``subset`` [kg/s].
        rss : float
            Whitened residual [-].

        Examples
        --------
        Three effects, the second at half its slope between sizes 1 and 2 and flat
        beyond (``E1`` at 1, ``1.5 E1`` from 2 on), an exact mixture:

        >>> E = np.eye(3) + 0.2
        >>> deltas = np.stack([E, E, E], axis=1) * np.array([1.0, 2.0, 4.0])[None, :, None]
        >>> deltas[1, 1:] = deltas[1, 0] * 1.5
        >>> model = WhitenedEffects(np.array([[1.0, 2.0, 4.0]] * 3), deltas,
        ...     lambda d: np.atleast_2d(d), 0.5 * E[0] + 1.2 * E[1] + 3.0 * E[2])
        >>> sizes, rss = model.fit_set((0, 1, 2), np.ones(3))
        >>> [round(float(x), 6) for x in sizes], rss < 1e-20
        ([0.5, 1.4, 3.0], True)
        """
        idx = list(subset)
        cap = self.size_cap[idx]
        sizes = np.clip(np.asarray(start, dtype=np.float64), 0.0, cap)
        k = len(idx)
        off = _off(k)[..., None]

        def residual_of(x: FloatArray) -> float:
            r = self.target - self.set_effect(subset, x, coupling)
            return float(r @ r)

        rss = residual_of(sizes)
        below = np.zeros(k, dtype=bool)  # last step ended on its segment's lower end
        still = 0
        for _ in range(iterations):
            segs = [
                self.segment(loc, x * (1.0 - 1e-12) if down else x)
                for loc, x, down in zip(idx, sizes, below, strict=True)
            ]
            A = np.stack([self.slope[loc, g] for loc, g in zip(idx, segs, strict=True)], axis=1)
            rhs = self.target - sum(
                self.intercept[loc, g] for loc, g in zip(idx, segs, strict=True)
            )
            if coupling is not None:
                pull = np.einsum("j,ijn->in", sizes, coupling * off)  # d(pair term)/d size
                A = A + pull.T
                rhs = rhs - 0.5 * sizes @ pull + sizes @ pull
            lo = self.lo[idx, segs]
            hi = np.minimum(self.hi[idx, segs], cap)
            hi = np.maximum(hi, lo)
            x = np.clip(box_least_squares(A, rhs, lo, hi, sizes), lo, hi)
            new = residual_of(x)
            if new > rss:  # the linearised interaction overshot: a shorter step
                x = 0.5 * (x + sizes)
                new = residual_of(x)
            if new > rss:
                break
            moved = np.abs(x - sizes) > tolerance * np.maximum(x, 1e-12)
            segs_arr = np.asarray(segs)
            below = (x <= lo * (1.0 + 1e-12)) & (segs_arr > 0)
            sizes, rss = x, new
            still = 0 if moved.any() else still + 1
            if still == 2 or (still == 1 and not below.any()):
                break
        return sizes, rss

    def _best_1d(self, loc: int, target: FloatArray, extra: FloatArray) -> tuple[float, float]:
        best_a, best_rss = 0.0, np.inf
        for k in range(self.n_segments):
            c = target - self.intercept[loc, k]
            slope = self.slope[loc, k] + extra
            g = float(slope @ slope)
            lo, hi = float(self.lo[loc, k]), float(self.hi[loc, k])
            a = min(max(float((c @ slope) / g) if g > 0 else lo, lo), hi)  # clipped
            r = c - a * slope
            rss = float(r @ r)
            if rss < best_rss:
                best_a, best_rss = a, rss
        return best_a, best_rss

    def refine_pair(
        self,
        first: int,
        second: int,
        coupling: FloatArray,
        sizes: tuple[float, float],
        iterations: int = 30,
    ) -> tuple[float, float, float]:
        """Sizes of two leaks with their bilinear interaction ``K``.

        Minimises ``|y - E_first(a) - E_second(b) - a b K|`` by alternating exact
        one-dimensional fits (each piecewise linear in its own size).

        Returns
        -------
        a, b : float
            Sizes of ``first`` and ``second`` [kg/s].
        rss : float
            Whitened residual [-].
        """
        a, b = sizes
        rss = np.inf
        for _ in range(iterations):
            a_old, b_old = a, b
            a, _ = self._best_1d(first, self.target - self(second, b), b * coupling)
            b, rss = self._best_1d(second, self.target - self(first, a), a * coupling)
            if abs(a - a_old) <= 1e-4 * max(a, 1e-12) and abs(b - b_old) <= 1e-4 * max(b, 1e-12):
                break
        return a, b, rss
