"""pneufdd: find, locate, size and cost compressed-air leaks in PLC-sequenced pneumatic machines.

The package follows the ISO 13374 condition-monitoring chain; imports flow one way::

    physics -> sim -> signals -> features -> diagnosis -> monitor/report -> cli

``pneufdd.Recording`` is the data model every layer shares.
"""

from __future__ import annotations

from pneufdd.recording import Recording

__all__ = ["Recording", "__version__"]
__version__ = "0.1.0"
