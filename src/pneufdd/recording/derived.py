"""Channels a tag map derives: end switches from a position, a signed flow from two meters.

Issue 33, items 3 and 4. Both are declared in the tag map (``docs/recording.md``) and
added by :func:`~pneufdd.recording.tag_map.read_mapped` after the file is read.

Flows in and out of a chamber
-----------------------------

A line flow ``Q_<ACT>_A/B`` is positive into the actuator (towards the chamber).
A rig may log it as one signed channel (a bidirectional meter: one column, nothing to
declare), as one meter that reads one direction only (one column: its other
direction reads 0, and the reference learns it that way; nothing to declare), or as
**two unsigned channels**, the flow into and the flow out of the chamber: two columns
with the same role and ``direction = "in"`` / ``"out"``::

    "FT1_in"  = { role = "Q_CYL_A", unit = "l/min", basis = "ANR", direction = "in" }
    "FT1_out" = { role = "Q_CYL_A", unit = "l/min", basis = "ANR", direction = "out" }

The channel is then ``in - out`` (a lone ``out`` column gives ``-out``). Both columns
must share their time column (rate, first sample, length). A magnitude logged with a
negative sign for the outflow is already signed: one column, no ``direction``.

End switches from a position sensor
-----------------------------------

Segmentation awaits the end switches the PLC waits for (``S_<ACT>_A`` at the home or
retracted end, ``S_<ACT>_B`` at the extended end). A rig that records a position
sensor (``X_<ACT>``, an LVDT or a linear potentiometer) may not record the switches,
or have none. A tag map then derives them from the position::

    [switches]
    S_CYL_A = { position = "X_CYL" }                         # learned: low end plateau
    S_CYL_B = { position = "X_CYL", above = 199.0 }          # given, in X_CYL's unit
    S_GRIP_B = { position = "X_GRIP", plateau = "low" }      # a sensor reading less extended

**Given thresholds** (``below`` or ``above``, in the position column's unit from the
map, or in ``unit``): the switch is on while the position is at or below ``below``
(at or above ``above``) and goes off only once it has moved ``hysteresis`` beyond it
(default: the learned rule's noise margin ``tol`` below, a switch's own hysteresis).

**Learned thresholds** (no ``below``/``above``): from the two end plateaus of the
position signal, where the actuator rests against its stops. With ``lo``/``hi`` the
0.5th and 99.5th percentiles of the finite samples (spikes ignored), the travel
``hi - lo``, the noise ``sigma`` (1.4826 x the median absolute sample-to-sample
difference / sqrt 2, at least a twelfth-root of the smallest step of a quantised
sensor) and the margin ``tol = max(4 sigma, 0.5 % of the travel, one resolution
step)``:

* the plateau level ``L`` is the median of the samples in the lowest 10 % of the travel
  (``H``: the highest 10 %); a plateau is **found** when the position stays within
  ``tol`` of it for at least :data:`MIN_REST_S` without a break;
* ``_A`` switches (``plateau = "low"`` by default) are on at or below ``L + tol`` and
  off above ``L + 2 tol``; ``_B`` switches (``"high"``) on at or above ``H - tol``, off
  below ``H - 2 tol`` (hysteresis ``tol``);
* a signal that does not move (travel below 20 sigma), or a plateau not found (a
  capture that never rests at that end, a sensor that drifts), is an error naming the
  file, the position channel and the switch, asking for ``below``/``above``.

Each file learns its own thresholds. The derived switch is sampled on the PLC's clock
(the grid of the recording's first valve solenoid channel; the position's own clock
when there is none): its state at a PLC sample is the hysteresis state of the last
position sample at or before it, as a PLC polling the sensor would see it. What was
derived is written to ``metadata["derived_switches"]``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.errors import ChannelError, InputError, UnitError, describe
from pneufdd.physics.units import UNITS
from pneufdd.recording.model import DIGITAL, Channel, Recording

__all__ = [
    "FLOW_DIRECTIONS",
    "MIN_REST_S",
    "SwitchSpec",
    "combine_flow_parts",
    "derive_switches",
    "flow_part_role",
    "parse_switches",
    "switch_thresholds",
]

FLOW_DIRECTIONS = {"in": 1.0, "out": -1.0}
"""A flow column's ``direction`` -> its sign in the chamber's signed flow."""

MIN_REST_S = 0.05
"""Shortest rest at an end stop that counts as a plateau [s]."""

PLATEAU_BAND = 0.10
"""Share of the travel at each end whose samples give the plateau level [-]."""

MIN_TRAVEL_NOISE = 20.0
"""Least travel, in noise standard deviations, of a position that moves [-]."""

_SWITCH = "S_[A-Z][A-Z0-9_]*_[AB]"
_KEYS = ("position", "below", "above", "plateau", "hysteresis", "unit")


@dataclass(frozen=True)
class SwitchSpec:
    """How one end switch is derived from a position channel (thresholds in SI, m).

    Attributes
    ----------
    switch : str
        The switch channel, ``S_<ACT>_A`` or ``S_<ACT>_B``.
    position : str
        The position channel (a role of the map, ``X_<ACT>``).
    below, above : float or None
        Given threshold [m]: on at or below ``below``, or at or above ``above``.
    plateau : str
        ``"low"`` or ``"high"``: the end a learned threshold is taken from.
    hysteresis : float or None
        Distance back beyond the threshold before the switch goes off [m]; None: the
        learned margin ``tol``.
    """

    switch: str
    position: str
    below: float | None = None
    above: float | None = None
    plateau: str = "low"
    hysteresis: float | None = None

    @property
    def learned(self) -> bool:
        """True when the threshold comes from the position's end plateau."""
        return self.below is None and self.above is None


