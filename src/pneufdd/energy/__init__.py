"""Energy beyond leaks (section 6.2.1): where the air goes, the lowest pressure, what-ifs.

>>> from pneufdd.energy import EnergySettings
>>> EnergySettings().tolerance
0.02

May import: :mod:`pneufdd.calibration`, :mod:`pneufdd.diagnosis`, :mod:`pneufdd.features`,
:mod:`pneufdd.sim` and the layers below; not classifiers, evaluation, monitor, report
or cli. Method: ``docs/energy.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pneufdd._lazy import lazy_getattr

if TYPE_CHECKING:
    from pneufdd.energy.analysis import EnergyAnalysis, air_breakdown, analyse_energy
    from pneufdd.energy.bookkeeping import TwinAir, twin_air
    from pneufdd.energy.breakdown import AirBreakdown
    from pneufdd.energy.changes import Change, apply_changes
    from pneufdd.energy.measures import Measure
    from pneufdd.energy.pressure import SetPointSearch, lowest_set_point
    from pneufdd.energy.settings import EnergySettings

__all__ = [
    "AirBreakdown",
    "Change",
    "EnergyAnalysis",
    "EnergySettings",
    "Measure",
    "SetPointSearch",
    "TwinAir",
    "air_breakdown",
    "analyse_energy",
    "apply_changes",
    "lowest_set_point",
    "twin_air",
]

# imported on first use: the package's modules load the twin (numba) and scipy
_LAZY = {
    "EnergyAnalysis": "pneufdd.energy.analysis",
    "air_breakdown": "pneufdd.energy.analysis",
    "analyse_energy": "pneufdd.energy.analysis",
    "TwinAir": "pneufdd.energy.bookkeeping",
    "twin_air": "pneufdd.energy.bookkeeping",
    "AirBreakdown": "pneufdd.energy.breakdown",
    "Change": "pneufdd.energy.changes",
    "apply_changes": "pneufdd.energy.changes",
    "Measure": "pneufdd.energy.measures",
    "SetPointSearch": "pneufdd.energy.pressure",
    "lowest_set_point": "pneufdd.energy.pressure",
    "EnergySettings": "pneufdd.energy.settings",
}

__getattr__ = lazy_getattr(__name__, _LAZY, globals())
