"""Changes of the history, pushed to every open page as server-sent events.

One task per server polls :func:`pneufdd.monitor.fleet.change_stamp` (maxima of a few
primary keys, no scan) every :data:`POLL_S` seconds in a worker thread; when it changes,
every subscribed page gets an ``event: change`` and fetches the parts it shows. A page
idle for :data:`HEARTBEAT_S` gets a comment line, so proxies keep the stream open.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import AsyncIterator, Callable
from typing import Any

import anyio.to_thread

__all__ = ["HEARTBEAT_S", "POLL_S", "ChangeFeed"]

POLL_S = 0.4
"""How often the history is asked whether anything changed [s]."""
HEARTBEAT_S = 15.0
"""Longest silence on an event stream [s]."""


class ChangeFeed:
    """Polls ``stamp`` and wakes the event streams when its value changes."""

    def __init__(self, stamp: Callable[[], Any], poll_s: float = POLL_S) -> None:
        self._stamp = stamp
        self.poll_s = poll_s
        self.version = 0
        self.error: str | None = None
        self._last: Any = None
        self._changed = asyncio.Condition()

    async def run(self) -> None:
        """Poll until cancelled (a failing database is reported on the page, retried)."""
        while True:
            try:
                now = await anyio.to_thread.run_sync(self._stamp)
                self.error = None
            except Exception as exc:  # the database away: say so, keep trying
                now, self.error = self._last, f"history not readable: {type(exc).__name__}"
            if now != self._last:
                self._last = now
                async with self._changed:
                    self.version += 1
                    self._changed.notify_all()
            await asyncio.sleep(self.poll_s)

    async def events(self) -> AsyncIterator[str]:
        """The event stream of one page: ``change`` events and heartbeats."""
        seen = self.version
        yield f"event: hello\ndata: {json.dumps({'version': seen})}\n\n"

        def moved() -> bool:
            return self.version != seen

        while True:
            async with self._changed:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._changed.wait_for(moved), HEARTBEAT_S)
            if self.version != seen:
                seen = self.version
                yield f"event: change\ndata: {json.dumps({'version': seen})}\n\n"
            else:
                yield ": still here\n\n"
