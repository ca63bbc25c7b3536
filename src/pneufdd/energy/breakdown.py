"""Where the air goes: the measured supply air per cycle, split by the twin.

The twin, calibrated to the machine and holding the diagnosed leaks, accounts for
every gram exactly (:mod:`pneufdd.energy.bookkeeping`): each actuator's strokes, its
dead volumes and tubes, the leaks, the ejector. Where the recordings have a supply
flow meter (``Q_In``), the meter decides the totals: the twin's air per step is
fitted to the measured air per step with one factor per actuator, leak and ejector
(a bounded weighted least-squares fit with a prior around 1, the calibration's step
weights): one factor shared by the actuators (those without line meters: the
calibration already sized each of them from this meter), one per leak, one for the
ejector, so each component keeps the twin's shape over the steps and the meter's
size. What the factors cannot explain stays as *unexplained* air; the twin's own total
is compared with the meter's. Without a meter the twin's figures are the breakdown.
Standby air (a stopped machine with the air on) comes from the twin stopped after a
cycle and, where the recordings hold idle stretches between cycles, from the meter
over them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.calibration.calibrate import AIR_ABS_SIGMA_FRACTION, AIR_REL_SIGMA, measure_evidence
from pneufdd.energy.bookkeeping import TwinAir
from pneufdd.energy.settings import EnergySettings, Money
from pneufdd.energy.standby import Standby
from pneufdd.recording.model import Recording
from pneufdd.signals.segmentation import plc_sequence, segment
from pneufdd.sim.description import MachineDescription

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "IDLE_MIN_S",
    "AirBreakdown",
    "group_of",
    "idle_flow",
    "kind_of",
    "measured_air",
    "reconcile",
]

PRIOR_SIGMA = {"actuator": 0.05, "leak": 0.5, "vacuum": 0.15}
"""Prior standard deviation of each factor's log. The actuators' common factor: the
twin was calibrated to this meter's air per step within about 5 %
(docs/calibration.md). A diagnosed leak's size is known to about 50 %; the ejector's
nozzle as an actuator's volume (0.15). Actuators with a flow meter on every line they
draw from take their factor from those meters."""
ACTUATORS = "actuators"
"""The factor the actuators without line meters share. One factor each (prior 0.05)
moved 13 of the 19 actuators of three acceptance plants (830M) further from the
plant's own figure, festo-dsd's small gripper HGD2 from +7.9 % (the calibrated twin)
to +19.2 % (its factor at the bound): the meter's air in a short step also holds the
tail of other actuators' fills (the air still flowing into a large drive's chambers as
they settle), which the twin shapes over the steps a little differently, and a factor
of its own lets the actuator that owns the step take it. The calibration fitted each
actuator's volume to the same meter with the whole twin; the breakdown only scales
them together."""
IDLE_MIN_S = 5.0
"""A stretch without a machine cycle at least this long counts as standby [s]; the
first 2 s after a cycle are left out (the held lines settle)."""


def group_of(component: str) -> str:
    """The factor a component shares: its actuator, its leak, the ejector or storage.

    Examples
    --------
    >>> group_of("DNC.tube"), group_of("leak.DNC_B"), group_of("vacuum")
    ('DNC', 'leak.DNC_B', 'vacuum')
    """
    return (
        component
        if component.startswith(("leak.", "vacuum", "storage"))
        else component.split(".")[0]
    )


def kind_of(component: str) -> str:
    """A component's kind: stroke, dead volume, tube, leak, vacuum or storage.

    Examples
    --------
    >>> kind_of("DNC.tube"), kind_of("leak.supply"), kind_of("vacuum")
    ('tube', 'leak', 'vacuum')
    """
    return "leak" if component.startswith("leak.") else component.split(".")[-1]


def _prior(group: str) -> float:
    if group.startswith("leak."):
        return PRIOR_SIGMA["leak"]
    return PRIOR_SIGMA["vacuum" if group == "vacuum" else "actuator"]


def metered_factors(air: TwinAir, lines_kg: Mapping[str, float]) -> dict[str, float]:
    """Factors of the actuators whose every supplied line has a flow meter [-].

    Their air is measured directly: the meters' air per cycle over the twin's.

    Examples
    --------
    >>> import numpy as np
    >>> air = TwinAir(("A.stroke",), np.ones((1, 1)), np.ones(1), np.ones(1), 1,
    ...               {"A_A": 0.5, "A_B": 0.5})
    >>> metered_factors(air, {"A_A": 0.6, "A_B": 0.6}), metered_factors(air, {"A_A": 0.6})
    ({'A': 1.2}, {})
    """
    out: dict[str, float] = {}
    groups = {group_of(c) for c in air.components if "." in c and not c.startswith("leak.")}
    for group in sorted(groups):
        supplied = [f"{group}_{s}" for s in "AB" if air.lines_kg.get(f"{group}_{s}", 0.0) > 0.0]
        if supplied and all(np.isfinite(lines_kg.get(line, np.nan)) for line in supplied):
            twin = sum(air.lines_kg[line] for line in supplied)
            out[group] = sum(lines_kg[line] for line in supplied) / twin
    return out


def reconcile(
    air: TwinAir, measured_kg: FloatArray, lines_kg: Mapping[str, float] | None = None
) -> tuple[dict[str, float], FloatArray]:
    """Factors that fit the twin's per-step air to the meter's, and the scaled air.

    Parameters
    ----------
    air : TwinAir
        The twin's air per step and component.
    measured_kg : ndarray
        The supply meter's mean air per step [kg].
    lines_kg : mapping of str to float, optional
        Air per cycle a line flow meter measured, by line (``<ACT>_A``) [kg]. An
        actuator whose every supplied line has one takes its factor from them
        (:func:`metered_factors`); the supply meter's steps fit the others.

    Returns
    -------
    factors : dict of str to float
        One factor per group (actuator, leak, ejector) [-]; the actuators without
        line meters share theirs (:data:`ACTUATORS`).
    scaled : ndarray, shape (n_steps, n_components)
        The twin's air per step with its group's factor [kg].
    """
    groups = sorted({group_of(c) for c in air.components} - {"storage"})
    factors = {g: 1.0 for g in groups}
    known = metered_factors(air, lines_kg or {})
    factors.update(known)

    def fitted(group: str) -> str:  # the factor a group takes in the fit
        return group if group.startswith("leak.") or group == "vacuum" else ACTUATORS

    names = sorted({fitted(g) for g in groups if g not in known})
    share = np.stack(
        [
            air.air_kg[:, [group_of(c) not in known and fitted(group_of(c)) == n
                           for c in air.components]].sum(axis=1)
            for n in names
        ] or [np.zeros(len(measured_kg))],
        axis=1,
    )  # fmt: skip
    fixed = air.air_kg[:, [group_of(c) == "storage" for c in air.components]].sum(axis=1)
    fixed = fixed + sum(
        air.air_kg[:, [group_of(c) == g for c in air.components]].sum(axis=1) * factors[g]
        for g in known
    )
    scale = AIR_REL_SIGMA * np.abs(measured_kg) + AIR_ABS_SIGMA_FRACTION * np.mean(
        np.abs(measured_kg)
    )
    used = [k for k in range(len(names)) if np.any(share[:, k] > 0.0)]
    if used:
        sigma = np.array([_prior(names[k]) for k in used])
        matrix = np.vstack([share[:, used] / scale[:, None], np.diag(1.0 / sigma)])
        target = np.concatenate([(measured_kg - fixed) / scale, 1.0 / sigma])
        fit = lsq_linear(matrix, target, bounds=(np.exp(-2.0 * sigma), np.exp(2.0 * sigma)))
        solved = {names[k]: float(f) for k, f in zip(used, fit.x, strict=True)}
        for g in groups:
            if g not in known:
                factors[g] = solved.get(fitted(g), 1.0)
    column = np.array([factors.get(group_of(c), 1.0) for c in air.components])
    return factors, air.air_kg * column[None, :]


@dataclass(frozen=True)
class AirBreakdown:
    """The air of one cycle, component by component, with what it costs a year.

    Attributes
    ----------
    machine : str
        Machine name.
    source : str
        ``"supply meter"`` (the meter sets the sizes, the twin the split) or ``"twin"``.
    components : tuple of str
        ``<ACT>.stroke``, ``<ACT>.dead volume``, ``<ACT>.tube``, ``leak.<loc>``,
        ``vacuum``, ``storage``.
    air_kg : ndarray
        Air per cycle of each component, as reported [kg].
    twin_kg : ndarray
        The twin's own air per cycle of each component [kg].
    factors : dict of str to float
        The meter's factor of each group (all 1 without a meter) [-].
    measured_kg : float
        The meter's supply air per cycle [kg] (NaN without a meter).
    cycle_time_s : float
        Mean cycle time of the recordings [s].
    cycles : int
        Complete cycles measured.
    leaks : tuple of dict
        The leaks in the twin (location, orifice mm, where from).
    standby : Standby
        The stopped machine's air.
    settings : EnergySettings
        Economics.
    """

    machine: str
    source: str
    components: tuple[str, ...]
    air_kg: FloatArray
    twin_kg: FloatArray
    factors: dict[str, float]
    measured_kg: float
    cycle_time_s: float
    cycles: int
    leaks: tuple[dict[str, Any], ...]
    standby: Standby
    settings: EnergySettings = field(default_factory=EnergySettings)

    @property
    def explained_kg(self) -> float:
        """Sum of the components [kg]."""
        return float(np.sum(self.air_kg))

    @property
    def unexplained_kg(self) -> float:
        """Metered air the components leave unexplained [kg] (0 without a meter)."""
        return 0.0 if not math.isfinite(self.measured_kg) else self.measured_kg - self.explained_kg

    @property
    def twin_total_kg(self) -> float:
        """The twin's own supply air per cycle [kg]."""
        return float(np.sum(self.twin_kg))

    @property
    def cycles_per_year(self) -> float:
        """Machine cycles in the operating hours [-]."""
        return self.settings.cost.hours * 3600.0 / self.cycle_time_s

    def by_group(self) -> dict[str, float]:
        """Air per cycle by actuator (stroke + dead volume + tube), leak, ejector [kg]."""
        out: dict[str, float] = {}
        for name, value in zip(self.components, self.air_kg, strict=True):
            out[group_of(name)] = out.get(group_of(name), 0.0) + float(value)
        return out

    def by_kind(self) -> dict[str, float]:
        """Air per cycle by kind: stroke, dead volume, tube, leak, vacuum, storage [kg]."""
        out: dict[str, float] = {}
        for name, value in zip(self.components, self.air_kg, strict=True):
            out[kind_of(name)] = out.get(kind_of(name), 0.0) + float(value)
        return out

    def money(self, air_per_cycle_kg: float) -> Money:
        """Air per cycle priced over the operating hours (eq. 1.1)."""
        return self.settings.price(air_per_cycle_kg / self.cycle_time_s)

    @property
    def standby_money(self) -> Money:
        """The standby flow priced over the standstill hours (eq. 1.1)."""
        flow = self.standby.measured_flow_kg_s
        if flow is None:
            flow = self.standby.flow_kg_s
        return self.settings.price(flow, self.settings.hours_standstill)

    def to_pandas(self) -> pd.DataFrame:
        """One row per component: air per cycle, share, twin's air, cost a year."""
        import pandas as pd

        total = self.explained_kg
        rows = [
            {
                "component": name,
                "group": group_of(name),
                "air_per_cycle_g": 1e3 * float(value),
                "share": float(value) / total if total > 0 else math.nan,
                "twin_air_per_cycle_g": 1e3 * float(twin),
                "cost_per_year": self.money(float(value)).cost,
            }
            for name, value, twin in zip(self.components, self.air_kg, self.twin_kg, strict=True)
        ]
        return pd.DataFrame(rows).set_index("component")

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        total = self.money(self.explained_kg)
        measured = self.measured_kg if math.isfinite(self.measured_kg) else None
        return {
            "machine": self.machine,
            "source": self.source,
            "cycles": self.cycles,
            "cycle_time_s": self.cycle_time_s,
            "air_per_cycle_kg": {
                "measured": measured,
                "explained": self.explained_kg,
                "unexplained": self.unexplained_kg if measured is not None else None,
                "twin": self.twin_total_kg,
                "twin_vs_measured": (self.twin_total_kg / measured - 1.0 if measured else None),
            },
            "components": [
                {
                    "name": name,
                    "air_per_cycle_kg": float(value),
                    "twin_air_per_cycle_kg": float(twin),
                    **self.money(float(value)).to_dict(),
                }
                for name, value, twin in zip(
                    self.components, self.air_kg, self.twin_kg, strict=True
                )
            ],
            "by_actuator_kg": {
                k: v
                for k, v in self.by_group().items()
                if not k.startswith(("leak.", "vacuum", "storage"))
            },
            "by_group_kg": self.by_group(),
            "by_kind_kg": self.by_kind(),
            "factors": self.factors,
            "leaks": list(self.leaks),
            "operating": total.to_dict(),
            "standby": {**self.standby.to_dict(), **self.standby_money.to_dict()},
        }


