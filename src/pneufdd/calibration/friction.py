"""A cylinder's friction identified from its own strokes, before the twin-in-the-loop fit.

Where a plant measures both line pressures and the position of a cylinder (the
press ram of ``press-fit-cell``, the DNC of ``festo-dsd``), its friction is not left
to the per-step evidence of :mod:`.calibrate` (mean line pressures and durations,
where a heavy friction and a tight throttle look alike) but identified directly from
the strokes, as section 4.2.3 does on the rig: the breakaway force Fsf at motion
onset (eq. 4.15, :func:`pneufdd.identification.fit_breakaway_friction`) and the
Coulomb force Fcf and viscous coefficient Cvf over the moving part of the strokes
(eq. 4.16, :func:`pneufdd.identification.fit_sliding_friction`). With strokes both
ways a constant force F0 is fitted alongside and left out of the twin: the zero
errors of the line pressure sensors (up to +-1.5 % of their span, ``dP A``: tens
of newtons on a 63 mm bore) and a vertical load's weight, which the twin does not
model; Fsf weighs each direction half, which cancels F0 as well.

The forces are computed with the piston areas of the description being calibrated.
For a drafted actuator those areas are assumed; the calibration's size factor
(:func:`pneufdd.calibration.parameters._size`) later scales areas and friction
together, and the piston force is linear in the areas, so friction identified at
the drafted areas stays consistent with the pressures once the size is fitted.

A stroke is cut from each solenoid edge of the actuator that starts a motion (the
A solenoid's rising edge extends; the B solenoid's rising edge, or the A solenoid's
falling edge of a spring-return valve, retracts) to 50 ms after the position has
settled at its new end, and kept when it travels at least half the stroke.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.errors import InputError
from pneufdd.identification.friction import (
    StrokeSamples,
    fit_breakaway_friction,
    fit_sliding_friction,
)
from pneufdd.recording.model import Recording
from pneufdd.signals.digital import edge_times
from pneufdd.sim import MachineDescription
from pneufdd.sim.compile import piston_areas
from pneufdd.sim.description import SINGLE_SOLENOID_VALVES, Actuator

__all__ = ["FrictionIdentification", "actuator_strokes", "identify_friction", "stroke_speed"]


SETTLE_FRACTION = 0.03
"""A stroke has arrived when the position stays within this part of its travel of
the final value [-]."""

AFTER_ARRIVAL_S = 0.05
"""Kept after arrival, so the differentiation window sees the stop [s]."""

MIN_TRAVEL_FRACTION = 0.5
"""Shortest motion kept as a stroke, as a part of the actuator's stroke [-]."""

MIN_SPEED_RATIO = 1.5
"""Fastest over slowest stroke speed needed to fit Cvf apart from Fcf [-]. Strokes at
about one speed (meter-out throttles set alike both ways, one supply pressure: the
usual production cycle) only tell the total friction at that speed; then the
description's ratio Cvf / Fcf is kept and one factor fitted (extend and retract do
not help: at equal speeds both give ``Fcf + Cvf v``)."""

LINEAR_KINDS = ("linear", "rodless", "slide")


