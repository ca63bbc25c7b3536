"""Text in figures is plain text: no mathtext, no LaTeX.

Names in figures come from files (machine, actuator, channel, location names); a
machine named ``$\\undefinedcmd$`` must be drawn as those characters, not parsed as
mathtext (which raised a ValueError and lost the figure, issue 39). Every figure
function of :mod:`pneufdd.report` is wrapped in :func:`plain_text`: while it runs, new
Text objects (titles, labels, legends, annotations) get ``parse_math=False`` and
``usetex=False``, which they keep when the figure is drawn later.

Examples
--------
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> import matplotlib.pyplot as plt
>>> @plain_text
... def titled(name):
...     fig, ax = plt.subplots()
...     ax.set_title(name)
...     return fig
>>> fig = titled(r"$\\undefinedcmd$")
>>> import io; fig.savefig(io.BytesIO(), format="png"); plt.close(fig)
>>> matplotlib.rcParams["text.parse_math"]  # unchanged outside
True
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

__all__ = ["PLAIN_TEXT", "plain_text", "printable"]

PLAIN_TEXT: dict[Any, Any] = {"text.parse_math": False, "text.usetex": False}
"""Matplotlib settings under which text is drawn as given."""

P = ParamSpec("P")
R = TypeVar("R")


def plain_text(function: Callable[P, R]) -> Callable[P, R]:
    """``function`` run with :data:`PLAIN_TEXT` (text it draws is never mathtext or LaTeX)."""

    @functools.wraps(function)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        import matplotlib

        with matplotlib.rc_context(PLAIN_TEXT):
            return function(*args, **kwargs)

    return wrapper


def printable(text: str) -> str:
    r"""``text`` with each control or other unprintable character shown as its escape.

    >>> printable("cell\x1b[31m\x07 ok")
    'cell\\x1b[31m\\x07 ok'
    """
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)
