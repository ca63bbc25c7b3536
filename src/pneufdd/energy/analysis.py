"""``pneufdd energy``: where the air goes, the lowest pressure, the what-ifs, in one call.

The machine is the description the reference keeps (calibrated to the machine when
the reference was built with ``--calibrate`` or ``--machine calibrated.toml``), or the
one given with ``machine=``; the leaks are the diagnosis's (the reference's check of
the recordings), kept in the twin as holes of their equivalent orifice so that they
blow less at a lower pressure, as real holes do.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.energy.breakdown import AirBreakdown, idle_flow, measured_air, reconcile
from pneufdd.energy.changes import bar_g
from pneufdd.energy.measures import Measure, measures_frame, rank
from pneufdd.energy.pressure import SetPointSearch, lowest_set_point
from pneufdd.energy.settings import EnergySettings
from pneufdd.energy.standby import twin_standby
from pneufdd.energy.twin import TwinRun, mean_machine, run_twin
from pneufdd.energy.whatifs import (
    air_off_measure,
    remedy_measures,
    set_point_measure,
    spring_measures,
    throttle_measure,
    tube_measure,
    valve_measure,
    zone_measure,
)
from pneufdd.errors import InputError, describe
from pneufdd.recording.model import Recording
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import Leak
from pneufdd.sim.loading import MachineLike, load_machine

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["EnergyAnalysis", "air_breakdown", "analyse_energy", "diagnosed_leaks", "json_safe"]

Progress = Callable[[str], None]


@dataclass(frozen=True)
class EnergyAnalysis:
    """Everything ``pneufdd energy`` reports.

    Attributes
    ----------
    machine : MachineDescription
        The twin the analysis ran.
    breakdown : AirBreakdown
        Where the air goes (item 1).
    search : SetPointSearch
        The lowest set point that does the job (item 2).
    measures : list of Measure
        The priced what-ifs, ranked (items 2-3).
    settings : EnergySettings
        The economics and tolerances.
    notes : tuple of str
        Plain-language remarks.
    """

    machine: MachineDescription
    breakdown: AirBreakdown
    search: SetPointSearch
    measures: list[Measure]
    settings: EnergySettings
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def set_point(self) -> Measure:
        """The lowest set point measure."""
        return next(m for m in self.measures if m.kind == "set_point")

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` output (a number that is not finite, such as the air per cycle
        of a standstill measure or the cycle time of a stalled candidate, is null)."""
        search = self.search
        data: dict[str, Any] = json_safe(
            {
                "machine": self.machine.name,
                "twin": self.machine.title,
                "supply_pressure_now_bar_g": bar_g(search.now_psig),
                "supply_pressure_min_bar_g": bar_g(search.min_psig),
                "limiting_actuator": search.limiting_actuator or None,
                "limit": None if search.limit is None else search.limit.reason,
                "saving_per_year": self.set_point.saving_per_year,
                "kwh_per_year": self.set_point.kwh_per_year,
                "cycle_time_s": {
                    "now": search.base.cycle_time_s,
                    "at_min_pressure": search.best.cycle_time_s,
                },
                "pressure_curve": [p.to_dict() for p in search.curve],
                "measures": [m.to_dict() for m in self.measures],
                "breakdown": self.breakdown.to_dict(),
                "settings": self.settings.to_dict(),
                "notes": list(self.notes),
            }
        )
        return data

    def to_pandas(self) -> pd.DataFrame:
        """The ranked measures, one row each."""
        return measures_frame(self.measures)


def json_safe(value: Any) -> Any:
    """``value`` with every float that is not finite replaced by None (JSON null).

    Examples
    --------
    >>> json_safe({"a": [1.0, float("nan")], "b": float("inf")})
    {'a': [1.0, None], 'b': None}
    """
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def diagnosed_leaks(
    reference: ReferenceModel, recordings: Sequence[Recording], settings: EnergySettings
) -> tuple[list[Leak], list[dict[str, Any]]]:
    """The leaks the reference's diagnosis finds in ``recordings``, as holes for the twin.

    Each leak at its most likely location, as a sharp-edged orifice of its equivalent
    diameter (``unit="mm"``; eq. 4.3, Cd 0.61): the same hole at any pressure.
    """
    from pneufdd.diagnosis.recordings import diagnose_pooled

    _, found = diagnose_pooled(reference, list(recordings), settings.cost, threads=1)
    if not found.detected:
        return [], []
    leaks = [Leak(str(f.location), float(f.orifice_mm), "mm") for f in found.leaks]
    info = [
        {
            "location": str(f.location),
            "orifice_mm": float(f.orifice_mm),
            "flow_slpm": float(f.flow_slpm),
            "average_flow_slpm": float(f.average_flow_slpm),
            "confidence": float(f.confidence),
            "source": "diagnosis",
        }
        for f in found.leaks
    ]
    return leaks, info


