"""OPC UA subscriptions that can carry the channels' rates, or a refusal that says why.

A server may revise what a client asks for: open62541, for one, grants at most 100
queued values per monitored item and a publishing interval of at least 100 ms. A
monitored item then delivers at most ``queue / interval`` values per second; a
channel whose rate needs more loses samples (the server sets the Overflow bit on the
value after the discarded ones). :func:`grant_problems` compares the granted
parameters with each channel's rate: a channel is carried when

    granted queue >= GRANT_MARGIN * rate * granted publishing interval

and the granted sampling interval is at most one sample period (0: the server
samples every change). :func:`subscribe` creates the subscription and its monitored
items and returns what the server granted (asyncua's own calls keep the revised
values to themselves).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pneufdd.errors import InputError

__all__ = [
    "GRANT_MARGIN",
    "Granted",
    "ItemRefusedError",
    "SubscriptionRefusedError",
    "grant_problems",
    "subscribe",
]

GRANT_MARGIN = 2.0
"""Headroom of a monitored item's queue over one publishing interval of samples [-]:
a publish that comes late (a busy client or server) must not overflow it."""


class SubscriptionRefusedError(InputError):
    """The server grants subscription parameters that cannot carry the channels' rates."""


class ItemRefusedError(InputError):
    """The server refused to monitor a tag (e.g. an unknown node id)."""


@dataclass(frozen=True)
class Granted:
    """What the server granted: the publishing interval [ms] and, per channel, the
    sampling interval [ms] and queue size [values]."""

    publishing_ms: float
    sampling_ms: dict[str, float]
    queue: dict[str, int]


def needed_queue(rate_hz: float, publishing_ms: float) -> int:
    """Queue size a channel at ``rate_hz`` needs at ``publishing_ms`` [values].

    >>> needed_queue(1000.0, 100.0), needed_queue(50.0, 100.0)
    (200, 10)
    """
    return max(1, math.ceil(GRANT_MARGIN * rate_hz * publishing_ms / 1000.0 - 1e-9))


def grant_problems(
    rates_hz: Mapping[str, float], requested_ms: float, requested_queue: int, granted: Granted
) -> list[str]:
    """One line per channel the granted parameters cannot carry at its rate (empty: all).

    Examples
    --------
    >>> g = Granted(100.0, {"P_In": 0.0, "S_A": 0.0}, {"P_In": 100, "S_A": 100})
    >>> lines = grant_problems({"P_In": 1000.0, "S_A": 100.0}, 50.0, 10000, g)
    >>> len(lines), lines[0][:56]
    (1, 'OPC UA channel P_In (1000 Hz): queue 100 granted (10000 ')
    """
    lines = []
    for channel, rate in rates_hz.items():
        queue = granted.queue.get(channel, 0)
        sampling = granted.sampling_ms.get(channel, 0.0)
        capacity = queue * 1000.0 / max(granted.publishing_ms, 1e-9) / GRANT_MARGIN
        reasons = []
        need = needed_queue(rate, granted.publishing_ms)
        if queue < need:
            reasons.append(
                f"queue {queue} granted ({requested_queue} requested), publishing interval "
                f"{granted.publishing_ms:g} ms ({requested_ms:g} requested) carry at most "
                f"{capacity:.0f} values/s; the channel needs {need}"
                f" queued values per publish ({GRANT_MARGIN:g} x rate x interval)"
            )
        if sampling > 1000.0 / rate + 1e-9:
            reasons.append(
                f"sampling interval {sampling:g} ms granted, the channel needs at most "
                f"{1000.0 / rate:g} ms"
            )
        if reasons:
            lines.append(f"OPC UA channel {channel} ({rate:g} Hz): " + "; ".join(reasons))
    return lines


class _Recorder:
    """The client's session, recording the server's answers to the subscription calls."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.subscription: Any = None
        self.items: list[Any] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    async def create_subscription(self, params: Any, callback: Any) -> Any:
        self.subscription = await self._inner.create_subscription(params, callback=callback)
        return self.subscription

    async def create_monitored_items(self, params: Any) -> Any:
        results = await self._inner.create_monitored_items(params)
        self.items = list(results)
        return results


async def subscribe(
    client: Any,
    handler: Any,
    nodes: Sequence[Any],
    names: Sequence[str],
    publishing_ms: float,
    queue: Mapping[str, int],
) -> tuple[Any, Granted]:
    """Subscribe ``nodes`` (channel ``names``; others, e.g. the end tag, queue 10)
    and return the subscription with what the server granted."""
    from asyncua import ua
    from asyncua.common.subscription import Subscription

    params = ua.CreateSubscriptionParameters()
    params.RequestedPublishingInterval = publishing_ms
    params.RequestedLifetimeCount = 10_000
    params.RequestedMaxKeepAliveCount = client.get_keepalive_count(publishing_ms)
    params.MaxNotificationsPerPublish = 0  # no limit
    params.PublishingEnabled = True
    params.Priority = 0
    recorder = _Recorder(client.uaclient.session)
    sub = Subscription(recorder, params, handler)  # type: ignore[arg-type]
    created = await sub.init()
    requests = [
        sub._make_monitored_item_request(
            node,
            ua.AttributeIds.Value,  # type: ignore[attr-defined]
            None,
            queue.get(name, 10),
            ua.MonitoringMode.Reporting,
            ua.Double(0.0),
        )
        for node, name in zip(nodes, names, strict=True)
    ]
    await sub.create_monitored_items(requests)
    sampling: dict[str, float] = {}
    sizes: dict[str, int] = {}
    for name, result in zip(names, recorder.items, strict=True):
        if not result.StatusCode.is_good():
            raise ItemRefusedError(
                f"OPC UA server refused to monitor {name!r}: {result.StatusCode}"
            )
        sampling[name] = float(result.RevisedSamplingInterval)
        sizes[name] = int(result.RevisedQueueSize)
    return sub, Granted(float(created.RevisedPublishingInterval), sampling, sizes)
