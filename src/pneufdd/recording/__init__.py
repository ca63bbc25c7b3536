"""Acquire: the :class:`Recording` data model and its readers and writer."""

from __future__ import annotations

from pneufdd.recording.model import ANALOG, DIGITAL, Channel, ChannelKind, Recording

__all__ = ["ANALOG", "DIGITAL", "Channel", "ChannelKind", "Recording"]