def _number(where: str, value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(describe(where, value, what))
    return float(value)


def _length(where: str, entry: Mapping[str, Any], key: str, unit: Any) -> float | None:
    """``entry[key]`` (in ``unit``, a length's :class:`~pneufdd.physics.units.UnitSpec`)
    in m; None when absent."""
    if key not in entry:
        return None
    value = _number(f"{where}.{key}", entry[key], "a number (the position's unit)")
    return float(unit.to_si(np.asarray(value)))


def parse_switches(
    data: Any, source: str, units: Mapping[str, str], roles: set[str]
) -> tuple[SwitchSpec, ...]:
    """Validate a map's ``[switches]`` table.

    Parameters
    ----------
    data : Any
        The table (switch name -> ``{ position = ..., below/above/plateau, ... }``).
    source : str
        The map's name in messages.
    units : mapping
        The map's position roles -> their unit (a :data:`~pneufdd.physics.units.UNITS` key).
    roles : set of str
        Every role the map's columns give (a derived switch must not be one).

    Examples
    --------
    >>> (s,) = parse_switches({"S_CYL_B": {"position": "X_CYL", "above": 199.0}},
    ...                       "m.toml", {"X_CYL": "mm"}, {"X_CYL"})
    >>> s.switch, s.plateau, round(s.above, 6)
    ('S_CYL_B', 'high', 0.199)
    """
    import re

    if not isinstance(data, Mapping):
        raise InputError(describe(f"{source}: [switches]", data, "a table per switch"))
    specs = []
    for switch, entry in data.items():
        where = f"{source}: switches.{switch!r}"
        if not isinstance(switch, str) or not re.fullmatch(_SWITCH, switch):
            raise InputError(describe(f"{source}: switch name", switch, "S_<ACT>_A or S_<ACT>_B"))
        if switch in roles:
            raise ChannelError(
                describe(where, "also the role of a column", "a switch derived or read, not both")
            )
        if not isinstance(entry, Mapping):
            raise InputError(describe(where, entry, '{ position = "X_<ACT>", ... }'))
        extra = sorted(set(entry) - set(_KEYS))
        if extra:
            raise InputError(describe(f"{where}: unknown key", extra[0], list(_KEYS)))
        position = entry.get("position")
        if not isinstance(position, str) or position not in units:
            raise InputError(
                describe(f"{where}.position", position, sorted(units) or "an X_<ACT> role")
            )
        unit = entry.get("unit", units[position])
        spec = UNITS.get(unit) if isinstance(unit, str) else None
        if spec is None or spec.quantity != "length":
            allowed = sorted(k for k, s in UNITS.items() if s.quantity == "length")
            raise UnitError(describe(f"{where}.unit", unit, allowed))
        below, above = _length(where, entry, "below", spec), _length(where, entry, "above", spec)
        if below is not None and above is not None:
            raise InputError(describe(f"{where}", "below and above", "one threshold"))
        plateau = entry.get("plateau", "low" if switch.endswith("_A") else "high")
        if plateau not in ("low", "high") or (
            (below is not None or above is not None) and "plateau" in entry
        ):
            raise InputError(
                describe(f"{where}.plateau", plateau, "'low' or 'high', without below/above")
            )
        if above is not None:
            plateau = "high"
        elif below is not None:
            plateau = "low"
        hysteresis = _length(where, entry, "hysteresis", spec)
        if hysteresis is not None and hysteresis < 0:
            raise InputError(describe(f"{where}.hysteresis", entry["hysteresis"], ">= 0"))
        specs.append(SwitchSpec(switch, str(position), below, above, str(plateau), hysteresis))
    return tuple(specs)


def _noise(x: npt.NDArray[np.float64]) -> tuple[float, float]:
    """Noise standard deviation and resolution step of a position signal [m]."""
    d = np.abs(np.diff(x))
    steps = d[d > 0]
    resolution = float(steps.min()) if steps.size else 0.0
    sigma = 1.4826 * float(np.median(d)) / math.sqrt(2.0) if d.size else 0.0
    return max(sigma, resolution / math.sqrt(12.0)), resolution


def _longest_rest(inside: npt.NDArray[np.bool_]) -> int:
    """Longest run of True samples."""
    if not inside.any():
        return 0
    edges = np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))
    return int(np.max(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)))


