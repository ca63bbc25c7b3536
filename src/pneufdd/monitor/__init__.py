"""Monitor: the leak history of a machine over many diagnosed runs."""

from __future__ import annotations

from pneufdd.monitor.history import HistoryEntry, append_history, location_trends, read_history

__all__ = ["HistoryEntry", "append_history", "location_trends", "read_history"]
