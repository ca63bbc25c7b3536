"""Read National Instruments TDMS files (the dissertation's DAQ was an NI PCI-6025E, sec. 3.2.4).

Waveform channels carry their timing as properties: ``wf_increment`` (sample
interval [s]), ``wf_start_offset`` [s] and ``wf_start_time`` (absolute, UTC). Units
come from the channel's ``unit_string`` property or the ``units`` argument and are
converted to SI with :func:`pneufdd.physics.units.to_si`.

A TDMS file declares its sizes in headers, so a small file can declare gigabytes
(issue 39). Before npTDMS reads anything, the segments' lead-ins (28 bytes each, NI's
"TDMS file format internal structure") give the number of segments, the metadata bytes
and the objects each segment lists, checked against ``docs/limits.md``; npTDMS then
reads only the metadata (``TdmsFile.open``) through a file that refuses any declared
length longer than what is left of the file; the channels' count, types and sample
counts are checked against the limits and the memory budget; only then are the chosen
channels' samples read.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import struct
from collections.abc import Collection, Iterator, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, FileFormatError, InputError, UnitError, describe
from pneufdd.limits import (
    MAX_CHANNELS,
    MAX_RATE_HZ,
    MAX_TDMS_LISTED_OBJECTS,
    MAX_TDMS_OBJECTS,
    MAX_TDMS_SEGMENTS,
    check_memory,
    clip_message,
)
from pneufdd.physics.units import UNITS, to_si
from pneufdd.recording._files import check_input_file, file_label
from pneufdd.recording._sampling import snap_rate
from pneufdd.recording.model import ANALOG, DIGITAL, Channel, Recording

__all__ = ["read_tdms"]

_EXPECTED = "a National Instruments TDMS file"
_LABVIEW_EPOCH = datetime(1904, 1, 1, tzinfo=UTC)  # a zero TDMS timestamp means "not set"


class _Collect(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        # npTDMS quotes whole byte strings (megabytes of a damaged file): keep the gist
        self.messages.append(clip_message(record.getMessage(), 300))


@contextlib.contextmanager
def _nptdms_warnings() -> Iterator[list[str]]:
    """Collect the warnings npTDMS logs (it logs, rather than raises, on truncated files),
    instead of letting its own console handler print them."""
    from nptdms.log import log_manager

    handler = _Collect()
    logger = logging.getLogger("nptdms")
    console = log_manager.console_handler
    level = console.level
    console.setLevel(logging.CRITICAL + 1)
    logger.addHandler(handler)
    try:
        yield handler.messages
    finally:
        logger.removeHandler(handler)
        console.setLevel(level)


_LEAD_IN_BYTES = 28
"""Bytes of a segment's lead-in: tag, table of contents, version, two offsets."""
_TOC_METADATA, _TOC_NEW_OBJECT_LIST, _TOC_BIG_ENDIAN = 1 << 1, 1 << 2, 1 << 6
_INCOMPLETE = 0xFFFF_FFFF_FFFF_FFFF  # next-segment offset of a segment LabVIEW never closed
_DEFRAGMENT = "defragment the file with NI's TDMS tools, which join its segments"

SEGMENT_BYTES = 256
"""Memory npTDMS keeps per segment [bytes] (about 230 measured over 10^5 segments)."""
LISTED_OBJECT_BYTES = 16
"""Memory per object listed by a segment [bytes] (its list copies: 8 measured)."""
METADATA_BYTES_PER_BYTE = 64
"""Memory per byte of metadata [bytes] (objects and properties: 15 to 57 measured)."""
SAMPLE_COPIES = 3
"""float64 copies of each sample read (SI values, the channel, a working copy)."""

# what npTDMS raises on a damaged file (struct.error: a field cut short; MemoryError: a
# count allocated at once, e.g. DAQmx raw-data widths; NotImplementedError: a data type
# that has no reader)
_DAMAGED = (
    ValueError, EOFError, OSError, KeyError, IndexError, TypeError, struct.error,
    NotImplementedError, OverflowError, MemoryError, AttributeError,
)  # fmt: skip


