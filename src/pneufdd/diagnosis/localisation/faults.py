"""Faults other than leaks as explanations of a run: fitted with the digital twin.

A run that deviates from its reference is first explained by leaks
(:mod:`pneufdd.diagnosis.localisation.search`). A closing meter-out throttle, worn
seals, a slow valve, a late switch or a drifting regulator deviate too, and the leak
model then either explains little of the run or names a leak that is not there. This
module tests those faults as competing explanations (issue 34, item 3):

1. **Hypotheses** (:func:`fault_hypotheses`): every fault kind of the catalogue
   (:data:`pneufdd.sim.faults.FAULT_KINDS`) that makes sense at each place of the
   machine description: a throttle fault on each line with a meter-out throttle;
   friction, a switching delay and a piston-seal leak on each actuator; a spool leak
   in and out on each line; a late switch on each switch the PLC waits for; a drift
   of the regulator. Each has one size, in its own unit, searched on one side (the
   side a fault moves it: a throttle closes, friction grows, the set point drops).
2. **Screening**: each hypothesis is simulated once at its screening size
   (:data:`HYPOTHESES`), with the same twin, seed and leak-free baseline as the leak
   check by simulation (:meth:`LeakEffectModel.simulate_fault`: common random
   numbers, so the screening runs are the same for every run of one reference and
   are cached), and ranked by the residual of its effect scaled linearly.
3. **Sizing**: the :data:`REFINED` best are sized by simulation, a bounded 1-D
   minimisation (:func:`scipy.optimize.minimize_scalar`, at most 8 simulations), and
   ranked by their simulated residual.

The residual is weighted with noise and a model-error floor relative to the larger of
the observed and the explained change per feature (:func:`residual`): the twin's
fault on a real plant (throttles, friction and volumes drawn around the description)
differs from the plant's, and without that floor a feature the twin moves and the
plant barely does (a chamber's lowest pressure) would decide alone.

The caller (:func:`pneufdd.diagnosis.engine.diagnose`) compares the fits with the
leak explanation by the information criterion of the leak search.
"""

from __future__ import annotations

import math
from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.piecewise import Whitener
from pneufdd.errors import InputError
from pneufdd.parallel import thread_map
from pneufdd.sim import MachineDescription
from pneufdd.sim.faults import FAULT_KINDS, Fault

__all__ = [
    "HYPOTHESES",
    "REFINED",
    "SETTINGS",
    "FaultFit",
    "FaultHypothesis",
    "Weighing",
    "cycle_time_change",
    "fault_hypotheses",
    "fit_faults",
    "largest_step_change",
    "residual",
]

HYPOTHESES: dict[str, tuple[float, float, float]] = {
    "throttle": (-1.0, 50.0, 95.0),
    "friction": (1.0, 80.0, 400.0),
    "valve-delay": (1.0, 80.0, 1000.0),
    "piston-leak": (1.0, 40.0, 400.0),
    "valve-leak-in": (1.0, 20.0, 400.0),
    "valve-leak-out": (1.0, 20.0, 400.0),
    "late": (1.0, 100.0, 2000.0),
    "regulator": (-1.0, 0.5, 3.0),
}
"""Kinds tested as explanations: ``kind -> (sign, screening size, largest size)``.

The size searched is ``sign * x`` in the kind's canonical unit with ``0 <= x <=
largest`` (a throttle closing by x % of its Cv, the set point dropping by x bar); the
screening size is the catalogue's large size or near it (``docs/faults.md``)."""

SETTINGS: dict[str, tuple[tuple[float, float, float, str, tuple[float, ...]], ...]] = {
    "throttle": ((1.0, 100.0, 400.0, "%", ()),),
    "cushion": ((-1.0, 60.0, 95.0, "%", (80.0, 90.0)), (1.0, 200.0, 400.0, "%", ())),
}
"""Settings an engineer turns either way, tested besides :data:`HYPOTHESES`:
``kind -> ((sign, screening size, largest size, unit, more screening sizes), ...)``.

A meter-out throttle turned out passes more (up to 5 times its Cv, the catalogue's
+400 %); an end-position cushion screw (Festo PPV, only where the description gives
the cushioning, ``cushion_length_mm``) set tighter or looser, in % of the described
screw's Cv (the catalogue's -95 to +400 %). A tighter screw is screened at -60, -80
and -90 %: its effect grows steeply as the screw closes (on the issue-33 rig, -60 %
adds 17 ms to the stroke, -90 % 185 ms), so one screening scaled linearly never reaches
a badly set cushion and it would not be sized. The issue-34 rig had its meter-out throttle and its
cushioning set wrong (``docs/faults.md``)."""

