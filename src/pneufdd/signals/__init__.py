"""Signal conditioning: segmentation into cycles and steps, synchronisation,
ensemble statistics and filtering (section 5.3.1 and section 3.2.4 of the dissertation).

``events`` (PLC signal names, debounced valve and switch edges, :class:`StepSpec`) ->
``sequence`` (the machine's PLC sequence: :func:`plc_sequence`) -> ``segmentation``
(cycles and steps) -> ``synchronisation``, ``ensemble``; ``quality`` judges channels
and applies the gap rule; ``digital``, ``filtering`` and ``windows`` are the tools.

May import: :mod:`pneufdd.errors`, :mod:`pneufdd.array_types`, :mod:`pneufdd.recording`,
:mod:`pneufdd.physics` and :mod:`pneufdd.sim` (machine descriptions).
"""

from __future__ import annotations

from pneufdd.signals.digital import debounce, edges
from pneufdd.signals.ensemble import (
    Ensemble,
    ensemble,
    reference_averages,
    select_window,
    step_ensembles,
)
from pneufdd.signals.filtering import Kinematics, fill_gaps, kinematics, lowpass
from pneufdd.signals.segmentation import (
    Cycle,
    RecordedStep,
    Segmentation,
    StepSpec,
    actuator_of,
    learn_sequence,
    segment,
)
from pneufdd.signals.synchronisation import (
    align_cycles,
    reference_lengths,
    sample_bounds,
    synchronise,
)

__all__ = [
    "Cycle",
    "Ensemble",
    "Kinematics",
    "RecordedStep",
    "Segmentation",
    "StepSpec",
    "actuator_of",
    "align_cycles",
    "debounce",
    "edges",
    "ensemble",
    "fill_gaps",
    "kinematics",
    "learn_sequence",
    "lowpass",
    "reference_averages",
    "reference_lengths",
    "sample_bounds",
    "segment",
    "select_window",
    "step_ensembles",
    "synchronise",
]
