"""What a standstill plan's states can separate: rank, separable locations, pairs.

The measurements are linear in the leaks' nominal flows ``L`` (each row sees the
locations its state pressurises): ``y = M L`` (:func:`pneufdd.standstill.plan.
measurement_rows`). A location is **separable** when its flow is estimable on its
own: its unit vector lies in the row space of ``M`` (rank of ``M`` unchanged by
appending it). The others form **groups**: locations tied by the null space of ``M``
(a 5/2 valve's two lines and the supply: ``A + B = supply``). Leaks are never
negative, so a single leak at any location is still located if no other location's
column reproduces its measurements with a non-negative size; a **pair** of leaks is
separable when no other set of at most two locations reproduces it with non-negative
sizes, at size ratios 1/3, 1 and 3 (``pairs_separable``). A flow meter's zero error
adds a constant to its rows, which is the supply's column: a supply leak smaller than
the meters' zero tolerance cannot be told from it (a note of the plan); the pair
analysis takes the zero errors as small against the leaks.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
from scipy.optimize import lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.standstill.plan import StandstillPlan, measurement_rows

__all__ = ["PAIR_RATIOS", "analyse_incidence", "with_separability"]

PAIR_RATIOS = (1.0 / 3.0, 1.0, 3.0)
"""Size ratios at which a pair must not be reproduced by another set [-]."""
_TOL = 1e-9


def _rank(m: FloatArray) -> int:
    return int(np.linalg.matrix_rank(m, tol=1e-9)) if m.size else 0


def _groups(
    m: FloatArray, locations: tuple[str, ...], separable: set[str]
) -> list[tuple[str, ...]]:
    """Locations tied together by the null space of ``m`` (union of overlapping
    supports of a null-space basis)."""
    _, sv, vt = np.linalg.svd(m)
    rank = int(np.sum(sv > 1e-9 * max(sv.max(initial=0.0), 1.0)))
    null = vt[rank:]
    parent = {loc: loc for loc in locations if loc not in separable}

    def root(x: str) -> str:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for vec in null:
        members = [locations[k] for k in np.nonzero(np.abs(vec) > 1e-9)[0]]
        members = [x for x in members if x in parent]
        for a, b in itertools.pairwise(members):
            parent[root(a)] = root(b)
    groups: dict[str, list[str]] = {}
    for loc in parent:
        groups.setdefault(root(loc), []).append(loc)
    return [tuple(g) for g in groups.values()]


def _ambiguous_pairs(m: FloatArray) -> set[tuple[int, int]]:
    """Pairs of columns whose measurements another set of at most two columns
    reproduces with non-negative sizes, at one of :data:`PAIR_RATIOS` or more."""
    n = m.shape[1]
    pairs = list(itertools.combinations(range(n), 2))
    ys = np.stack(
        [m[:, a] * r + m[:, b] for a, b in pairs for r in PAIR_RATIOS], axis=1
    )  # rows x (pairs x ratios)
    owner = np.repeat(np.arange(len(pairs)), len(PAIR_RATIOS))
    scale = np.maximum(np.linalg.norm(ys, axis=0), 1.0)
    ambiguous = np.zeros(ys.shape[1], dtype=bool)
    for k, pair in enumerate(pairs):
        if _rank(m[:, list(pair)]) < 2:  # two lines every state treats alike
            ambiguous[owner == k] = True
    for subset in [(k,) for k in range(n)] + pairs:
        cols = m[:, list(subset)]
        z = np.linalg.pinv(cols) @ ys
        exact = np.linalg.norm(cols @ z - ys, axis=0) <= _TOL * scale
        if _rank(cols) < cols.shape[1]:  # not unique: judge the exact ones by a bounded fit
            for j in np.nonzero(exact & ~ambiguous)[0]:
                sol = lsq_linear(cols, ys[:, j], bounds=(0.0, np.inf))
                exact[j] = np.linalg.norm(cols @ sol.x - ys[:, j]) <= 1e-7 * scale[j]
        else:
            exact &= np.all(z >= -_TOL * scale, axis=0)
        if len(subset) == 2:
            exact &= owner != pairs.index(subset)  # a pair reproduces itself
        ambiguous |= exact
    return {pairs[k] for k in np.unique(owner[ambiguous])}


def analyse_incidence(
    m: FloatArray, locations: tuple[str, ...]
) -> tuple[int, list[str], list[tuple[str, ...]], list[tuple[str, str]], list[tuple[str, str]]]:
    """Rank, separable locations, groups, and separable and ambiguous pairs of ``m``.

    Parameters
    ----------
    m : ndarray
        Measurement rows x locations (1 where a row sees a location) [-].
    locations : tuple of str
        Column names.

    Returns
    -------
    (rank, separable, groups, pairs separable, pairs not separable)

    Examples
    --------
    Two 5/2 valves and the supply, home and each toggled (columns supply, X_A, X_B,
    Y_A, Y_B): nothing separable alone, every single leak still located.

    >>> m = np.array([[1, 0, 1, 0, 1], [1, 1, 0, 0, 1], [1, 0, 1, 1, 0]], float)
    >>> rank, sep, groups, ok, bad = analyse_incidence(m, ("s", "XA", "XB", "YA", "YB"))
    >>> rank, sep, groups
    (3, [], [('s', 'XA', 'XB', 'YA', 'YB')])
    >>> ("XA", "YA") in ok, ("s", "XB") in bad
    (True, True)
    """
    rank = _rank(m)
    separable = [
        loc
        for k, loc in enumerate(locations)
        if _rank(np.vstack([m, np.eye(m.shape[1])[k]])) == rank
    ]
    groups = _groups(m, locations, set(separable))
    bad_pairs = _ambiguous_pairs(m)
    good: list[tuple[str, str]] = []
    bad: list[tuple[str, str]] = []
    for a, b in itertools.combinations(range(len(locations)), 2):
        (bad if (a, b) in bad_pairs else good).append((locations[a], locations[b]))
    return rank, separable, groups, good, bad


def with_separability(plan: StandstillPlan) -> StandstillPlan:
    """``plan`` with its rank, separable locations, groups, pairs and notes filled in."""
    m, _ = measurement_rows(plan)
    rank, separable, groups, good, bad = analyse_incidence(m, plan.locations)
    notes = [
        f"{len(plan.states)} states, {m.shape[0]} measurement rows, rank {rank} of "
        f"{len(plan.locations)} locations",
    ]
    if separable:
        notes.append("separated on their own: " + ", ".join(separable))
    for group in groups:
        notes.append(
            "not separated on their own (a single leak is still located; pairs below): "
            + ", ".join(group)
        )
    if plan.mode == "flow":
        notes.append(
            f"the supply leak is told from the zero error of {plan.supply_flow_channel} "
            "only by its size: below the meter's zero tolerance it cannot be"
        )
    else:
        notes.append(
            "each state's leak area is its decay's conductance times the connected volume "
            "of the description (supply_volume_m3 and the lines): a wrong volume scales "
            "every size"
        )
    return dataclasses.replace(
        plan,
        separable=tuple(separable),
        groups=tuple(groups),
        pairs_separable=tuple(good),
        pairs_not_separable=tuple(bad),
        rank=rank,
        notes=tuple(notes),
    )
