"""Features: every per-cycle and per-step feature, for every consumer.

Sections 3.3, 4.3.1-4.3.2, 5.3.1.1 and 5.3.3 of the dissertation. One package
produces the features that the diagnosis, the monitor, the classifiers, the
evaluation and the report use; they take them from here and compute none of their
own. Two kinds, from one segmentation:

* **The step table** (:mod:`pneufdd.features.step_table`,
  built by :mod:`pneufdd.features.step_summaries`): per complete cycle and PLC step,
  the step's duration and the mean, minimum and maximum of *every* analog channel of
  the sensor set over the step, plus step-aligned traces. Its flattened columns
  (``duration@3``, ``Q_In.mean@3``: :func:`feature_names`) are what the diagnosis
  detects, locates and sizes on (the reference model, the run tables, the leak
  signatures of the twin) and what the monitor scores each cycle with; the
  monitor's per-cycle supply air and pressure are :meth:`StepTable.cycle_integral`
  and :meth:`StepTable.cycle_mean`.
* **The registry's named features** (:mod:`pneufdd.features.registry`; groups
  ``motion`` (section 3.3: motion times, speeds), ``air`` (eq. 4.17: air per step, per
  stroke, per cycle), ``table44`` (Table 4.4) and ``wavelet`` (section 5.3.3)):
  physically named quantities of fixed channels, computed by
  :func:`feature_matrix` into a table with one row per cycle. The classifiers, the
  evaluation campaigns and the ``pneufdd features`` command use them.

Both segment a recording with the same PLC sequence, decided in one place:
:func:`plc_sequence` (the machine description given, else the one the recording
carries, else learned from its signals; ``segment_cycles`` does not look at a carried
description, see its docstring).

Extending: a feature registered with :func:`pneufdd.features.registry.register`
appears in :func:`feature_matrix` (and so in ``pneufdd features``, the classifiers
and the evaluation), **not** in ``diagnose``: the diagnosis works on the step table,
whose columns are fixed by the sensor set (durations and three statistics per
channel and step). The step-table statistics are not registered features either
(a registered feature is a function of fixed channels over the filtered cycle; the
step table summarises whichever analog channels a reference was built with, from
the gap-repaired samples), so ``pneufdd features`` does not output them; the
diagnosis's own columns are listed by :meth:`StepTable.feature_names`.

May import: :mod:`pneufdd.signals`, :mod:`pneufdd.sim` (machine descriptions),
:mod:`pneufdd.recording`, :mod:`pneufdd.physics` and the shared helpers.
"""

from __future__ import annotations

from pneufdd.features import air, motion, table44, wavelet
from pneufdd.features.context import CycleView, Options, RecordingData
from pneufdd.features.matrix import GROUPS, feature_matrix, features_of, labels_of
from pneufdd.features.registry import REGISTRY, Feature, Unavailable, column_name, get
from pneufdd.features.step_summaries import (
    build_step_table,
    machine_sequence,
    segment_cycles,
    sequence_from_records,
    sequence_to_records,
    trace_offsets,
)
from pneufdd.features.step_table import STATISTICS, StepTable, feature_floor, feature_names
from pneufdd.features.table44 import TABLE_4_5, TABLE_44_NAMES
from pneufdd.signals.segmentation import plc_sequence

__all__ = [
    "GROUPS",
    "REGISTRY",
    "STATISTICS",
    "TABLE_4_5",
    "TABLE_44_NAMES",
    "CycleView",
    "Feature",
    "Options",
    "RecordingData",
    "StepTable",
    "Unavailable",
    "air",
    "build_step_table",
    "column_name",
    "feature_floor",
    "feature_matrix",
    "feature_names",
    "features_of",
    "get",
    "labels_of",
    "machine_sequence",
    "motion",
    "plc_sequence",
    "segment_cycles",
    "sequence_from_records",
    "sequence_to_records",
    "table44",
    "trace_offsets",
    "wavelet",
]
