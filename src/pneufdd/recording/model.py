"""The :class:`Recording`: one data model for simulated and measured machine data.

A recording holds uniformly sampled channels, each at its own rate (on the
dissertation's rig: analog at 1 kHz, digital at 100 Hz, Table 3.2 and section 3.2.4),
a start time, and free JSON-compatible metadata (machine, scenario, ground-truth
leaks for simulated data). Values are stored in SI units (see
:mod:`pneufdd.physics.units`); readers convert at the edge.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, InputError, UnitError, describe
from pneufdd.physics.units import UNITS

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["ANALOG", "DIGITAL", "Channel", "ChannelKind", "Recording"]

ChannelKind = Literal["analog", "digital"]
ANALOG: ChannelKind = "analog"
DIGITAL: ChannelKind = "digital"

SI_UNITS: frozenset[str] = frozenset(spec.si_unit for spec in UNITS.values())
"""Units a channel may carry inside a Recording (SI only)."""


@dataclass(frozen=True, eq=False)
class Channel:
    """One uniformly sampled channel.

    Attributes
    ----------
    name : str
        Channel name, following the dissertation's codes (Fig. 3.16): ``P_In``,
        ``Q_In``, ``P_DNC_A``, ``U_DNC_A`` (valve solenoid), ``S_DNC_A`` (switch).
    values : ndarray
        Samples, 1-D. Analog: float32 or float64 in ``unit``. Digital: uint8, 0 or 1.
    rate_hz : float
        Sample rate [Hz].
    unit : str
        SI unit of ``values`` (``"1"`` for digital channels).
    kind : {"analog", "digital"}
        Analog (sensor) or digital (PLC I/O) channel.
    t0 : float
        Time of the first sample after the recording's start [s].
    """

    name: str
    values: npt.NDArray[Any]
    rate_hz: float
    unit: str
    kind: ChannelKind = ANALOG
    t0: float = 0.0

    def __post_init__(self) -> None:
        where = f"channel {self.name!r}"
        if not isinstance(self.name, str) or not self.name or self.name != self.name.strip():
            raise ChannelError(describe("channel name", self.name, "a non-empty string"))
        if self.kind not in (ANALOG, DIGITAL):
            raise ChannelError(describe(f"kind of {where}", self.kind, [ANALOG, DIGITAL]))
        if self.unit not in SI_UNITS:
            raise UnitError(
                describe(
                    f"unit of {where} (store SI; convert with to_si)", self.unit, sorted(SI_UNITS)
                )
            )
        rate = float(self.rate_hz)
        if not math.isfinite(rate) or rate <= 0.0:
            raise ChannelError(describe(f"sample rate of {where} [Hz]", self.rate_hz, "> 0"))
        t0 = float(self.t0)
        if not math.isfinite(t0):
            raise ChannelError(describe(f"start offset t0 of {where} [s]", self.t0, "finite"))
        values = np.asarray(self.values)
        if values.ndim != 1:
            raise ChannelError(describe(f"shape of {where}", values.shape, "1-D"))
        if self.kind == DIGITAL:
            if self.unit != "1":
                raise UnitError(describe(f"unit of digital {where}", self.unit, ["1"]))
            if values.dtype.kind in "ub":
                wrong = values.size > 0 and int(values.max()) > 1
            else:
                finite = values[np.isfinite(values)] if values.dtype.kind == "f" else values
                wrong = finite.size != values.size or bool(np.any((finite != 0) & (finite != 1)))
            if wrong:
                raise ChannelError(
                    describe(f"values of digital {where}", "values other than 0 and 1", "0 or 1")
                )
            values = values.astype(np.uint8)
        elif values.dtype.kind == "f" and values.dtype.itemsize in (4, 8):
            values = values.astype(values.dtype.newbyteorder("="), copy=False)
        elif values.dtype not in (np.float32, np.float64):
            if values.dtype.kind not in "iuf":
                raise ChannelError(describe(f"dtype of {where}", str(values.dtype), "numeric"))
            values = values.astype(np.float64)
        values.setflags(write=False)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "rate_hz", rate)
        object.__setattr__(self, "t0", t0)

    @property
    def time(self) -> npt.NDArray[np.float64]:
        """Sample times after the recording's start [s]."""
        return self.t0 + np.arange(self.values.size, dtype=np.float64) / self.rate_hz

    @property
    def duration(self) -> float:
        """Time span covered, ``n / rate`` [s]."""
        return self.values.size / self.rate_hz

    def equals(self, other: Channel) -> bool:
        """True when name, kind, unit, rate, offset, dtype and every value match exactly."""
        return (
            self.name == other.name
            and self.kind == other.kind
            and self.unit == other.unit
            and self.rate_hz == other.rate_hz
            and self.t0 == other.t0
            and self.values.dtype == other.values.dtype
            and np.array_equal(self.values, other.values, equal_nan=True)
        )


