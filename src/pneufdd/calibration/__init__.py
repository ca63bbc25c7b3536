"""From a plant's own recordings to its machine description (issue 10).

:mod:`.draft` drafts a description from the PLC's signals; :mod:`.calibrate` fits the
parameters the recordings inform with the digital twin in the loop.
"""

from __future__ import annotations

from pneufdd.calibration.draft import DraftedMachine, draft_machine

__all__ = ["DraftedMachine", "draft_machine"]