def _machine(reference: ReferenceModel | None, machine: MachineLike | None) -> MachineDescription:
    """The twin the analysis runs: the given or kept description's mean machine."""
    if machine is not None:
        return mean_machine(load_machine(machine))
    if reference is not None and reference.description is not None:
        return mean_machine(reference.description)
    raise InputError(
        describe(
            "machine description",
            None,
            "a reference that keeps one (--reference ref.pnref) or a description (--machine)",
        )
    )


def _recordings(items: Sequence[Recording | str | Path]) -> list[Recording]:
    if not items:
        raise InputError(describe("recordings", 0, "at least one"))
    return [r if isinstance(r, Recording) else Recording.read(Path(r)) for r in items]


def _leaks(
    reference: ReferenceModel | None,
    recordings: Sequence[Recording],
    leaks: Mapping[str, float] | None,
    settings: EnergySettings,
) -> tuple[list[Leak], list[dict[str, Any]]]:
    if leaks is not None:
        given = [Leak(loc, float(mm), "mm") for loc, mm in leaks.items()]
        return given, [
            {"location": k.location, "orifice_mm": k.size, "source": "given"} for k in given
        ]
    if reference is None:
        return [], []
    return diagnosed_leaks(reference, recordings, settings)


def _breakdown(
    machine: MachineDescription,
    recordings: Sequence[Recording],
    base: TwinRun,
    leak_info: list[dict[str, Any]],
    leaks: Sequence[Leak],
    settings: EnergySettings,
) -> AirBreakdown:
    assert base.air is not None
    measured, durations, cycles, lines = measured_air(recordings, machine)
    twin_kg = base.air.air_kg.sum(axis=0)
    if np.all(np.isfinite(measured)):
        factors, scaled = reconcile(base.air, measured, lines)
        air_kg, source, total = scaled.sum(axis=0), "supply meter", float(np.sum(measured))
    else:
        factors = {}
        air_kg, source, total = twin_kg, "twin", math.nan
    standby = twin_standby(machine, leaks, settings.seed)
    flow, idle_s = idle_flow(recordings, machine)
    standby = replace(standby, measured_flow_kg_s=flow, measured_idle_s=idle_s)
    return AirBreakdown(
        machine=machine.name,
        source=source,
        components=base.air.components,
        air_kg=np.asarray(air_kg, dtype=np.float64),
        twin_kg=np.asarray(twin_kg, dtype=np.float64),
        factors=factors,
        measured_kg=total,
        cycle_time_s=float(np.sum(durations)),
        cycles=cycles,
        leaks=tuple(leak_info),
        standby=standby,
        settings=settings,
    )


def air_breakdown(
    recordings: Sequence[Recording | str | Path],
    reference: ReferenceModel | str | Path | None = None,
    machine: MachineLike | None = None,
    settings: EnergySettings | None = None,
    leaks: Mapping[str, float] | None = None,
) -> AirBreakdown:
    """Where the air of ``recordings`` goes (item 1 of ``pneufdd energy``).

    Parameters
    ----------
    recordings : sequence of Recording or path
        Recordings of the machine running (the measured supply air, when they have
        ``Q_In``; the cycles and step times).
    reference : ReferenceModel or path, optional
        The machine's reference: its description is the twin, its diagnosis of the
        recordings gives the leaks.
    machine : str, path or MachineDescription, optional
        A description that overrides the reference's (``--machine calibrated.toml``).
    settings : EnergySettings, optional
        Economics (eq. 1.1) and twin settings.
    leaks : mapping of str to float, optional
        Leaks to put in the twin instead of the diagnosis's: location -> equivalent
        orifice diameter [mm].

    Returns
    -------
    AirBreakdown
    """
    settings = settings or EnergySettings()
    model = _reference(reference)
    recs = _recordings(recordings)
    twin = _machine(model, machine)
    found, info = _leaks(model, recs, leaks, settings)
    base = run_twin(twin, found, settings.cycles, settings.seed)
    if base.air is None:
        raise InputError(f"the twin of {twin.name!r} stalls: {base.stalled}")
    return _breakdown(twin, recs, base, info, found, settings)