class _BoundedFile:
    """The file npTDMS reads: a length declared past the end of the file is refused.

    npTDMS reads a name or property of a declared length with ``file.read(n)``, which
    allocates ``n`` bytes first: a 4 GiB length in a 1 kB file is a MemoryError (or
    4 GiB of address space). Lengths up to a lead-in's are passed on (npTDMS finds a
    truncated lead-in itself).
    """

    def __init__(self, handle: BinaryIO, size: int, label: str) -> None:
        self._handle, self._size, self._label = handle, size, label

    def read(self, n: int = -1) -> bytes:
        if n is not None and n > _LEAD_IN_BYTES:
            at = self._handle.tell()
            if n > self._size - at:
                raise FileFormatError(
                    describe(
                        f"{self._label}: a length its TDMS metadata declares at byte {at:,} "
                        "(a name, a property or a data block)",
                        f"{n:,} bytes",
                        f"at most the {self._size - at:,} bytes left in the file",
                    )
                )
        return self._handle.read(n)

    def readinto(self, buffer: Any) -> int:
        return self._handle.readinto(buffer)  # type: ignore[attr-defined,no-any-return]

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._handle.seek(offset, whence)

    def tell(self) -> int:
        return self._handle.tell()


def _segments(handle: BinaryIO, size: int, label: str) -> tuple[int, int, int]:
    """``(segments, metadata bytes, objects listed over all segments)`` from the lead-ins.

    Each count is checked as it grows (:data:`~pneufdd.limits.MAX_TDMS_SEGMENTS`,
    :data:`~pneufdd.limits.MAX_TDMS_OBJECTS` a segment,
    :data:`~pneufdd.limits.MAX_TDMS_LISTED_OBJECTS`), so a walk ends early. A segment
    without metadata lists its predecessor's objects; one that adds to its
    predecessor's list (no ``kTocNewObjList``) is counted as adding every object it
    names (an upper bound: the names are not read here).
    """
    position = segments = metadata = listed = objects = 0
    while position + _LEAD_IN_BYTES <= size:
        handle.seek(position)
        lead = handle.read(_LEAD_IN_BYTES)
        if lead[:4] != b"TDSm":
            break  # npTDMS names what it finds there
        (toc,) = struct.unpack("<l", lead[4:8])
        order = ">" if toc & _TOC_BIG_ENDIAN else "<"
        _, next_offset, raw_offset = struct.unpack(order + "lQQ", lead[8:28])
        segments += 1
        _limit(label, f"number of segments ({_DEFRAGMENT})", segments, MAX_TDMS_SEGMENTS, False)
        if toc & _TOC_METADATA:
            start = position + _LEAD_IN_BYTES
            metadata += max(0, min(raw_offset, size - start))
            count = handle.read(4)
            declared = struct.unpack(order + "L", count)[0] if len(count) == 4 else 0
            where = f"objects listed by the segment at byte {position:,}"
            _limit(label, where, declared, MAX_TDMS_OBJECTS)
            objects = declared if toc & _TOC_NEW_OBJECT_LIST else objects + declared
        listed += objects
        where = f"objects listed over all segments (objects x segments; {_DEFRAGMENT})"
        _limit(label, where, listed, MAX_TDMS_LISTED_OBJECTS, False)
        if next_offset == _INCOMPLETE:
            break
        position += _LEAD_IN_BYTES + next_offset
    return segments, metadata, listed


def _limit(label: str, what: str, value: int, limit: int, exact: bool = True) -> None:
    """Refuse ``value`` past ``limit``; ``exact``: the value is whole (else a count that
    stopped growing at the limit, shown as "more than")."""
    if value > limit:
        shown = f"{value:,}" if exact else f"more than {limit:,}"
        raise FileFormatError(
            describe(f"{label}: {what}", shown, f"at most {limit:,} (docs/limits.md)")
        )


