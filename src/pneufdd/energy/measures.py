"""A measure: a change to the machine, priced by the twin against the present machine.

Every measure is judged the same way: the twin runs the changed machine with the
present machine's seed, leaks and cycles, and its air per cycle, step durations and
cycle time are compared with the present machine's. The saving is priced at the same
production (the present cycles per hour: air per cycle saved x cycles a year) with
eq. 1.1; a measure that lowers the header pressure also gets the DOE rule's
compressor-side saving, counted when the compressor follows (``header_follows``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pneufdd.energy.changes import Change
from pneufdd.energy.pressure import Verdict, allowances, judge
from pneufdd.energy.settings import EnergySettings, Money
from pneufdd.energy.twin import TwinRun

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["Measure", "price_measure", "rank"]


@dataclass(frozen=True)
class Measure:
    """One what-if, priced.

    Attributes
    ----------
    name : str
        Short title (``lower the set point``, ``spring return: EJECT``, ...).
    kind : str
        ``set_point``, ``throttles``, ``spring_return``, ``tubes``, ``valves``,
        ``pressure_zone``, ``larger_bore``, ``booster``, ``air_off``.
    changes : tuple of Change
        What is changed on the machine (applied to the present description).
    feasible : bool
        The changed machine still does the job (every step within its allowance,
        forces held, no stall).
    reason : str
        The twin's verdict in one line.
    air_before_kg, air_after_kg : float
        Supply air per cycle, present and changed [kg] (NaN for standstill measures).
    cycle_before_s, cycle_after_s : float
        Cycle time, present and changed [s].
    step_change_s : tuple of float
        Change of each step's duration [s].
    saving : Money
        The air saved, priced over the operating (or standstill) hours.
    compressor_side : Money or None
        The DOE rule's saving of a lower header, when the measure lowers it.
    counts_compressor_side : bool
        Whether ``compressor_side`` is in the total (``header_follows``).
    note : str
        What else to know (disadvantages, what the figure assumes).
    remedy_for : str
        The limiting actuator this measure lowers the pressure around ('' otherwise).
    """

    name: str
    kind: str
    changes: tuple[Change, ...]
    feasible: bool
    reason: str
    air_before_kg: float
    air_after_kg: float
    cycle_before_s: float
    cycle_after_s: float
    step_change_s: tuple[float, ...]
    saving: Money
    compressor_side: Money | None = None
    counts_compressor_side: bool = False
    note: str = ""
    remedy_for: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def saving_per_year(self) -> float:
        """Money saved a year (air, and the compressor side when it counts)."""
        total = self.saving.cost
        if self.compressor_side is not None and self.counts_compressor_side:
            total += self.compressor_side.cost
        return float(total)

    @property
    def kwh_per_year(self) -> float:
        """Compressor energy saved a year [kWh] (as ``saving_per_year``)."""
        total = self.saving.kwh
        if self.compressor_side is not None and self.counts_compressor_side:
            total += self.compressor_side.kwh
        return float(total)

    @property
    def what(self) -> str:
        """What must be changed on the machine."""
        return "; ".join(c.describe() for c in self.changes) or "nothing"

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {
            "name": self.name,
            "kind": self.kind,
            "feasible": self.feasible,
            "verdict": self.reason,
            "what_to_change": self.what,
            "changes": [c.to_dict() for c in self.changes],
            "air_per_cycle_kg": {"now": self.air_before_kg, "after": self.air_after_kg},
            "cycle_time_s": {"now": self.cycle_before_s, "after": self.cycle_after_s},
            "step_duration_change_s": list(self.step_change_s),
            "air_saving": self.saving.to_dict(),
            "compressor_side_saving": (
                None if self.compressor_side is None else self.compressor_side.to_dict()
            ),
            "compressor_side_counted": self.counts_compressor_side,
            "saving_per_year": self.saving_per_year,
            "kwh_per_year": self.kwh_per_year,
            "note": self.note,
            "remedy_for": self.remedy_for,
            **({"extra": self.extra} if self.extra else {}),
        }


def price_measure(
    name: str,
    kind: str,
    changes: Sequence[Change],
    base: TwinRun,
    run: TwinRun,
    settings: EnergySettings,
    header_drop_psi: float = 0.0,
    extra_air_kg: float = 0.0,
    note: str = "",
    remedy_for: str = "",
    verdict: Verdict | None = None,
) -> Measure:
    """Price ``run`` (the changed machine) against ``base`` (the present one).

    ``extra_air_kg``: air per cycle the twin does not carry (a booster's drive air).
    ``header_drop_psi``: how much lower the header can go (DOE compressor-side rule).
    """
    verdict = verdict or judge(run, base, allowances(base, settings), settings.cycle_time_needed_s)
    after = run.supply_kg + extra_air_kg
    before = base.supply_kg
    flow = (before - after) / base.cycle_time_s if math.isfinite(after) else 0.0
    saving = settings.price(flow)
    side = None
    if header_drop_psi > 0.0 and math.isfinite(after):
        side = settings.compressor_side(after / base.cycle_time_s, header_drop_psi)
    change = run.duration_s - base.duration_s
    return Measure(
        name=name,
        kind=kind,
        changes=tuple(changes),
        feasible=verdict.feasible,
        reason=verdict.reason,
        air_before_kg=before,
        air_after_kg=after,
        cycle_before_s=base.cycle_time_s,
        cycle_after_s=run.cycle_time_s,
        step_change_s=tuple(float(v) for v in np.asarray(change)),
        saving=saving,
        compressor_side=side,
        counts_compressor_side=settings.header_follows,
        note=note,
        remedy_for=remedy_for,
    )


def rank(measures: Sequence[Measure]) -> list[Measure]:
    """Feasible measures by saving a year, largest first; infeasible ones after them."""
    return sorted(measures, key=lambda m: (not m.feasible, -m.saving_per_year))


def measures_frame(measures: Sequence[Measure]) -> pd.DataFrame:
    """One row per measure: name, feasible, saving a year, kWh, air, cycle-time change."""
    import pandas as pd

    rows = [
        {
            "measure": m.name,
            "feasible": m.feasible,
            "saving_per_year": m.saving_per_year,
            "kwh_per_year": m.kwh_per_year,
            "air_m3_anr_per_year": m.saving.air_m3_anr,
            "cycle_time_change_s": m.cycle_after_s - m.cycle_before_s,
            "what_to_change": m.what,
        }
        for m in measures
    ]
    return pd.DataFrame(rows)
