"""A standstill leak test planned by the twin (issue 35, ``pneufdd standstill``).

:mod:`.plan` chooses the held valve states from a machine's description,
:mod:`.separability` says what they separate, :mod:`.program` writes the sequence as
IEC 61131-3 Structured Text and as a table for the PLC programmer (and as a PLC
sequence for the twin), :mod:`.twin` simulates the test on a plant, :mod:`.analyse`
turns a recording of it into each line's leak with its uncertainty.
``docs/standstill.md`` explains the method.

May import: :mod:`pneufdd.identification`, :mod:`pneufdd.sim`, :mod:`pneufdd.signals`
and lower layers (it sits after ``diagnosis``, which it does not use).
"""

from __future__ import annotations

from pneufdd.standstill.plan import MODES, StandstillPlan, StandstillState, plan_standstill

__all__ = ["MODES", "StandstillPlan", "StandstillState", "plan_standstill"]
