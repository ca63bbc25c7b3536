"""pneufdd: find, locate, size and cost compressed-air leaks in PLC-sequenced pneumatic machines.

The package follows the ISO 13374 condition-monitoring chain; imports flow one way::

    physics -> sim -> signals -> features -> diagnosis -> monitor/report -> cli

``pneufdd.Recording`` is the data model every layer shares; ``pneufdd.LeakDiagnoser``
is the diagnosis (fit on leak-free recordings, ``diagnose`` a run), ``pneufdd.Location``
names a leak's place (the supply, or one line of one actuator). They are imported on
first use, so ``import pneufdd`` stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pneufdd._lazy import lazy_getattr

if TYPE_CHECKING:
    from pneufdd.diagnosis.diagnoser import LeakDiagnoser
    from pneufdd.diagnosis.findings import Diagnosis
    from pneufdd.location import Location
    from pneufdd.recording import Recording

__all__ = ["Diagnosis", "LeakDiagnoser", "Location", "Recording", "__version__"]
__version__ = "0.1.0"

_LAZY = {
    "Recording": "pneufdd.recording",
    "LeakDiagnoser": "pneufdd.diagnosis.diagnoser",
    "Diagnosis": "pneufdd.diagnosis.findings",
    "Location": "pneufdd.location",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())