@dataclass(frozen=True)
class FrictionIdentification:
    """One actuator's friction identified from its strokes (section 4.2.3).

    Attributes
    ----------
    actuator : str
        Actuator id.
    strokes : int
        Strokes used (both directions).
    static_friction_n, coulomb_friction_n, viscous_friction_n_s_m : float
        Fsf [N] (eq. 4.15), Fcf [N] and Cvf [N s/m] (eq. 4.16), at the piston areas of
        the description they were identified with.
    static_friction_std_n, coulomb_friction_std_n, viscous_friction_std_n_s_m : float
        Standard errors [N], [N], [N s/m] (of the strokes' scatter; the samples of
        one stroke are not independent, so they are lower bounds).
    viscous_fitted : bool
        False when the strokes' speeds could not separate Cvf from Fcf and the
        description's ratio Cvf / Fcf was kept (:data:`MIN_SPEED_RATIO`).
    """

    actuator: str
    strokes: int
    static_friction_n: float
    static_friction_std_n: float
    coulomb_friction_n: float
    coulomb_friction_std_n: float
    viscous_friction_n_s_m: float
    viscous_friction_std_n_s_m: float
    viscous_fitted: bool

    def describe(self) -> str:
        """One line: ``Fsf 105 +- 4 N, Fcf 80 +- 2 N, Cvf 230 N s/m (kept) from 12 strokes``."""
        cvf = (
            f"Cvf {self.viscous_friction_n_s_m:.0f} +- {self.viscous_friction_std_n_s_m:.0f} N s/m"
            if self.viscous_fitted
            else f"Cvf {self.viscous_friction_n_s_m:.0f} N s/m (ratio to Fcf kept: one speed)"
        )
        return (
            f"Fsf {self.static_friction_n:.1f} +- {self.static_friction_std_n:.1f} N, "
            f"Fcf {self.coulomb_friction_n:.1f} +- {self.coulomb_friction_std_n:.1f} N, "
            f"{cvf} from {self.strokes} strokes"
        )


def _motion_starts(rec: Recording, actuator: Actuator) -> FloatArray:
    """Times of the solenoid edges that can start a motion of ``actuator`` [s]."""
    ident = actuator.id
    a_on, a_off = edge_times(rec, f"U_{ident}_A")
    starts = [a_on, edge_times(rec, f"U_{ident}_B")[0]]
    if actuator.valve.kind in SINGLE_SOLENOID_VALVES:  # released: the spring returns it
        starts.append(a_off)
    out: FloatArray = np.sort(np.concatenate(starts))
    return out


