"""Exit codes of the ``pneufdd`` command (documented in the README).

=====  ==============================================================
code   meaning
=====  ==============================================================
0      success; for ``diagnose``: no leak found
1      ``diagnose``: a leak or another fault was found (a detected run)
2      bad input or usage: a file, channel, unit, option or value
3      internal error (a bug: please report it with the traceback)
=====  ==============================================================
"""

from __future__ import annotations

from enum import IntEnum

__all__ = ["ExitCode"]


class ExitCode(IntEnum):
    """Process exit codes of the ``pneufdd`` command."""

    OK = 0
    LEAK_FOUND = 1
    INPUT_ERROR = 2
    INTERNAL_ERROR = 3
