"""What an explanation leaves: the leaks that could still hide in it, and how sure its sizes are.

A diagnosis names the leaks the evidence supports (issue 38). What it does not name
must be said too:

- the **share of the deviation explained**, ``1 - rss / rss_null`` in the run's
  weighting;
- for every location not reported, the **largest additional leak there that the
  residual cannot reject** (:func:`hidden_leak_bounds`): a profile-likelihood upper
  bound. The chosen leaks are refit around it (linearised: their whitened Jacobian
  is projected out), and the added leak's effect is the signatures' (piecewise
  linear in its size). A size ``a`` is rejected when the residual it leaves exceeds
  the best by more than :math:`\\chi^2_{1,1-2\\alpha}\\, s^2` (2.71 s^2 for a
  one-sided bound at 95 %), with :math:`s^2` the residual scale of the explanation
  (at least 1; larger when model error dominates). Where model error dominates, it
  can cancel a leak's effect: a leak whose whole effect is no larger than what the
  explanation leaves beyond noise could hide too, and the bound is the larger;
- the **covariance of the sizes** (:func:`size_spread`): :math:`s^2 (J^T J)^{-1}`
  of the whitened Jacobian, from which the total flow and its interval follow even
  when the single leaks cannot be separated (two leaks whose effects are nearly
  collinear have a poorly determined difference but a well determined sum);
- the **model error of the sizes** (:func:`model_error_spread`): on each plausible
  plant the leaks act differently from the twin, and the fit would read that
  difference as different sizes. The spread of those readings over the plants is
  added to the covariance, so a total's interval carries the twin's model error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pneufdd.array_types import BoolArray, FloatArray
from pneufdd.diagnosis.effects.piecewise import WhitenedEffects
from pneufdd.location import Location

__all__ = [
    "BOUND_LEVEL",
    "HiddenLeak",
    "Remainder",
    "hidden_leak_bounds",
    "model_error_spread",
    "size_spread",
]

BOUND_LEVEL = 0.95
"""Confidence of the hidden-leak bounds (one-sided) [-]."""

_CHI2_ONE_SIDED_95 = 2.705543454095404
"""``chi2.ppf(0.90, 1)``: the profile-likelihood drop of a one-sided 95 % bound [-]."""


@dataclass(frozen=True)
class HiddenLeak:
    """The largest additional leak at one location that the run cannot rule out.

    Attributes
    ----------
    location : Location
        Where.
    mass_flow : float
        Upper bound of an additional leak's nominal flow there [kg/s].
    at_cap : bool
        The bound is the largest size searched (the run says nothing against any
        size there: the sensors barely see that location).
    """

    location: Location
    mass_flow: float
    at_cap: bool = False


@dataclass(frozen=True)
class Remainder:
    """What a diagnosis's leaks leave unexplained.

    Attributes
    ----------
    explained : float
        Share of the run's weighted deviation the reported leaks explain [-].
    hidden : tuple of HiddenLeak
        For every location without a reported leak, the largest leak that could
        still hide there, largest first.
    level : float
        Confidence of those bounds (one-sided) [-].
    more_leaks_possible : bool
        The run holds evidence of more leaks than reported (:attr:`reasons`).
    reasons : tuple of str
        Why more leaks may be present (empty when none).
    complete_confidence : float
        Probability-like weight of "no further leak" against the best explanation
        with one leak more (1 when none fits) [-].
    next_leak_gain : float
        Fraction of the residual the best explanation with one leak more removes
        (NaN when none was fitted) [-].
    """

    explained: float
    hidden: tuple[HiddenLeak, ...]
    level: float = BOUND_LEVEL
    more_leaks_possible: bool = False
    reasons: tuple[str, ...] = ()
    complete_confidence: float = 1.0
    next_leak_gain: float = float("nan")

    def groups(self) -> list[tuple[str, float, bool]]:
        """The bounds per location group (the supply; each actuator's two lines).

        Returns
        -------
        list of (str, float, bool)
            Group name, the largest bound of its locations [kg/s] and whether that
            bound is the size cap, largest first.

        Examples
        --------
        >>> r = Remainder(0.9, (HiddenLeak(Location.parse("X_A"), 2e-4),
        ...     HiddenLeak(Location.parse("X_B"), 3e-4), HiddenLeak(Location(), 1e-4)))
        >>> r.groups()
        [('X', 0.0003, False), ('supply', 0.0001, False)]
        """
        out: dict[str, tuple[float, bool]] = {}
        for leak in self.hidden:
            name = "supply" if leak.location.actuator is None else leak.location.actuator
            if name not in out or leak.mass_flow > out[name][0]:
                out[name] = (leak.mass_flow, leak.at_cap)
        return sorted(((name, flow, cap) for name, (flow, cap) in out.items()), key=lambda g: -g[1])


def _orthogonal(jacobian: FloatArray | None, n: int) -> FloatArray:
    """An orthonormal basis of the columns of ``jacobian`` (none: shape ``(n, 0)``)."""
    if jacobian is None or jacobian.size == 0:
        return np.zeros((n, 0))
    basis, singular, _ = np.linalg.svd(jacobian, full_matrices=False)
    keep = singular > 1e-10 * max(float(singular[0]), 1e-300)
    return np.asarray(basis[:, keep], dtype=np.float64)


def _largest_within(
    c0: FloatArray,
    c1: FloatArray,
    c2: FloatArray,
    limit: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
) -> FloatArray:
    """Per location, the largest ``a`` on any segment ``[lo, hi]`` with
    ``c0 + c1 a + c2 a^2 <= limit`` (-inf where none) [kg/s]."""
    disc = c1 * c1 - 4.0 * c2 * (c0 - limit)
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where(
            c2 > 0,
            (-c1 + np.sqrt(np.maximum(disc, 0.0))) / (2.0 * c2),
            np.where(c1 < 0, np.inf, np.where(c1 > 0, (limit - c0) / c1, np.inf)),
        )
    q_lo = c0 + c1 * lo + c2 * lo * lo
    feasible = (q_lo <= limit * (1 + 1e-12)) | ((disc >= 0) & (root >= lo))
    return np.asarray(np.max(np.where(feasible, np.clip(root, lo, hi), -np.inf), axis=1))


def hidden_leak_bounds(
    model: WhitenedEffects,
    residual: FloatArray,
    jacobian: FloatArray | None,
    exclude: tuple[int, ...],
    s2: float,
    drop: float = _CHI2_ONE_SIDED_95,
    unexplained: float = 0.0,
) -> tuple[FloatArray, BoolArray]:
    r"""Largest additional leak at each location the residual cannot reject.

    With the explanation's whitened residual :math:`r` and Jacobian :math:`J`
    (its sizes refit linearly: :math:`P = I - QQ^T`, :math:`Q` an orthonormal basis
    of :math:`J`), an added leak of size :math:`a` at location ``l`` leaves

    .. math::

        q_l(a) = \lVert P\,(r - e_l(a)) \rVert^2,

    piecewise quadratic in :math:`a` (the effect :math:`e_l` is piecewise linear).
    The profile bound is the largest :math:`a` up to the size cap with
    :math:`q_l(a) \le \min_a q_l + \mathrm{drop}\; s^2`. It takes the residual
    for noise; where model error dominates it (a plant's leaks act differently from
    the twin's), the error can cancel a leak's effect, and a leak whose whole effect
    is no larger than what the explanation leaves beyond noise could hide there:

    .. math::

        \lVert P\, e_l(a) \rVert^2 \le u + \mathrm{drop}\; s^2,

    with ``u`` = ``unexplained``, the residual beyond its noise expectation. The
    bound is the larger of the two.

    Parameters
    ----------
    model : WhitenedEffects
        The run's whitened effects.
    residual : ndarray
        The explanation's whitened residual [-].
    jacobian : ndarray, shape (n_components, k), optional
        Its whitened effect's derivative by each size [1/(kg/s)]; None: no leak.
    exclude : tuple of int
        Locations not bounded (the reported leaks).
    s2 : float
        Residual scale [-].
    drop : float
        Allowed rise of the residual, in units of ``s2`` [-].
    unexplained : float
        The residual beyond what noise explains, ``max(0, rss - (dof - k))`` [-].

    Returns
    -------
    bounds : ndarray, shape (n_locations,)
        Upper bound per location (0 for ``exclude``) [kg/s].
    at_cap : ndarray of bool
        The bound is the size cap.

    Examples
    --------
    One location whose effect is ``a (1, 0)``, a residual of noise level: a leak of
    size ``sqrt(2.71)`` raises it by 2.71 (with the best fit at ``a = 0.5``, the
    bound is ``0.5 + sqrt(2.71)``); with 9 units of the residual unexplained by noise,
    a leak of effect ``sqrt(9 + 2.71)`` could hide in it:

    >>> model = WhitenedEffects(np.array([[10.0]]), np.array([[[10.0, 0.0]]]),
    ...     lambda d: np.atleast_2d(d), np.zeros(2))
    >>> bounds, cap = hidden_leak_bounds(model, np.array([0.5, 1.0]), None, (), 1.0)
    >>> round(float(bounds[0]), 3), bool(cap[0])
    (2.145, False)
    >>> bounds, _ = hidden_leak_bounds(model, np.array([0.5, 1.0]), None, (), 1.0,
    ...                                unexplained=9.0)
    >>> round(float(bounds[0]), 3)
    3.421
    """
    n_loc, n_seg = model.lo.shape
    r = np.asarray(residual, dtype=np.float64)
    basis = _orthogonal(jacobian, r.size)
    r = r - basis @ (basis.T @ r)
    V = model.intercept.reshape(n_loc * n_seg, -1)
    S = model.slope.reshape(n_loc * n_seg, -1)
    V = V - (V @ basis) @ basis.T
    S = S - (S @ basis) @ basis.T
    rV, rS = V @ r, S @ r
    VV = np.einsum("ij,ij->i", V, V).reshape(n_loc, n_seg)
    VS = np.einsum("ij,ij->i", V, S).reshape(n_loc, n_seg)
    SS = np.einsum("ij,ij->i", S, S).reshape(n_loc, n_seg)
    # q(a) = c0 + c1 a + c2 a^2 on each segment
    c0 = float(r @ r) - 2.0 * rV.reshape(n_loc, n_seg) + VV
    c1 = -2.0 * (rS.reshape(n_loc, n_seg) - VS)
    lo, hi = model.lo, np.minimum(model.hi, model.size_cap[:, None])
    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = np.where(SS > 0, -c1 / (2.0 * SS), lo)
    at = np.clip(vertex, lo, hi)
    q_min = np.min(c0 + c1 * at + SS * at * at, axis=1)
    profile = _largest_within(c0, c1, SS, q_min[:, None] + drop * s2, lo, hi)
    hiding = _largest_within(VV, 2.0 * VS, SS, np.full_like(VV, unexplained + drop * s2), lo, hi)
    bounds = np.asarray(np.maximum(np.maximum(profile, hiding), 0.0), dtype=np.float64)
    cap = np.asarray(bounds >= model.size_cap * (1.0 - 1e-9), dtype=np.bool_)
    for i in exclude:
        bounds[i], cap[i] = 0.0, False
    return bounds, cap


def size_spread(jacobian: FloatArray, s2: float) -> FloatArray:
    r"""A factor :math:`F` of the sizes' covariance :math:`s^2 (J^T J)^{-1} = F F^T` [kg/s].

    Linearised at the fitted sizes, from the singular values of the whitened
    Jacobian (:math:`J = U \Sigma V^T`, :math:`F = s V \Sigma^{-1}`, a ridge of 1e-12
    of the largest :math:`\sigma^2` keeping it finite). A size the run barely
    determines (a column of :math:`J` near zero, or collinear with others) gets a
    large variance; a combination along well determined directions keeps a small
    one: the variance of :math:`g^T a` is :math:`\lVert F^T g \rVert^2`, computed
    without the cancellation a product with the covariance itself would suffer.

    Examples
    --------
    Two leaks with the same effect: each is undetermined, their sum is not:

    >>> F = size_spread(np.array([[1.0, 1.0], [1.0, 1.0]]), 1.0)
    >>> bool((F @ F.T)[0, 0] > 1e6), round(float(np.sum((F.T @ np.ones(2)) ** 2)), 6)
    (True, 0.5)
    """
    J = np.asarray(jacobian, dtype=np.float64)
    _, singular, vt = np.linalg.svd(J, full_matrices=False)
    squares = singular**2
    largest = float(np.max(squares, initial=0.0))
    ridge = 1e-12 * largest if largest > 0 else 1.0
    return np.asarray(np.sqrt(s2) * vt.T / np.sqrt(squares + ridge)[None, :], dtype=np.float64)


def model_error_spread(
    jacobian: FloatArray, deviations: FloatArray, unexplained: float = 0.0
) -> FloatArray:
    r"""A factor :math:`G` of the sizes' covariance from the twin's model error [kg/s].

    On plausible plant ``k`` the leaks' joint effect differs from the twin's by
    :math:`d^{(k)}` (whitened like the run, the leaks' deviations summed:
    :attr:`~pneufdd.diagnosis.effects.signatures.SignatureSet.plant_deviations`).
    Linearised at the fitted sizes, the fit reads it as the size change
    :math:`\delta a^{(k)} = J^{+} d^{(k)}` (:math:`J^{+}` the pseudo-inverse of the
    whitened Jacobian); the model error's covariance is their mean square over the
    ``K`` plants, :math:`\frac{1}{K} \sum_k \delta a^{(k)} \delta a^{(k)T} = G G^T`,
    :math:`G = [\delta a^{(1)} \dots \delta a^{(K)}] / \sqrt{K}`. The mean square, not
    the variance: a deviation every plant shares (a bias of the twin) is an error of
    the sizes too.

    A plant may differ from the twin more than the plausible plants do. What the
    explanation leaves beyond noise (``unexplained``, :math:`u`) is the part of this
    plant's deviation beside the leaks' directions; against the plausible plants'
    mean square there, :math:`\overline{\lVert P d^{(k)} \rVert^2}` (:math:`P` the
    projection beside the columns of :math:`J`), it gives the factor
    :math:`\lambda^2 = \max(1, u / \overline{\lVert P d^{(k)} \rVert^2})` by which
    this plant's deviation is taken to exceed theirs, along the leaks' directions
    too: :math:`G` is multiplied by :math:`\lambda`.

    Parameters
    ----------
    jacobian : ndarray, shape (n_components, k)
        Whitened derivative of the leaks' effect by each size [1/(kg/s)].
    deviations : ndarray, shape (K, n_components)
        Whitened deviation of each plausible plant's effect of the leaks [-].
    unexplained : float
        The explanation's residual beyond its noise expectation [-].

    Returns
    -------
    ndarray, shape (k, K)
        ``G`` [kg/s]; the variance of :math:`g^T a` from model error is
        :math:`\lVert G^T g \rVert^2`.

    Examples
    --------
    One leak whose effect is ``a (1, 1)``; two plants read it 10 % larger and 10 %
    smaller at ``a = 2``: a model error of 0.2 in the size:

    >>> J = np.array([[1.0], [1.0]])
    >>> d = np.array([[0.2, 0.2], [-0.2, -0.2]])
    >>> G = model_error_spread(J, d)
    >>> G.shape, round(float(np.sum(G**2)), 6)
    ((1, 2), 0.04)

    A plant whose deviation beside the leak's direction is 4 times (in square) the
    plausible plants' doubles the spread:

    >>> d = np.array([[0.3, 0.1], [-0.1, -0.3]])
    >>> round(float(np.sum(model_error_spread(J, d, unexplained=0.08) ** 2)), 6)
    0.16
    """
    J = np.asarray(jacobian, dtype=np.float64)
    D = np.atleast_2d(np.asarray(deviations, dtype=np.float64))
    if J.shape[1] == 0 or D.shape[0] == 0:
        return np.zeros((J.shape[1], 0))
    readings = np.linalg.lstsq(J, D.T, rcond=None)[0]
    basis = _orthogonal(J, J.shape[0])
    beside = D.T - basis @ (basis.T @ D.T)
    seen = float(np.mean(np.sum(beside**2, axis=0)))
    scale = max(1.0, unexplained / seen) if seen > 0 else 1.0
    return np.asarray(np.sqrt(scale) * readings / np.sqrt(D.shape[0]), dtype=np.float64)