REFINED = 3
"""Best screened hypotheses sized by simulation [-]."""

_ITERATIONS = 8
"""Simulations per sized hypothesis at most (bounded Brent steps) [-]."""


@dataclass(frozen=True)
class FaultHypothesis:
    """A fault kind at one place of the machine, with the side its size is searched on.

    Attributes
    ----------
    kind : str
        A name of :data:`~pneufdd.sim.faults.FAULT_KINDS`.
    location : str
        Where it sits, as the twin takes it (``PRESS``, ``PRESS_B``, ``S_PRESS_B``,
        ``supply``).
    sign : float
        +1 or -1: the fault's size is ``sign * x``, ``x >= 0``.
    screening : float
        ``x`` of the screening simulation [unit].
    largest : float
        Largest ``x`` [unit].
    size_unit : str
        The size's unit when not the kind's canonical one (a cushion in ``%`` of the
        described screw); empty: canonical.
    more_screening : tuple of float
        Further ``x`` screened, for kinds whose effect is far from linear in the size
        (the best screened size ranks the hypothesis) [unit].

    Examples
    --------
    >>> h = FaultHypothesis("throttle", "PRESS_B", -1.0, 50.0, 95.0)
    >>> h.family, h.unit, h.fault(40.0)
    ('throttle', '%', Fault(location='PRESS_B', kind='throttle', size=-40.0, unit='%', \
start_s=0.0, growth_per_s=0.0, repair_s=None))
    """

    kind: str
    location: str
    sign: float
    screening: float
    largest: float
    size_unit: str = ""
    more_screening: tuple[float, ...] = ()

    @property
    def family(self) -> str:
        """The fault type a diagnosis reports (``throttle``, ``internal-leak``...)."""
        return FAULT_KINDS[self.kind].family

    @property
    def unit(self) -> str:
        """The size's unit (the kind's canonical one unless ``size_unit`` is given)."""
        return self.size_unit or FAULT_KINDS[self.kind].unit

    def fault(self, x: float) -> Fault:
        """The fault of size ``sign * x`` [unit], present from the start."""
        return Fault(self.location, self.kind, self.sign * float(x), self.unit)


@dataclass(frozen=True)
class FaultFit:
    """A fault hypothesis fitted to a run.

    Attributes
    ----------
    hypothesis : FaultHypothesis
        What was fitted.
    size : float
        Fitted size, signed, in the kind's unit.
    rss : float
        Whitened residual sum of squares of the fit [-].
    change : ndarray
        Simulated feature change at ``size`` [feature unit].
    simulated : bool
        True when sized by simulation; False: the screening's linear fit only.
    """

    hypothesis: FaultHypothesis
    size: float
    rss: float
    change: FloatArray
    simulated: bool


def fault_hypotheses(
    machine: MachineDescription, kinds: Sequence[str] | None = None
) -> list[FaultHypothesis]:
    """Every hypothesis of :data:`HYPOTHESES` the description can carry.

    Throttle faults only on lines with a meter-out throttle (``meter_out_cv`` below
    50, free), closed and opened (:data:`SETTINGS`); cushion faults, tighter and looser,
    only on actuators with described cushioning; late switches only on switches a step
    waits for.

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> hyps = fault_hypotheses(load_machine("press-fit-cell"))
    >>> len(hyps), sorted({h.kind for h in hyps})[:3]
    (53, ['friction', 'late', 'piston-leak'])
    >>> [(h.sign, h.unit) for h in hyps if h.location == "PRESS_B" and h.kind == "throttle"]
    [(-1.0, '%'), (1.0, '%')]
    """
    wanted = (*HYPOTHESES, *SETTINGS) if kinds is None else tuple(kinds)
    waited = sorted({s for step in machine.steps for s in (*step.wait, *step.wait_off)})
    out: list[FaultHypothesis] = []

    def add(kind: str, location: str) -> None:
        if kind not in wanted:
            return
        if kind in HYPOTHESES:
            out.append(FaultHypothesis(kind, location, *HYPOTHESES[kind]))
        out.extend(
            FaultHypothesis(kind, location, sign, x0, largest, unit, more)
            for sign, x0, largest, unit, more in SETTINGS.get(kind, ())
        )

    for act in machine.actuators:
        for kind in ("friction", "valve-delay", "piston-leak"):
            add(kind, act.id)
        for side, meter in (("A", act.meter_out_cv_a), ("B", act.meter_out_cv_b)):
            if meter < 50.0:
                add("throttle", f"{act.id}_{side}")
            if act.cushion_length_mm > 0.0:
                add("cushion", f"{act.id}_{side}")
            add("valve-leak-in", f"{act.id}_{side}")
            add("valve-leak-out", f"{act.id}_{side}")
    for switch in waited:
        add("late", switch)
    add("regulator", "supply")
    return out