@contextlib.contextmanager
def _opened(path: Path) -> Iterator[Any]:
    """The TDMS file's metadata (``TdmsFile.open``), its sizes checked; samples unread."""
    from nptdms import TdmsFile

    label = file_label(path)
    size = path.stat().st_size
    with open(path, "rb") as handle:
        segments, metadata, listed = _segments(handle, size, label)
        check_memory(
            f"{label}: TDMS metadata ({segments:,} segments, {metadata:,} bytes of metadata, "
            f"{listed:,} objects listed)",
            segments * SEGMENT_BYTES
            + listed * LISTED_OBJECT_BYTES
            + metadata * METADATA_BYTES_PER_BYTE,
            error=FileFormatError,
        )
        handle.seek(0)
        with _nptdms_warnings() as warnings:
            with _damage(label, "is not a readable TDMS file"):
                tdms = TdmsFile.open(_BoundedFile(handle, size, label))
            if warnings:
                raise FileFormatError(
                    f"{label} is truncated or corrupted: npTDMS reported "
                    f"{'; '.join(warnings)!r}. Was the acquisition or the copy interrupted?"
                )
            yield tdms


@contextlib.contextmanager
def _damage(label: str, what: str) -> Iterator[None]:
    """npTDMS's errors on a damaged file as a :class:`FileFormatError` naming ``label``."""
    try:
        yield
    except InputError:
        raise
    except _DAMAGED as exc:
        raise FileFormatError(
            f"{label} {what} ({type(exc).__name__}: {exc}); expected {_EXPECTED}, complete "
            "and uncorrupted"
        ) from None


def _select(
    label: str, sources: dict[str, Any], channel_map: Mapping[str, str] | None
) -> list[tuple[str, Any, str]]:
    """Return ``(tdms key, channel object, pneufdd name)`` in file or map order."""
    if channel_map is None:
        chosen = [(key, ch, ch.name) for key, ch in sources.items()]
    else:
        by_name: dict[str, list[str]] = {}
        for key, ch in sources.items():
            by_name.setdefault(ch.name, []).append(key)
        chosen = []
        for key, name in channel_map.items():
            if key in sources:
                chosen.append((key, sources[key], name))
            elif len(by_name.get(key, [])) == 1:
                full = by_name[key][0]
                chosen.append((full, sources[full], name))
            elif key in by_name:
                raise ChannelError(
                    describe(
                        f"{label}: channel_map key {key!r} is in several groups", key, by_name[key]
                    )
                )
            else:
                raise ChannelError(
                    describe(f"{label}: channel_map key not in the file", key, list(sources))
                )
    seen: dict[str, str] = {}
    for key, _, name in chosen:
        if name in seen:
            raise ChannelError(
                describe(
                    f"{label}: TDMS channels {seen[name]!r} and {key!r} both become channel "
                    f"{name!r} (rename one with channel_map={{'group/channel': 'name'}})",
                    name,
                    "each channel name once",
                )
            )
        seen[name] = key
    return chosen


def _wall_time(value: Any) -> datetime | None:
    if value is None:
        return None
    stamp = np.datetime64(value, "us").astype(datetime)
    if not isinstance(stamp, datetime):
        return None
    stamp = stamp.replace(tzinfo=UTC)
    return None if stamp == _LABVIEW_EPOCH else stamp


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.datetime64):
        return str(np.datetime_as_string(value, unit="us")) + "Z"
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, str | int | float | bool) or value is None:
        return value
    return str(value)


def _rate(label: str, key: str, properties: Mapping[str, Any]) -> float:
    increment = properties.get("wf_increment")
    try:
        step = float(increment)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        step = math.nan
    if not (math.isfinite(step) and step >= 1.0 / MAX_RATE_HZ):
        raise FileFormatError(
            describe(
                f"{label}: TDMS channel {key} wf_increment (the sample interval [s]; pneufdd "
                "reads uniformly sampled waveform channels, select only those with channel_map)",
                increment,
                f">= {1.0 / MAX_RATE_HZ:g} s (at most {MAX_RATE_HZ:g} Hz, docs/limits.md)",
            )
        )
    return snap_rate(1.0 / step, lambda rate: 1.0 / rate == step)


