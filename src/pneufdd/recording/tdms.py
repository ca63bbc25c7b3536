"""Read National Instruments TDMS files (the dissertation's DAQ was an NI PCI-6025E, sec. 3.2.4).

Waveform channels carry their timing as properties: ``wf_increment`` (sample
interval [s]), ``wf_start_offset`` [s] and ``wf_start_time`` (absolute, UTC). Units
come from the channel's ``unit_string`` property or the ``units`` argument and are
converted to SI with :func:`pneufdd.physics.units.to_si`.
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Collection, Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, FileFormatError, InputError, UnitError, describe
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
        self.messages.append(record.getMessage())


@contextlib.contextmanager
def _nptdms_warnings() -> Iterator[list[str]]:
    """Collect the warnings npTDMS logs (it logs, rather than raises, on truncated files)."""
    handler = _Collect()
    logger = logging.getLogger("nptdms")
    logger.addHandler(handler)
    try:
        yield handler.messages
    finally:
        logger.removeHandler(handler)


def _open(path: Path) -> Any:
    from nptdms import TdmsFile

    label = file_label(path)
    try:
        with _nptdms_warnings() as warnings:
            tdms = TdmsFile.read(path)
    except (ValueError, EOFError, OSError, KeyError, IndexError, TypeError) as exc:
        raise FileFormatError(
            f"{label} is not a readable TDMS file ({type(exc).__name__}: {exc}); "
            f"expected {_EXPECTED}, complete and uncorrupted"
        ) from exc
    if warnings:
        raise FileFormatError(
            f"{label} is truncated or corrupted: npTDMS reported {'; '.join(warnings)!r}. "
            "Was the acquisition or the copy interrupted?"
        )
    return tdms


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
    except (TypeError, ValueError):
        step = math.nan
    if not (math.isfinite(step) and step > 0.0):
        raise FileFormatError(
            describe(
                f"{label}: TDMS channel {key} wf_increment (the sample interval [s]; pneufdd "
                "reads uniformly sampled waveform channels, select only those with channel_map)",
                increment,
                "> 0",
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
    tdms = _open(path)
    sources = {f"{g.name}/{c.name}": c for g in tdms.groups() for c in g.channels()}
    if not sources:
        raise FileFormatError(f"{label} holds no channels; expected {_EXPECTED} with waveforms")
    chosen = _select(label, sources, channel_map)
    names = [name for _, _, name in chosen]
    units = dict(units or {})
    for what, given in (("units", units), ("digital", digital or ())):
        unknown = sorted(set(given) - set(names))
        if unknown:
            raise ChannelError(describe(f"{label}: {what} names channels not read", unknown, names))
    starts = {key: _wall_time(ch.properties.get("wf_start_time")) for key, ch, _ in chosen}
    known = [s for s in starts.values() if s is not None]
    if start_time is None and known:
        start_time = min(known)
    if start_time is not None and start_time.tzinfo is None:
        start_time = start_time.replace(tzinfo=UTC)
    channels = []
    for key, source, name in chosen:
        props = source.properties
        rate = _rate(label, key, props)
        t0 = float(props.get("wf_start_offset", 0.0) or 0.0)
        started = starts[key]
        if started is not None and start_time is not None:
            t0 += (started - start_time).total_seconds()
        data = source[:]
        detected = digital is None and np.asarray(data).dtype.kind in "biu"
        if detected or (digital is not None and name in digital):
            values = _digital_values(label, key, name, data, detected)
            channels.append(Channel(name, values, rate, "1", DIGITAL, t0))
            continue
        unit = units.get(name) or str(props.get("unit_string", "") or "")
        where = (
            f"of channel {name!r} (TDMS {key}) in {label}; override with units={{{name!r}: ...}}"
        )
        if not unit:
            raise UnitError(describe(f"unit {where}", None, sorted(UNITS)))
        if np.asarray(data).dtype.kind not in "iuf":
            raise ChannelError(describe(f"dtype {where}", str(np.asarray(data).dtype), "numeric"))
        si_values, si_unit = to_si(data, unit, where)
        channels.append(Channel(name, si_values, rate, si_unit, ANALOG, t0))
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