def _reference(reference: ReferenceModel | str | Path | None) -> ReferenceModel | None:
    if reference is None or isinstance(reference, ReferenceModel):
        return reference
    from pneufdd.diagnosis.reference.file import load_reference

    return load_reference(reference)


def analyse_energy(
    recordings: Sequence[Recording | str | Path],
    reference: ReferenceModel | str | Path | None = None,
    machine: MachineLike | None = None,
    settings: EnergySettings | None = None,
    leaks: Mapping[str, float] | None = None,
    progress: Progress | None = None,
) -> EnergyAnalysis:
    """Breakdown, lowest set point and priced what-ifs for a machine's recordings.

    Parameters are those of :func:`air_breakdown`; ``progress(task)`` is told each
    stage as it starts.

    Returns
    -------
    EnergyAnalysis
    """
    tell = progress or (lambda _task: None)
    settings = settings or EnergySettings()
    model = _reference(reference)
    recs = _recordings(recordings)
    twin = _machine(model, machine)
    tell("diagnosing leaks" if leaks is None and model is not None else "reading")
    found, info = _leaks(model, recs, leaks, settings)
    tell("running the twin")
    base = run_twin(twin, found, settings.cycles, settings.seed)
    if base.air is None:
        raise InputError(f"the twin of {twin.name!r} stalls: {base.stalled}")
    breakdown = _breakdown(twin, recs, base, info, found, settings)
    tell("lowest set point")
    search = lowest_set_point(twin, found, settings, base=base, grid=4)
    measures: list[Measure | None] = [set_point_measure(search, settings)]
    for task, make in (
        ("flow controls", lambda: [throttle_measure(twin, search, found, settings)]),
        ("spring return", lambda: spring_measures(twin, base, found, settings)),
        ("tubes and valves", lambda: [tube_measure(twin, base, found, settings),
                                      valve_measure(twin, base, found, settings)]),
        ("pressure zone", lambda: [zone_measure(twin, search, found, settings)]),
        ("limiting actuator", lambda: remedy_measures(twin, search, found, settings)),
    ):  # fmt: skip
        tell(task)
        measures += make()
    measures.append(air_off_measure(breakdown.standby, settings, base))
    notes = _notes(breakdown, search, settings)
    return EnergyAnalysis(
        machine=twin,
        breakdown=breakdown,
        search=search,
        measures=rank([m for m in measures if m is not None]),
        settings=settings,
        notes=notes,
    )


def _notes(
    breakdown: AirBreakdown, search: SetPointSearch, settings: EnergySettings
) -> tuple[str, ...]:
    notes = []
    if breakdown.source == "twin":
        notes.append("no supply flow meter (Q_In): the breakdown is the twin's alone")
    else:
        gap = breakdown.twin_total_kg / breakdown.measured_kg - 1.0
        notes.append(
            f"the twin's own supply air is {100 * gap:+.1f} % of the meter's; the meter sets "
            "the sizes, the twin the split"
        )
    if search.floor_reached:
        notes.append("the search floor (a quarter of the present set point) still did the job")
    grow = search.best.cycle_time_s / search.base.cycle_time_s - 1.0
    if settings.cycle_time_needed_s is None and grow > settings.tolerance:
        notes.append(
            f"at the lowest set point the cycle takes {100 * grow:.1f} % longer (each step "
            "within its tolerance); --cycle-time bounds the cycle time"
        )
    if not settings.header_follows:
        notes.append(
            "compressor-side savings (DOE: 2 psi ~ 1 %) are shown but not counted; "
            "--header-follows counts them when this machine sets the plant pressure"
        )
    return tuple(notes)