def _check_metadata(metadata: Mapping[str, Any]) -> dict[str, Any]:
    try:
        text = json.dumps(dict(metadata), allow_nan=False, sort_keys=True)
    except (TypeError, ValueError, RecursionError) as exc:
        raise InputError(
            describe(
                "recording metadata",
                type(metadata).__name__,
                "a JSON-serialisable mapping (str keys, no NaN)",
            )
        ) from exc
    loaded: dict[str, Any] = json.loads(text)
    return loaded


class Recording:
    """Synchronously started, uniformly sampled channels of one machine run.

    Parameters
    ----------
    channels : iterable of Channel
        The channels; names must be unique.
    start_time : datetime, optional
        Wall-clock time of t = 0 (timezone-aware; naive times are taken as UTC).
        Defaults to 1970-01-01T00:00:00Z, which marks simulated data.
    metadata : mapping, optional
        Free JSON-compatible metadata. Conventional keys: ``machine`` (name or
        description), ``scenario``, ``leaks`` (ground truth for simulated data:
        a list of ``{"location", "size", "unit", "mass_flow_kg_s"}``), ``seed``.

    Examples
    --------
    >>> import numpy as np
    >>> rec = Recording.from_arrays(
    ...     analog={"P_In": np.full(1000, 5.0e5)}, analog_rate_hz=1000.0,
    ...     digital={"U_DNC_A": np.zeros(100, dtype=np.uint8)}, digital_rate_hz=100.0,
    ...     units={"P_In": "Pa"}, metadata={"machine": "festo-dsd"})
    >>> rec.channels
    ('P_In', 'U_DNC_A')
    >>> t, p = rec.channel("P_In")
    >>> float(t[1]), float(p[0])
    (0.001, 500000.0)
    """

    def __init__(
        self,
        channels: Iterable[Channel],
        start_time: datetime | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        by_name: dict[str, Channel] = {}
        for ch in channels:
            if not isinstance(ch, Channel):
                raise ChannelError(describe("channel", type(ch).__name__, ["Channel"]))
            if ch.name in by_name:
                raise ChannelError(describe("duplicate channel name", ch.name, "each name once"))
            by_name[ch.name] = ch
        self._channels = by_name
        if start_time is None:
            start_time = datetime(1970, 1, 1, tzinfo=UTC)
        if not isinstance(start_time, datetime):
            raise InputError(describe("start_time", start_time, "a datetime"))
        to_pydatetime = getattr(start_time, "to_pydatetime", None)
        if callable(to_pydatetime):  # a pandas Timestamp: keep a plain datetime (microseconds)
            start_time = to_pydatetime(warn=False)
        if start_time.tzinfo is None:
            start_time = start_time.replace(tzinfo=UTC)
        self._start_time = start_time
        self._metadata = _check_metadata(metadata or {})

    # ------------------------------------------------------------------ build
    @classmethod
    def from_arrays(
        cls,
        analog: Mapping[str, npt.ArrayLike],
        analog_rate_hz: float,
        digital: Mapping[str, npt.ArrayLike] | None = None,
        digital_rate_hz: float | None = None,
        units: Mapping[str, str] | None = None,
        start_time: datetime | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> Recording:
        """Build a recording from arrays already in SI units.

        Parameters
        ----------
        analog : mapping of str to array_like
            Analog channels, all at ``analog_rate_hz``.
        analog_rate_hz : float
            Analog sample rate [Hz].
        digital : mapping of str to array_like, optional
            Digital channels (0/1), all at ``digital_rate_hz``.
        digital_rate_hz : float, optional
            Digital sample rate [Hz]; required when ``digital`` is given.
        units : mapping of str to str, optional
            SI unit of each analog channel; a channel not named is an error.
        start_time : datetime, optional
            Wall-clock time of t = 0.
        metadata : mapping, optional
            Free JSON-compatible metadata.

        Returns
        -------
        Recording
        """
        units = dict(units or {})
        chans: list[Channel] = []
        for name, vals in analog.items():
            if name not in units:
                raise UnitError(
                    describe(
                        f"unit of analog channel {name!r}",
                        None,
                        "one of the SI units; pass units={name: unit}",
                    )
                )
            chans.append(Channel(name, np.asarray(vals), analog_rate_hz, units[name], ANALOG))
        if digital:
            if digital_rate_hz is None:
                raise InputError(describe("digital_rate_hz", None, "> 0 when digital given"))
            for name, vals in digital.items():
                chans.append(Channel(name, np.asarray(vals), digital_rate_hz, "1", DIGITAL))
        return cls(chans, start_time=start_time, metadata=metadata)

    # ----------------------------------------------------------------- access
    @property
    def channels(self) -> tuple[str, ...]:
        """Channel names, in insertion order."""
        return tuple(self._channels)

    @property
    def analog_channels(self) -> tuple[str, ...]:
        """Names of the analog channels."""
        return tuple(n for n, c in self._channels.items() if c.kind == ANALOG)

    @property
    def digital_channels(self) -> tuple[str, ...]:
        """Names of the digital channels."""
        return tuple(n for n, c in self._channels.items() if c.kind == DIGITAL)

    @property
    def metadata(self) -> dict[str, Any]:
        """Free metadata (a copy: edit it and pass it to :meth:`with_metadata`)."""
        return json.loads(json.dumps(self._metadata))  # type: ignore[no-any-return]

    @property
    def start_time(self) -> datetime:
        """Wall-clock time of t = 0 (timezone-aware)."""
        return self._start_time

    @property
    def duration(self) -> float:
        """Longest time span of any channel [s]."""
        return max((c.t0 + c.duration for c in self._channels.values()), default=0.0)

    def time_bases(self, names: Iterable[str]) -> dict[tuple[float, float, int], list[str]]:
        """``names`` grouped by time base: (rate [Hz], t0 [s], sample count) -> names.

        Channels on one time base can be processed as one 2-D array.

        Examples
        --------
        >>> rec = Recording.from_arrays(
        ...     analog={"P_In": np.zeros(10), "Q_In": np.zeros(10)}, analog_rate_hz=1000.0,
        ...     digital={"U_A": np.zeros(1, dtype=np.uint8)}, digital_rate_hz=100.0,
        ...     units={"P_In": "Pa", "Q_In": "kg/s"})
        >>> rec.time_bases(["P_In", "U_A", "Q_In"])
        {(1000.0, 0.0, 10): ['P_In', 'Q_In'], (100.0, 0.0, 1): ['U_A']}
        """
        groups: dict[tuple[float, float, int], list[str]] = {}
        for name in names:
            ch = self.info(name)
            groups.setdefault((ch.rate_hz, ch.t0, ch.values.size), []).append(name)
        return groups

    def info(self, name: str) -> Channel:
        """Return the :class:`Channel` called ``name``.

        Raises
        ------
        ChannelError
            If there is no such channel; the message lists those there are.
        """
        try:
            return self._channels[name]
        except KeyError:
            raise ChannelError(describe("channel not in recording", name, self.channels)) from None

    def channel(self, name: str) -> tuple[npt.NDArray[np.float64], npt.NDArray[Any]]:
        """Return ``(time [s], values)`` of one channel at its own rate.

        Parameters
        ----------
        name : str
            Channel name.

        Returns
        -------
        time : ndarray
            Sample times after the recording's start [s].
        values : ndarray
            Samples in the channel's SI unit (read-only).
        """
        ch = self.info(name)
        return ch.time, ch.values

    def unit(self, name: str) -> str:
        """SI unit of channel ``name``."""
        return self.info(name).unit

    def rate(self, name: str) -> float:
        """Sample rate of channel ``name`` [Hz]."""
        return self.info(name).rate_hz

    def require(self, names: Iterable[str], purpose: str) -> None:
        """Raise a clear error when any of ``names`` is missing.

        Parameters
        ----------
        names : iterable of str
            Channels the caller needs.
        purpose : str
            What they are needed for, named in the message.
        """
        missing = [n for n in names if n not in self._channels]
        if missing:
            raise ChannelError(
                f"{purpose} needs channel(s) {missing} which the recording lacks; "
                f"it has: {list(self.channels)}"
            )

    # -------------------------------------------------------------- transform
    def select(self, names: Sequence[str]) -> Recording:
        """Return a recording with only the channels ``names``, in that order."""
        self.require(names, "select")
        return Recording([self._channels[n] for n in names], self._start_time, self._metadata)

    def with_metadata(self, metadata: Mapping[str, Any]) -> Recording:
        """Return a copy whose metadata is ``metadata`` (channels are shared, read-only)."""
        return Recording(self._channels.values(), self._start_time, metadata)

    def equals(self, other: Recording) -> bool:
        """True when channels, start time and metadata match exactly."""
        return (
            self.channels == other.channels
            and self._start_time == other._start_time
            and self._metadata == other._metadata
            and all(self._channels[n].equals(other._channels[n]) for n in self.channels)
        )

    def __repr__(self) -> str:
        kinds = f"{len(self.analog_channels)} analog, {len(self.digital_channels)} digital"
        return f"<Recording {kinds} channels, {self.duration:.3f} s>"

    def to_pandas(self, channels: Sequence[str] | None = None) -> pd.DataFrame:
        """Return the channels as one wide DataFrame on the fastest channel's time base.

        Slower channels (typically the 100 Hz digital ones) are sample-and-hold
        resampled onto that base, as a PLC input would be read. The index is the
        time after the start [s], named ``time_s``; columns are channel names.

        Parameters
        ----------
        channels : sequence of str, optional
            Channels to include; all by default.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        names = list(channels) if channels is not None else list(self.channels)
        self.require(names, "to_pandas")
        if not names:
            return pd.DataFrame(index=pd.Index([], name="time_s", dtype=np.float64))
        fastest = max(names, key=lambda n: self._channels[n].rate_hz)
        base = self._channels[fastest]
        t_end = max(self._channels[n].t0 + self._channels[n].duration for n in names)
        n = round((t_end - base.t0) * base.rate_hz)
        time = base.t0 + np.arange(n, dtype=np.float64) / base.rate_hz
        data: dict[str, npt.NDArray[Any]] = {}
        for name in names:
            ch = self._channels[name]
            idx = np.floor((time - ch.t0) * ch.rate_hz + 1e-9).astype(np.int64)
            valid = (idx >= 0) & (idx < ch.values.size)
            col = np.full(n, np.nan)
            col[valid] = ch.values[idx[valid]]
            data[name] = col
        return pd.DataFrame(data, index=pd.Index(time, name="time_s"))

    # -------------------------------------------------------------------- I/O
    @classmethod
    def read(cls, path: str | Path, **options: Any) -> Recording:
        """Read a recording; the format follows the file's suffix.

        ``.parquet`` is pneufdd's own format (exact round trip). ``.csv`` needs a
        column map and units (see :func:`pneufdd.recording.csv.read_csv`); ``.tdms``
        reads National Instruments TDMS files (see :func:`pneufdd.recording.tdms.read_tdms`).

        Raises
        ------
        FileFormatError
            If the file is missing, truncated, corrupted or of an unknown kind.
        """
        from pneufdd.recording.io import read_any

        return read_any(Path(path), **options)

    def write(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write the recording to Parquet; refuses to replace a file unless ``overwrite``.

        The file is written to a temporary name and renamed into place, so an
        interrupted write never leaves a half file under ``path``.

        Returns
        -------
        Path
            The path written.
        """
        from pneufdd.recording.parquet import write_parquet

        return write_parquet(self, Path(path), overwrite=overwrite)