def _digital_values(label: str, key: str, name: str, data: npt.NDArray[Any], detected: bool) -> Any:
    values = np.asarray(data)
    if values.dtype.kind == "b":
        return values.astype(np.uint8)
    ok = (values == 0) | (values == 1)
    if not np.all(ok):
        bad = values[~ok][0]
        how = (
            f"taken as digital because of its integer dtype {values.dtype}; pass digital=[...] "
            "naming the digital channels (digital=[] reads all as analog)"
            if detected
            else "listed in digital"
        )
        raise ChannelError(
            describe(
                f"{label}: value of digital channel {name!r} (TDMS {key}, {how})",
                bad.item(),
                "0 or 1",
            )
        )
    return values.astype(np.uint8)


def read_tdms(
    path: str | Path,
    channel_map: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    digital: Collection[str] | None = None,
    start_time: datetime | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> Recording:
    """Read the waveform channels of a TDMS file into a :class:`Recording`.

    Parameters
    ----------
    path : str or Path
        TDMS file.
    channel_map : mapping of str to str, optional
        TDMS channel -> pneufdd channel name (Fig. 3.16 codes). Keys are
        ``"group/channel"`` or a channel name that is unique in the file. When given,
        only the channels it names are read, in its order; by default every channel
        is read under its TDMS channel name.
    units : mapping of str to str, optional
        pneufdd channel name -> unit of the stored values (a key of
        :data:`pneufdd.physics.units.UNITS`); overrides the ``unit_string`` property.
    digital : collection of str, optional
        pneufdd names of the digital channels (0/1). By default, channels of boolean
        or integer dtype are digital.
    start_time : datetime, optional
        Wall-clock time of t = 0; default: the earliest ``wf_start_time`` of the
        channels read (or 1970-01-01 UTC if none has one).
    metadata : mapping, optional
        Free JSON-compatible metadata; ``source`` (file name and file properties)
        is added unless given.

    Returns
    -------
    Recording
        Analog channels as float64 in SI, digital channels as uint8. Each channel's
        rate is ``1 / wf_increment`` [Hz]; its ``t0`` is ``wf_start_offset`` plus
        its ``wf_start_time`` after ``start_time`` [s].

    Raises
    ------
    MissingFileError, FileFormatError
        Missing, empty, truncated or corrupted file; a channel without ``wf_increment``.
    ChannelError
        Unknown or ambiguous ``channel_map`` key, two channels with one name, digital
        values other than 0/1.
    UnitError
        An analog channel without a unit, or an unknown or ambiguous unit.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> from nptdms import ChannelObject, TdmsWriter
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "run.tdms"
    ...     with TdmsWriter(path) as writer:
    ...         writer.write_segment([
    ...             ChannelObject("AI", "Dev1/ai0", np.array([5.0, 5.5]),
    ...                           properties={"wf_increment": 0.001, "unit_string": "bar(g)"}),
    ...             ChannelObject("DI", "Dev1/port0/line0", np.array([0, 1], dtype=np.uint8),
    ...                           properties={"wf_increment": 0.01})])
    ...     rec = read_tdms(path, {"Dev1/ai0": "P_In", "Dev1/port0/line0": "U_DNC_A"})
    >>> rec.rate("P_In"), rec.rate("U_DNC_A"), float(rec.channel("P_In")[1][1])
    (1000.0, 100.0, 651325.0)
    """
    path = check_input_file(Path(path), _EXPECTED)
    label = file_label(path)
    with _opened(path) as tdms:
        with _damage(label, "has a damaged channel list"):
            sources = {f"{g.name}/{c.name}": c for g in tdms.groups() for c in g.channels()}
        if not sources:
            raise FileFormatError(f"{label} holds no channels; expected {_EXPECTED} with waveforms")
        _limit(label, "number of channels", len(sources), MAX_CHANNELS)
        chosen = _select(label, sources, channel_map)
        names = [name for _, _, name in chosen]
        units = dict(units or {})
        for what, given in (("units", units), ("digital", digital or ())):
            unknown = sorted(set(given) - set(names))
            if unknown:
                raise ChannelError(
                    describe(f"{label}: {what} names channels not read", unknown, names)
                )
        starts = {key: _wall_time(ch.properties.get("wf_start_time")) for key, ch, _ in chosen}
        known = [s for s in starts.values() if s is not None]
        if start_time is None and known:
            start_time = min(known)
        if start_time is not None and start_time.tzinfo is None:
            start_time = start_time.replace(tzinfo=UTC)
        plans = [_plan(label, key, source, name, units, digital) for key, source, name in chosen]
        check_memory(
            f"{label}: samples of the channels read ({sum(p.samples for p in plans):,} "
            "samples; split long recordings)",
            sum(p.samples * (p.itemsize + 8 * SAMPLE_COPIES) for p in plans),
            error=FileFormatError,
        )
        channels = []
        for plan in plans:
            started = starts[plan.key]
            t0 = plan.t0
            if started is not None and start_time is not None:
                t0 += (started - start_time).total_seconds()
            with _damage(label, f"has damaged samples in channel {plan.key}"):
                data = plan.source[:]
            channels.append(_channel(label, plan, data, t0))
        meta = dict(metadata or {})
        meta.setdefault(
            "source",
            {
                "format": "tdms",
                "file": path.name,
                "properties": {k: _jsonable(v) for k, v in tdms.properties.items()},
            },
        )
    try:
        return Recording(channels, start_time=start_time, metadata=meta)
    except InputError as exc:
        raise type(exc)(f"{label}: {exc}") from exc


@dataclass(frozen=True)
class _Plan:
    """A channel to read, checked from its metadata before its samples are read."""

    key: str
    source: Any
    name: str
    rate: float
    t0: float
    samples: int
    itemsize: int
    unit: str | None  # None: digital
    detected: bool  # digital because of its integer dtype


def _plan(
    label: str,
    key: str,
    source: Any,
    name: str,
    units: Mapping[str, str],
    digital: Collection[str] | None,
) -> _Plan:
    """Check a chosen channel's timing, type and unit from its metadata alone."""
    props = source.properties
    rate = _rate(label, key, props)
    t0 = _start_offset(label, key, props)
    with _damage(label, f"has a damaged data type in channel {key}"):
        dtype = np.dtype(source.dtype)
        samples = len(source)
    detected = digital is None and dtype.kind in "biu"
    if detected or (digital is not None and name in digital):
        if dtype.kind not in "biuf":
            raise ChannelError(
                describe(f"{label}: dtype of digital channel {name!r} (TDMS {key})",
                         str(dtype), "0/1 numbers")
            )  # fmt: skip
        return _Plan(key, source, name, rate, t0, samples, dtype.itemsize, None, detected)
    unit = units.get(name) or str(props.get("unit_string", "") or "")
    where = f"of channel {name!r} (TDMS {key}) in {label}; override with units={{{name!r}: ...}}"
    if not unit:
        raise UnitError(describe(f"unit {where}", None, sorted(UNITS)))
    if dtype.kind not in "iuf":
        raise ChannelError(describe(f"dtype {where}", str(dtype), "numeric"))
    return _Plan(key, source, name, rate, t0, samples, dtype.itemsize, unit, False)


def _channel(label: str, plan: _Plan, data: Any, t0: float) -> Channel:
    if plan.unit is None:
        values = _digital_values(label, plan.key, plan.name, data, plan.detected)
        return Channel(plan.name, values, plan.rate, "1", DIGITAL, t0)
    where = (
        f"of channel {plan.name!r} (TDMS {plan.key}) in {label}; override with "
        f"units={{{plan.name!r}: ...}}"
    )
    si_values, si_unit = to_si(data, plan.unit, where)
    return Channel(plan.name, si_values, plan.rate, si_unit, ANALOG, t0)


def _start_offset(label: str, key: str, properties: Mapping[str, Any]) -> float:
    value = properties.get("wf_start_offset", 0.0)
    try:
        t0 = float(value or 0.0)
    except (TypeError, ValueError, OverflowError):
        t0 = math.nan
    if not math.isfinite(t0):
        raise FileFormatError(
            describe(f"{label}: TDMS channel {key} wf_start_offset [s]", value, "a finite time")
        )
    return t0