def switch_thresholds(
    x: npt.ArrayLike, rate_hz: float, spec: SwitchSpec, where: str
) -> tuple[float, float, dict[str, float]]:
    """(on threshold, hysteresis, what was learned) of ``spec`` on samples ``x`` [m].

    Raises
    ------
    ChannelError
        When a learned threshold finds no movement or no plateau at its end.
    """
    values = np.asarray(x, dtype=np.float64)
    values = values[np.isfinite(values)]
    learned: dict[str, float] = {}
    if spec.learned or spec.hysteresis is None:
        if values.size < 3:
            raise ChannelError(
                describe(f"{where}: samples of {spec.position}", values.size, ">= 3 finite")
            )
        lo, hi = (float(v) for v in np.percentile(values, [0.5, 99.5]))
        travel = hi - lo
        sigma, resolution = _noise(values)
        tol = max(4.0 * sigma, 0.005 * travel, resolution)
        learned = {"noise_m": sigma, "travel_m": travel, "tol_m": tol}
        if spec.learned:
            if travel < MIN_TRAVEL_NOISE * sigma or travel <= 0.0:
                raise ChannelError(
                    f"{where}: cannot learn {spec.switch} from {spec.position}: the position "
                    f"travels {travel:.3g} m against a noise of {sigma:.3g} m (no movement "
                    "seen); give below = ... or above = ... for it under [switches]"
                )
            low = spec.plateau == "low"
            band = (
                values <= lo + PLATEAU_BAND * travel
                if low
                else values >= hi - PLATEAU_BAND * travel
            )
            level = float(np.median(values[band]))
            rest = _longest_rest(np.abs(values - level) <= tol) / rate_hz
            if rest < MIN_REST_S:
                raise ChannelError(
                    f"{where}: no end plateau found at the {spec.plateau} end of "
                    f"{spec.position} for {spec.switch} (the position stayed within "
                    f"{tol:.3g} m of {level:.4g} m for {rest:.3f} s at most, less than "
                    f"{MIN_REST_S:g} s); give below = ... or above = ... for it under "
                    "[switches]"
                )
            learned["plateau_m"] = level
            threshold = level + tol if low else level - tol
            return threshold, tol if spec.hysteresis is None else spec.hysteresis, learned
    given = spec.below if spec.below is not None else spec.above
    hysteresis = spec.hysteresis if spec.hysteresis is not None else learned["tol_m"]
    return float(given if given is not None else 0.0), hysteresis, learned


def _states(
    x: npt.NDArray[np.float64], threshold: float, hysteresis: float, low: bool
) -> npt.NDArray[np.uint8]:
    """Switch state at each position sample, with hysteresis (NaN holds the state)."""
    with np.errstate(invalid="ignore"):
        if low:
            on, off = x <= threshold, x > threshold + hysteresis
        else:
            on, off = x >= threshold, x < threshold - hysteresis
    event = np.where(on, 1, np.where(off, 0, -1)).astype(np.int8)
    if event.size and event[0] < 0:  # inside the hysteresis band at the start
        first = x[0]
        event[0] = int(
            math.isfinite(first)
            and (first <= threshold + hysteresis if low else first >= threshold - hysteresis)
        )
    index = np.where(event >= 0, np.arange(event.size), 0)
    np.maximum.accumulate(index, out=index)
    return event[index].astype(np.uint8)