Weighing = Callable[[FloatArray], Whitener]
"""The run's weighting for an explanation whose effect has magnitude ``m`` per feature
[feature unit]: noise plus a model-error floor relative to ``m``
(:func:`pneufdd.diagnosis.engine.whitener`)."""

_SCALES = (0.25, 0.5, 1.0, 1.5, 2.0)
"""Multiples of the screening effect tried, linearly scaled, to rank a hypothesis [-]."""

_FAILED = 1e300
"""Residual of a size the machine cannot run with [-]."""


def residual(observed: FloatArray, change: FloatArray, weigh: Weighing) -> float:
    r"""Weighted residual sum of squares of an explanation of ``observed`` by ``change``.

    The weighting's model error is relative to the larger of the observed and the
    explained change per feature, :math:`m_j = \max(|\Delta x_j|, |e_j|)`: a feature
    the twin moves but the plant does not is model error too, as for the leaks
    (:func:`pneufdd.diagnosis.engine.run_whitener`).

    Examples
    --------
    >>> weigh = lambda m: (lambda d: np.atleast_2d(d) / np.sqrt(1.0 + (0.5 * m) ** 2))
    >>> round(residual(np.array([2.0, 0.0]), np.array([2.0, 2.0]), weigh), 12)
    2.0
    """
    magnitude = np.maximum(np.abs(observed), np.abs(change))
    r = np.asarray(weigh(magnitude)(observed - change)[0], dtype=np.float64)
    return float(r @ r)


