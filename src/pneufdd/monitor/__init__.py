"""Monitor: watch a running machine and keep its leak history.

Live monitoring (``pneufdd monitor``, ``docs/monitor.md``): sources (replay in
:mod:`~pneufdd.monitor.sources`, :mod:`~pneufdd.monitor.mqtt`,
:mod:`~pneufdd.monitor.opcua_source`; what they lost in
:mod:`~pneufdd.monitor.completeness`) -> :func:`~pneufdd.monitor.stream.run_stream`:
:class:`~pneufdd.monitor.samples.SampleAssembler` ->
:class:`~pneufdd.monitor.cycles.CycleStreamer` ->
:class:`~pneufdd.monitor.live.MachineMonitor` (per-cycle score, CUSUM, leak lives;
location and sizing in a worker, :mod:`~pneufdd.monitor.estimates`) ->
:class:`~pneufdd.monitor.database.HistoryDatabase` (SQLAlchemy, tables in
:mod:`~pneufdd.monitor.schema`); alarms through :mod:`~pneufdd.monitor.alarms` (an
outbox in the history). :mod:`pneufdd.monitor.history` writes one JSON line per
diagnosed file.

May import: :mod:`pneufdd.diagnosis`, :mod:`pneufdd.features` and the layers below;
not report or cli.
"""

from __future__ import annotations

from pneufdd.monitor.history import HistoryEntry, append_history, location_trends, read_history

__all__ = ["HistoryEntry", "append_history", "location_trends", "read_history"]
