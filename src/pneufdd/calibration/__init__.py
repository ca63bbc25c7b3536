"""From a plant's own recordings to its machine description (issue 10).

:mod:`.draft` drafts a description from the PLC's signals; :mod:`.calibrate` fits the
parameters the recordings inform with the digital twin in the loop.

May import: :mod:`pneufdd.identification`, :mod:`pneufdd.sim`, :mod:`pneufdd.signals`,
:mod:`pneufdd.recording`, :mod:`pneufdd.physics` and the shared helpers; nothing of
:mod:`pneufdd.diagnosis` needs it, and it needs nothing of the diagnosis.
"""

from __future__ import annotations

from pneufdd.calibration.draft import DraftedMachine, draft_machine

__all__ = ["DraftedMachine", "draft_machine"]