def fit_faults(
    observed: FloatArray,
    simulate_fault: Callable[[Fault], FloatArray | None],
    weigh: Weighing,
    hypotheses: Sequence[FaultHypothesis],
    refined: int = REFINED,
    threads: int = 1,
    cache: MutableMapping[tuple[str, str, float], FloatArray | None] | None = None,
) -> list[FaultFit]:
    """Fit every hypothesis's size to the observed change; best (smallest rss) first.

    Each hypothesis is simulated once at its screening size ``x0`` and ranked by the
    best :func:`residual` of that effect scaled linearly by 0.25-2 (no more
    simulations); the ``refined`` best are sized by simulation: a bounded scalar
    minimisation (:func:`scipy.optimize.minimize_scalar`, at most
    :data:`_ITERATIONS` simulations) of :func:`residual` over ``x`` in ``[0.1, 3]``
    times the scaled start (within the kind's range; for a hypothesis screened at
    several sizes, between the screened sizes around it).

    Parameters
    ----------
    observed : ndarray
        Mean feature change of the run against the reference [feature unit].
    simulate_fault : callable
        Simulated feature change of a fault, None when the machine cannot run with it
        (:meth:`~pneufdd.diagnosis.effects.model.LeakEffectModel.simulate_fault`).
    weigh : callable
        The run's weighting for an effect magnitude (:data:`Weighing`).
    hypotheses : sequence of FaultHypothesis
        What to test.
    refined : int
        Best screened hypotheses sized by simulation [-].
    threads : int
        Simulations that run at once (``simulate_fault`` must be thread-safe).
    cache : mapping, optional
        Screening simulations kept between runs of one reference,
        ``(kind, location, signed size) -> change`` (they do not depend on the run).

    Returns
    -------
    list of FaultFit
        The sized ones first (best first), then the screened ones (best first);
        hypotheses the machine cannot run at any size tried are left out.

    Examples
    --------
    A "twin" whose throttle fault slows one feature as 1/(1 - x) (x: the share
    closed): the screening's linear guess is refined to the true 40 %:

    >>> h = FaultHypothesis("throttle", "X_B", -1.0, 50.0, 95.0)
    >>> sim = lambda f: np.array([1.0 / (1.0 + f.size / 100.0) - 1.0, 0.0])
    >>> weigh = lambda m: (lambda d: np.atleast_2d(d) * 100.0)
    >>> fits = fit_faults(sim(h.fault(40.0)), sim, weigh, [h])
    >>> round(fits[0].size, 0), fits[0].simulated
    (-40.0, True)
    """
    store = {} if cache is None else cache

    def screen_at(h: FaultHypothesis, sizes: Sequence[float]) -> tuple[float, FloatArray] | None:
        for x in sizes:
            key = (h.kind, h.location, h.sign * x)
            if key not in store:
                try:
                    store[key] = simulate_fault(h.fault(x))
                except InputError:  # the description cannot carry it
                    store[key] = None
                    return None
            change = store[key]
            if change is not None:
                return x, change
        return None

    def screen(h: FaultHypothesis) -> list[tuple[float, FloatArray]]:
        first = screen_at(h, (h.screening, h.screening / 3.0))
        more = [screen_at(h, (x,)) for x in h.more_screening] if first is not None else []
        return [got for got in (first, *more) if got is not None]

    screened = thread_map(screen, list(hypotheses), threads)
    ranked: list[tuple[float, FaultHypothesis, float, float, FloatArray]] = []
    for h, got in zip(hypotheses, screened, strict=True):
        tries = [
            (residual(observed, s * change, weigh), s * x0, x0, s * change)
            for x0, change in got
            for s in _SCALES
            if s * x0 <= h.largest
        ]
        if not got:
            continue
        if not tries:
            tries = [(math.inf, got[0][0], got[0][0], got[0][1])]
        rss, x, x0, change = min(tries, key=lambda t: t[0])
        ranked.append((rss, h, x, x0, change))
    ranked.sort(key=lambda item: item[0])

    def size(item: tuple[float, FaultHypothesis, float, float, FloatArray]) -> FaultFit | None:
        _, h, x, x0, _ = item
        changes: dict[float, FloatArray] = {}
        scores: dict[float, float] = {}

        def objective(value: float) -> float:
            change = simulate_fault(h.fault(value))
            if change is None:
                return _FAILED
            changes[value] = change
            scores[value] = residual(observed, change, weigh)
            return scores[value]

        low, high = 0.1 * x, min(3.0 * x, h.largest)
        if h.more_screening:  # far from linear: between the screened sizes around x
            grid = sorted({h.screening, *h.more_screening})
            low = max([g for g in grid if g < x], default=low)
            high = min([g for g in grid if g > x], default=h.largest)
        minimize_scalar(
            objective,
            bounds=(low, high),
            method="bounded",
            options={"xatol": 0.01 * x0, "maxiter": _ITERATIONS},
        )
        if not scores:
            return None
        best = min(scores, key=lambda v: scores[v])
        return FaultFit(h, float(h.sign * best), scores[best], changes[best], True)

    top = ranked[: max(refined, 0)]
    sized = [f for f in thread_map(size, top, threads) if f is not None]
    sized.sort(key=lambda f: f.rss)
    rest = [
        FaultFit(h, float(h.sign * x), rss, change, False)
        for rss, h, x, _, change in ranked[len(top) :]
    ]
    return sized + rest


def largest_step_change(
    feature_names: Sequence[str], change: FloatArray
) -> tuple[int, float] | None:
    """The step (1-based) whose duration changes most, and its change [s].

    Examples
    --------
    >>> largest_step_change(("duration@1", "duration@2", "Q_In.mean@1"),
    ...                     np.array([0.01, -0.25, 3.0]))
    (2, -0.25)
    """
    steps = [
        (abs(float(v)), int(name.split("@")[1]), float(v))
        for name, v in zip(feature_names, change, strict=True)
        if name.startswith("duration@") and math.isfinite(float(v))
    ]
    if not steps:
        return None
    _, step, value = max(steps)
    return step, round(value, 12)


def cycle_time_change(feature_names: Sequence[str], change: FloatArray) -> float:
    """Change of the cycle's duration: the sum of the step durations' changes [s].

    Examples
    --------
    >>> cycle_time_change(("duration@1", "duration@2", "Q_In.mean@1"),
    ...                   np.array([0.1, 0.05, 3.0]))
    0.15
    """
    total = sum(
        float(v)
        for name, v in zip(feature_names, change, strict=True)
        if name.startswith("duration@")
    )
    return round(total, 12) if math.isfinite(total) else total