def measured_air(
    recordings: Sequence[Recording], machine: MachineDescription
) -> tuple[FloatArray, FloatArray, int, dict[str, float]]:
    """The recordings' mean supply air and duration per step, the cycles averaged, and
    the air per cycle of each line with a flow meter.

    The calibration's evidence (:func:`pneufdd.calibration.calibrate.measure_evidence`):
    segmented with the machine's sequence, the first cycle of a recording with three
    or more left out, the gap rule applied. Supply air is NaN without ``Q_In``. A line
    meter (``Q_<ACT>_A/B``, one that measures towards the cylinder only, like the SFE1)
    reads its zero error while the line is still: the median of its step means is taken
    as that and subtracted, what is left is integrated over the steps.
    """
    meters = {
        s.channel: s.location
        for s in machine.sensors
        if s.kind == "flow"
        and s.location != "supply"
        and s.direction == "forward"
        and all(s.channel in r.channels for r in recordings)
    }
    evidence = measure_evidence(recordings, machine, tuple(meters))
    lines: dict[str, float] = {}
    for channel, line in meters.items():
        means = evidence.line_pressure_pa[channel]  # any channel's step means
        zero = float(np.median(means))
        lines[line] = float(np.sum(np.clip(means - zero, 0.0, None) * evidence.duration_s))
    return evidence.supply_air_kg, evidence.duration_s, evidence.cycles, lines


