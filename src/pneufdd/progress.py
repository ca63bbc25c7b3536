"""Progress reporting for long library work, without a user-interface library.

Long jobs (simulating leak signatures, campaigns) accept ``progress``: a callable
``progress(task, done, total)`` called as work advances, where ``task`` is a short
description (``"simulating leak signatures"``), ``done`` the units finished so far
and ``total`` the units of that task. The command line turns these calls into
progress bars; a script may print them or pass None.

Examples
--------
>>> seen = []
>>> tick = counter(lambda task, done, total: seen.append((task, done, total)), "work", 2)
>>> tick(); tick()
>>> seen
[('work', 0, 2), ('work', 1, 2), ('work', 2, 2)]
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["Progress", "counter"]

Progress = Callable[[str, int, int], None]
"""``progress(task, done, total)``: ``done`` of ``total`` units of ``task`` are finished."""


def counter(progress: Progress | None, task: str, total: int) -> Callable[[], None]:
    """A function that advances ``task`` by one unit each call (reports 0 at once).

    Parameters
    ----------
    progress : callable or None
        Where to report; None reports nowhere.
    task : str
        Description of the task.
    total : int
        Units of the task.
    """
    done = 0
    if progress is not None:
        progress(task, 0, total)

    def advance() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(task, done, total)

    return advance
