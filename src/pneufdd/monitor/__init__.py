"""Monitor: watch a running machine and keep its leak history.

Live monitoring (``pneufdd monitor``, ``docs/monitor.md``): sources (replay, MQTT,
OPC UA) -> :class:`~pneufdd.monitor.samples.SampleAssembler` ->
:class:`~pneufdd.monitor.cycles.CycleStreamer` ->
:class:`~pneufdd.monitor.live.MachineMonitor` (per-cycle score, CUSUM, location and
sizing, leak lives) -> :class:`~pneufdd.monitor.database.HistoryDatabase` (SQLAlchemy).
:mod:`pneufdd.monitor.history` writes one JSON line per diagnosed file.

May import: :mod:`pneufdd.diagnosis`, :mod:`pneufdd.features` and the layers below;
not report or cli.
"""

from __future__ import annotations

from pneufdd.monitor.history import HistoryEntry, append_history, location_trends, read_history

__all__ = ["HistoryEntry", "append_history", "location_trends", "read_history"]
