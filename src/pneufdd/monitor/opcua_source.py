"""OPC UA source: a client (asyncua) subscribing to a PLC's tags, every value checked.

The subscription's parameters are checked against the channels' rates
(:mod:`pneufdd.monitor.opcua`); every value's status, time stamps and clocks are
checked before it is used (:class:`OpcUaSource`).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import queue
import threading
import time as wallclock
from collections.abc import Callable, Iterator, Sequence
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

import numpy as np

from pneufdd.monitor.completeness import ClockOffsets, LossLedger, iso_time
from pneufdd.monitor.database import masked_url
from pneufdd.monitor.opcua import (
    ItemRefusedError,
    SubscriptionRefusedError,
    grant_problems,
    needed_queue,
    subscribe,
)
from pneufdd.monitor.samples import SampleBatch

if TYPE_CHECKING:
    from pneufdd.monitor.sources import ChannelTags

__all__ = ["OpcUaSource"]


def _quiet(_: str) -> None:
    return None


def _seconds(stamp: datetime | None) -> float | None:
    """An OPC UA time stamp [s since 1970-01-01 UTC] (naive ones are UTC)."""
    if stamp is None:
        return None
    return stamp.timestamp() if stamp.tzinfo else stamp.replace(tzinfo=UTC).timestamp()


class OpcUaSource:
    """Subscribe to PLC tags on an OPC UA server (asyncua) and yield their changes.

    Every value is checked before it is used (:meth:`_take`): its status
    (``losses``), a repeat of the channel's previous source time stamp (a duplicate,
    e.g. the values a subscription reports again after a reconnection: dropped and
    counted), and its clocks: the server time stamp minus the source time stamp and
    the arrival time minus the server time stamp are kept in ``clocks``. The samples
    of a lost connection are marked lost in ``losses`` from the newest source time
    before it to the first new one after it. The end tag ends the stream when it
    *becomes* true: a tag already true at the connection (left from the last run)
    is said, and the run ends once it has been false and is true again.
    """

    def __init__(
        self,
        url: str,
        tags: ChannelTags,
        channels: Sequence[str],
        log: Callable[[str], None] = _quiet,
        publish_ms: float = 50.0,
        watchdog_s: float = 10.0,
        accept_revised: bool = False,
    ) -> None:
        self.url = url
        self.shown = masked_url(url)  # what messages show: never the password
        self.tags = tags
        self.channels = tuple(channels)
        self.rates_hz = {c: tags.rates_hz[c] for c in self.channels}
        self.lateness_s = tags.lateness_s
        self.log = log
        self.publish_ms = publish_ms
        self.watchdog_s = watchdog_s
        self.accept_revised = accept_revised
        self.losses = LossLedger()
        self.clocks = ClockOffsets()
        self.duplicates = 0
        self.without_source_time = 0
        self._last_t: dict[str, float] = {}
        self._newest_t = -math.inf
        self._outage_from: float | None = None
        self._end_armed = False  # the end tag was seen false: true now ends the run
        self._end_seen = False
        self._clocks_said = False
        self._ended: asyncio.Event | None = None
        self._queue: queue.Queue[SampleBatch | BaseException | None] = queue.Queue()
        self._stop = threading.Event()

    def notes(self) -> list[str]:
        """What the values showed, for the end of the run (empty: nothing to say)."""
        out = []
        if self.duplicates:
            out.append(
                f"{self.duplicates} OPC UA value(s) repeating their channel's previous "
                "source time stamp dropped (duplicates)"
            )
        if self.without_source_time:
            out.append(
                f"{self.without_source_time} OPC UA value(s) without a source time stamp "
                "were stamped with the server's time"
            )
        if self.clocks.summary():
            out.append(f"clock offsets: {self.clocks.summary()}")
        return out

    def _take(self, name: str, val: Any, value: Any) -> None:
        """Check one value of channel ``name`` (a DataValue) and queue it if usable."""
        arrived = wallclock.time()
        source_t, server_t = _seconds(value.SourceTimestamp), _seconds(value.ServerTimestamp)
        if name == "__end__":
            self._end(bool(val))
            return
        code = int(getattr(value.StatusCode, "value", 0) or 0)
        t = source_t if source_t is not None else server_t
        if source_t is None and server_t is not None:
            self.without_source_time += 1
        if t is None:
            if not code:
                return
            t = arrived  # a Bad value may carry no time stamp
        if server_t is not None:
            self.clocks.observe("local - server", arrived - server_t)
            if source_t is not None:
                self.clocks.observe("server - source", server_t - source_t)
        if not self.losses.observe(name, t, code) or val is None:
            return  # Bad or Uncertain: the channel is unknown until a Good value
        if self._last_t.get(name) == t:
            self.duplicates += 1
            return
        self._last_t[name] = t
        if self._outage_from is not None and t > self._outage_from:
            self.losses.lose(self.channels, self._outage_from, t)
            self.log(
                f"OPC UA samples from {iso_time(self._outage_from)} to {iso_time(t)} lost "
                "while disconnected; the cycles that touch them are skipped"
            )
            self._outage_from = None
        self._newest_t = max(self._newest_t, t)
        batch = SampleBatch(name, np.array([float(val)]), times=np.array([t]))
        self._queue.put(self.tags.to_si(batch))
        if not self._clocks_said and self.clocks.count("local - server") >= 100:
            self._clocks_said = True  # said once, early; the end of the run says it again
            self.log(f"OPC UA clock offsets: {self.clocks.summary()}")

    def _end(self, value: bool) -> None:
        """The end tag's value: the run ends when it becomes true."""
        if not value:
            self._end_armed = True
        elif self._end_armed and self._ended is not None:
            self._ended.set()
        elif not self._end_seen:
            self.log(
                f"end tag {self.tags.end} is already true at the connection (left from an "
                "earlier run): the run ends once it has been false and is true again"
            )
        self._end_seen = True

    def __iter__(self) -> Iterator[SampleBatch | None]:
        thread = threading.Thread(target=self._thread, daemon=True, name="pneufdd-opcua")
        thread.start()
        try:
            while True:
                try:
                    item = self._queue.get(timeout=0.5)
                except queue.Empty:
                    yield None
                    continue
                if isinstance(item, StopIteration):
                    yield None
                    return
                if isinstance(item, BaseException):
                    raise item
                yield item
                if item is None:
                    continue
        finally:
            self._stop.set()
            if thread is not threading.current_thread():  # closed by the garbage collector
                thread.join(timeout=5.0)

    def _thread(self) -> None:
        try:
            asyncio.run(self._run())
        except BaseException as exc:  # pragma: no cover - reported to the consumer
            self._queue.put(exc)

    async def _run(self) -> None:
        from asyncua.client.client import Client
        from asyncua.ua.uaerrors import UaError

        source = self
        ended = asyncio.Event()
        self._ended = ended
        nodes_by_id: dict[str, str] = {}

        class Handler:
            def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
                name = nodes_by_id.get(node.nodeid.to_string())
                if name is not None:
                    source._take(name, val, data.monitored_item.Value)

        attempt = 0
        checked = False  # the granted parameters are judged at the first connection
        while not self._stop.is_set():
            # the client probes the server's state every watchdog_s and gives it as long
            # to answer: a diagnosis that keeps this process busy for seconds must not
            # count as a lost connection (asyncua's 1 s default dropped the subscription,
            # and the samples of the reconnection gap with it, on a loaded machine)
            client = Client(self.url, timeout=self.watchdog_s, watchdog_intervall=self.watchdog_s)
            try:
                await client.connect()
            except (TimeoutError, OSError, UaError) as exc:
                attempt += 1
                if attempt == 1 or attempt % 10 == 0:
                    self.log(f"OPC UA server {self.shown} unreachable ({exc}); retrying")
                await asyncio.sleep(1.0)
                continue
            self.log(("reconnected to" if attempt else "connected to") + f" OPC UA {self.shown}")
            attempt = 1
            try:
                nodes = []
                for name in self.channels:
                    node = client.get_node(self.tags.nodes[name])
                    nodes_by_id[node.nodeid.to_string()] = name
                    nodes.append(node)
                if self.tags.end:
                    node = client.get_node(self.tags.end)
                    nodes_by_id[node.nodeid.to_string()] = "__end__"
                    nodes.append(node)
                names = [*self.channels, *(["__end__"] if self.tags.end else [])]
                await self._subscribe(client, Handler(), nodes, names, first=not checked)
                checked = True
                while not self._stop.is_set() and not ended.is_set():
                    await asyncio.sleep(0.2)
                    self._queue.put(None)
                    await client.check_connection()
                if ended.is_set():
                    await asyncio.sleep(max(self.publish_ms / 1000.0, 0.1) * 3)
                    self._queue.put(StopIteration())
                    await client.disconnect()
                    return
                await client.disconnect()
                return
            except SubscriptionRefusedError:
                with contextlib.suppress(Exception):
                    await client.disconnect()
                raise
            except ItemRefusedError as exc:
                with contextlib.suppress(Exception):
                    await client.disconnect()
                if not checked:  # at the first connection: the tag map names a wrong node
                    raise
                # after a reconnection: a server that restarted may not have all its
                # nodes yet (the monitor had them before)
                self.log(f"{exc} after the reconnection; trying again")
                await asyncio.sleep(1.0)
            except (TimeoutError, OSError, ConnectionError, UaError) as exc:
                self.log(f"OPC UA connection to {self.shown} lost ({exc}); reconnecting")
                if self._outage_from is None and math.isfinite(self._newest_t):
                    self._outage_from = self._newest_t  # lost from here to the next new value
                with contextlib.suppress(Exception):  # already broken
                    await client.disconnect()
                await asyncio.sleep(1.0)

    async def _subscribe(
        self, client: Any, handler: Any, nodes: list[Any], names: list[str], first: bool
    ) -> None:
        """Subscribe; check what the server grants against the channels' rates.

        At the first connection, parameters that cannot carry a channel's rate are
        said (one line per channel) and asked for once more (half the publishing
        interval, twice the queue the granted interval needs); if still short, the
        source refuses (:class:`~pneufdd.monitor.opcua.SubscriptionRefusedError`, exit 2)
        unless ``accept_revised`` (the URL's ``?accept_revised=1``): then it runs,
        and the cycles the server loses samples of are skipped.
        """
        interval = self.publish_ms
        queue = dict.fromkeys(self.channels, 10_000)
        sub, granted = await subscribe(client, handler, nodes, names, interval, queue)
        problems = grant_problems(self.rates_hz, interval, 10_000, granted)
        if not problems or not first:
            return
        for line in problems:
            self.log(line)
        await sub.delete()
        interval = interval / 2.0
        queue = {
            c: max(10_000, 2 * needed_queue(r, granted.publishing_ms))
            for c, r in self.rates_hz.items()
        }
        self.log(
            f"asking OPC UA {self.shown} again: publishing interval {interval:g} ms, "
            f"queue {max(queue.values())}"
        )
        sub, granted = await subscribe(client, handler, nodes, names, interval, queue)
        problems = grant_problems(self.rates_hz, interval, max(queue.values()), granted)
        if not problems:
            return
        for line in problems:
            self.log(line)
        if self.accept_revised:
            self.log(
                "accepting the revised parameters (accept_revised=1): cycles the server "
                "loses samples of are skipped and reported"
            )
            return
        await sub.delete()
        raise SubscriptionRefusedError(
            f"OPC UA server {self.shown} cannot deliver the rates the reference needs "
            f"({len(problems)} channel(s), above); lower the channels' rate_hz in the tag "
            "map (and build the reference at that rate), raise the server's queue and "
            "publishing limits, or add ?accept_revised=1 to the source to run anyway "
            "(cycles with lost samples are then skipped)"
        )