def actuator_strokes(rec: Recording, actuator: Actuator) -> list[StrokeSamples]:
    """The complete strokes of ``actuator`` in ``rec`` (see the module's docstring).

    Needs the channels ``P_<ID>_A``, ``P_<ID>_B`` and ``X_<ID>`` on one time base;
    returns an empty list when any is missing.
    """
    ident = actuator.id
    names = (f"P_{ident}_A", f"P_{ident}_B", f"X_{ident}")
    if not all(n in rec.channels for n in names):
        return []
    t, pa = rec.channel(names[0])
    tb, pb = rec.channel(names[1])
    tx, x = rec.channel(names[2])
    if t.size != tb.size or t.size != tx.size or not np.allclose(t, tx):
        return []  # pragma: no cover - simulated and imported recordings share one base
    pa = np.asarray(pa, np.float64)
    pb = np.asarray(pb, np.float64)
    x = np.asarray(x, np.float64)
    starts = _motion_starts(rec, actuator)
    stroke_m = actuator.stroke_mm * 1e-3
    out: list[StrokeSamples] = []
    for k, t1 in enumerate(starts):
        t_next = starts[k + 1] if k + 1 < starts.size else float(t[-1])
        i0 = int(np.searchsorted(t, t1))
        i1 = int(np.searchsorted(t, t_next))
        if i1 - i0 < 20:
            continue
        seg = x[i0:i1]
        final = float(np.median(seg[-max(5, seg.size // 20) :]))
        travel = abs(final - float(np.median(seg[: max(3, min(10, seg.size // 20))])))
        if travel < MIN_TRAVEL_FRACTION * stroke_m:
            continue
        away = np.flatnonzero(np.abs(seg - final) > SETTLE_FRACTION * travel)
        if away.size == 0:
            continue
        rate = 1.0 / float(np.median(np.diff(t[i0:i1])))
        end = min(i0 + int(away[-1]) + 1 + round(AFTER_ARRIVAL_S * rate), i1)
        sel = slice(i0, end)
        out.append(StrokeSamples(t[sel], pa[sel], pb[sel], x[sel]))
    return out


def stroke_speed(stroke: StrokeSamples) -> float:
    """Mean speed between 10 % and 90 % of the stroke's travel [m/s]."""
    x = np.asarray(stroke.position, np.float64)
    t = np.asarray(stroke.time, np.float64)
    travel = float(x[-1] - x[0])
    progress = (x - x[0]) / travel
    i10 = int(np.argmax(progress >= 0.1))
    i90 = int(np.argmax(progress >= 0.9))
    return 0.8 * abs(travel) / max(float(t[i90] - t[i10]), 1e-6)


def _speeds_separate(strokes: Sequence[StrokeSamples]) -> tuple[bool, bool]:
    """Whether the strokes' speeds separate Cvf from Fcf, and whether they go both ways.

    With strokes both ways a constant force F0 is fitted too, so Fcf and Cvf need
    speeds differing by :data:`MIN_SPEED_RATIO` within one direction; one way, across
    the strokes.
    """
    by_way: dict[bool, list[float]] = {}
    for s in strokes:
        x = np.asarray(s.position)
        by_way.setdefault(bool(x[-1] > x[0]), []).append(stroke_speed(s))
    ratios = [max(v) / min(v) for v in by_way.values()]
    return max(ratios) >= MIN_SPEED_RATIO, len(by_way) == 2


def _position_noise(strokes: Sequence[StrokeSamples]) -> float:
    """Position noise [m]: the spread of the samples at rest before each stroke."""
    rests = []
    for s in strokes:
        head = np.asarray(s.position)[:10]
        rests.append(head - np.median(head))
    return float(np.std(np.concatenate(rests))) if rests else 0.0


def identify_friction(
    machine: MachineDescription, recordings: Sequence[Recording]
) -> dict[str, FrictionIdentification]:
    """Friction of every linear actuator whose line pressures and position are recorded.

    Parameters
    ----------
    machine : MachineDescription
        Gives the actuators' areas [m^2], strokes [m], moving masses [kg] and valve
        kinds, and the Cvf kept when the strokes cannot separate it.
    recordings : sequence of Recording
        Leak-free recordings with ``P_<ID>_A``, ``P_<ID>_B`` and ``X_<ID>``.

    Returns
    -------
    dict
        Actuator id -> :class:`FrictionIdentification`; actuators without the
        channels, with fewer than two strokes, or whose fit fails (a physically
        impossible negative friction) are left out: their friction is then fitted
        with the twin in the loop.
    """
    found: dict[str, FrictionIdentification] = {}
    for actuator in machine.actuators:
        if actuator.kind not in LINEAR_KINDS:
            continue
        strokes = [s for rec in recordings for s in actuator_strokes(rec, actuator)]
        if len(strokes) < 2:
            continue
        area_a, area_b, _ = piston_areas(actuator)
        try:
            breakaway = fit_breakaway_friction(
                strokes, area_a, area_b, noise_m=_position_noise(strokes)
            )
            viscous_fitted, both_ways = _speeds_separate(strokes)
            ratio = None
            if not viscous_fitted:
                ratio = actuator.viscous_friction_n_s_m / max(actuator.coulomb_friction_n, 1e-9)
            sliding = fit_sliding_friction(
                strokes,
                area_a,
                area_b,
                actuator.moving_mass_kg,
                viscous_ratio_s_m=ratio,
                offset=both_ways,
            )
        except InputError:
            continue
        if breakaway.static_friction_n <= 0.0 or sliding.coulomb_friction_n <= 0.0:
            continue
        found[actuator.id] = FrictionIdentification(
            actuator=actuator.id,
            strokes=len(strokes),
            static_friction_n=breakaway.static_friction_n,
            static_friction_std_n=breakaway.static_friction_std_n,
            coulomb_friction_n=sliding.coulomb_friction_n,
            coulomb_friction_std_n=sliding.coulomb_friction_std_n,
            viscous_friction_n_s_m=sliding.viscous_friction_n_s_m,
            viscous_friction_std_n_s_m=sliding.viscous_friction_std_n_s_m,
            viscous_fitted=viscous_fitted,
        )
    return found
