"""pneufdd: find, locate, size and cost compressed-air leaks in PLC-sequenced pneumatic machines.

The package follows the ISO 13374 condition-monitoring chain; imports flow one way::

    physics -> sim -> signals -> features -> diagnosis -> monitor/report -> cli

``pneufdd.Recording`` is the data model every layer shares; ``pneufdd.LeakDiagnoser``
is the diagnosis (fit on leak-free recordings, ``diagnose`` a run: a
``pneufdd.Diagnosis`` with one ``pneufdd.LeakFinding`` per leak), ``pneufdd.Location``
names a leak's place (the supply, or one line of one actuator) and ``pneufdd.simulate``
runs a machine's digital twin (a ``Recording``, with leaks if asked). They are imported
on first use, so ``import pneufdd`` stays light (no compiled twin is loaded).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pneufdd._lazy import lazy_getattr

if TYPE_CHECKING:
    from pneufdd.diagnosis.diagnoser import LeakDiagnoser
    from pneufdd.diagnosis.findings import Diagnosis, LeakFinding
    from pneufdd.location import Location
    from pneufdd.recording import Recording
    from pneufdd.sim.simulate import simulate

__all__ = [
    "Diagnosis",
    "LeakDiagnoser",
    "LeakFinding",
    "Location",
    "Recording",
    "__version__",
    "simulate",
]
__version__ = "0.1.0"

_LAZY = {
    "Recording": "pneufdd.recording",
    "LeakDiagnoser": "pneufdd.diagnosis.diagnoser",
    "Diagnosis": "pneufdd.diagnosis.findings",
    "LeakFinding": "pneufdd.diagnosis.findings",
    "Location": "pneufdd.location",
    "simulate": "pneufdd.sim.simulate",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())
