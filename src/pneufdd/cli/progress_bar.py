"""Progress bars for the library's ``progress(task, done, total)`` callbacks (rich)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from pneufdd.progress import Progress as ProgressCallback

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import TaskID

__all__ = ["progress_bars"]


@contextmanager
def progress_bars(console: Console | None = None) -> Iterator[ProgressCallback]:
    """A rich display with one bar per task; yields the callback to pass to the library."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from pneufdd.report.plain_text import printable

    with Progress(
        TextColumn("{task.description}", markup=False),  # a task may name a machine
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=console or Console(stderr=True),
        transient=True,
    ) as bars:
        tasks: dict[str, TaskID] = {}

        def update(task: str, done: int, total: int) -> None:
            if task not in tasks:
                # plain text: ``cell[/]`` is no markup, ``a\\[b`` keeps its backslash, an
                # escape sequence in a machine's name is shown, never sent to the terminal
                tasks[task] = bars.add_task(printable(task), total=total)
            bars.update(tasks[task], completed=done, total=total)

        yield update