def derive_switches(recording: Recording, specs: tuple[SwitchSpec, ...], where: str) -> Recording:
    """``recording`` with the switches of ``specs`` added (on the PLC's clock).

    Examples
    --------
    >>> x = np.concatenate([np.zeros(300), np.linspace(0, 0.2, 200), np.full(300, 0.2)])
    >>> rec = Recording.from_arrays({"X_CYL": x}, 1000.0, units={"X_CYL": "m"},
    ...     digital={"U_CYL_A": np.zeros(80, np.uint8)}, digital_rate_hz=100.0)
    >>> out = derive_switches(rec, (SwitchSpec("S_CYL_B", "X_CYL", plateau="high"),), "rec")
    >>> _, s = out.channel("S_CYL_B")
    >>> int(np.argmax(s)), out.metadata["derived_switches"]["S_CYL_B"]["rule"]
    (50, 'learned from the high end plateau')
    """
    if not specs:
        return recording
    clocks = [n for n in recording.digital_channels if n.startswith("U_")]
    derived: list[Channel] = []
    report: dict[str, Any] = {}
    for spec in specs:
        if spec.switch in recording.channels:
            raise ChannelError(
                describe(f"{where}: derived switch {spec.switch}", "already recorded", "one source")
            )
        recording.require([spec.position], f"deriving {spec.switch}")
        info = recording.info(spec.position)
        x = np.asarray(info.values, dtype=np.float64)
        threshold, hysteresis, learned = switch_thresholds(x, info.rate_hz, spec, where)
        low = spec.plateau == "low"
        state = _states(x, threshold, hysteresis, low)
        grid = recording.info(clocks[0]) if clocks else info
        t = grid.time
        k = np.floor((t - info.t0) * info.rate_hz + 1e-9).astype(np.int64)
        sampled = np.where(k >= 0, state[np.clip(k, 0, max(state.size - 1, 0))], state[:1])
        if not state.size:
            sampled = np.zeros(t.size, dtype=np.uint8)
        derived.append(Channel(spec.switch, sampled, grid.rate_hz, "1", DIGITAL, grid.t0))
        report[spec.switch] = {
            "position": spec.position,
            "rule": (
                f"learned from the {spec.plateau} end plateau"
                if spec.learned
                else f"given: {'below' if low else 'above'} the threshold"
            ),
            "on_m": threshold,
            "off_m": threshold + hysteresis if low else threshold - hysteresis,
            **learned,
        }
    metadata = {**recording.metadata, "derived_switches": report}
    channels = [recording.info(n) for n in recording.channels] + derived
    return Recording(channels, start_time=recording.start_time, metadata=metadata)


def flow_part_role(role: str, direction: str) -> str:
    """The name a one-direction flow column is read under before it is combined.

    Examples
    --------
    >>> flow_part_role("Q_CYL_A", "out")
    'Q_CYL_A.out'
    """
    return f"{role}.{direction}"


def combine_flow_parts(recording: Recording, where: str) -> Recording:
    """``recording`` with each pair of one-direction flow channels made one signed flow.

    Channels named ``<role>.in`` / ``<role>.out`` (:func:`flow_part_role`) become
    ``<role>`` = in - out, in the place of the first part.

    Examples
    --------
    >>> rec = Recording.from_arrays(
    ...     {"Q_CYL_A.in": np.array([2.0, 0.0]), "Q_CYL_A.out": np.array([0.0, 3.0])},
    ...     1000.0, units={"Q_CYL_A.in": "kg/s", "Q_CYL_A.out": "kg/s"})
    >>> combine_flow_parts(rec, "r").channel("Q_CYL_A")[1].tolist()
    [2.0, -3.0]
    """
    parts: dict[str, list[str]] = {}
    for name in recording.channels:
        base, dot, direction = name.rpartition(".")
        if dot and direction in FLOW_DIRECTIONS:
            parts.setdefault(base, []).append(name)
    if not parts:
        return recording
    channels: list[Channel] = []
    for name in recording.channels:
        base, _, direction = name.rpartition(".")
        if base not in parts:
            channels.append(recording.info(name))
            continue
        if name != parts[base][0]:
            continue
        infos = [recording.info(n) for n in parts[base]]
        first = infos[0]
        for other in infos[1:]:
            if (other.rate_hz, other.t0, other.values.size) != (
                first.rate_hz,
                first.t0,
                first.values.size,
            ):
                raise ChannelError(
                    describe(
                        f"{where}: the in and out columns of {base} (rate, first sample, length)",
                        f"{other.rate_hz:g} Hz, {other.t0:g} s, {other.values.size}",
                        f"{first.rate_hz:g} Hz, {first.t0:g} s, {first.values.size} "
                        "(one time column)",
                    )
                )
        total = np.zeros(first.values.size, dtype=np.float64)
        for info in infos:
            sign = FLOW_DIRECTIONS[info.name.rpartition(".")[2]]
            total += sign * np.asarray(info.values, dtype=np.float64)
        channels.append(Channel(base, total, first.rate_hz, first.unit, first.kind, first.t0))
    return Recording(channels, start_time=recording.start_time, metadata=recording.metadata)