def _idle_stretches(rec: Recording, sequence: Any) -> list[tuple[float, float]]:
    """Stretches outside the complete cycles with no valve command changing [s]."""
    cycles = list(segment(rec, sequence).complete)
    t, _ = rec.channel("Q_In")
    edges = sorted(
        float(when)
        for name in rec.channels
        if name.startswith("U_")
        for when in _edge_times(rec, name)
    )
    bounds = [float(t[0])]
    for c in cycles:
        bounds += [c.start_s, c.steps[-1].end_s]
    bounds.append(float(t[-1]))
    stretches = []
    for a, b in zip(bounds[0::2], bounds[1::2], strict=True):
        cuts = [a, *(e for e in edges if a < e < b), b]
        stretches += [(x, y) for x, y in itertools.pairwise(cuts) if y - x >= IDLE_MIN_S]
    return stretches


def _edge_times(rec: Recording, name: str) -> FloatArray:
    t, v = rec.channel(name)
    change = np.flatnonzero(np.diff(np.asarray(v, dtype=np.int64)) != 0)
    return np.asarray(t[change + 1], dtype=np.float64)


def idle_flow(
    recordings: Sequence[Recording], machine: MachineDescription
) -> tuple[float | None, float]:
    """Mean ``Q_In`` over the recordings' idle stretches, and their total length [kg/s, s].

    A stretch outside the complete cycles in which no valve command changes counts
    when it lasts :data:`IDLE_MIN_S` or more; its first 2 s are left out (the held
    lines and the supply settle).
    """
    sequence = plc_sequence(machine=machine)
    total = 0.0
    weighted = 0.0
    for rec in recordings:
        if "Q_In" not in rec.channels:
            continue
        t, q = rec.channel("Q_In")
        rate = rec.info("Q_In").rate_hz
        for a, b in _idle_stretches(rec, sequence):
            sel = (t >= a + 2.0) & (t < b) & np.isfinite(q)
            total += float(np.count_nonzero(sel)) / rate
            weighted += float(np.sum(q[sel])) / rate
    if total <= 0.0:
        return None, 0.0
    return weighted / total, total
