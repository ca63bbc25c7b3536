"""The leak-free reference model of one machine and sensor set.

It holds what section 5.3 compares new cycles against:

- per-step, per-sample templates with their spread for the band method
  (eq. 5.21, Fig. 5.13), per analog channel;
- the per-cycle feature vectors of the reference cycles (step durations, mean/min/max
  of each analog channel over each step) from which the detectors of
  :mod:`pneufdd.diagnosis.detection.statistic` are fitted (deterministically, so they are refit
  on load rather than stored);
- the machine's name and **description** (the TOML mapping of
  ``docs/machine-format.md``): its digital twin computes the leak signatures, checks
  explanations by simulation and gives the leaks' duty for their cost, so a
  reference of any machine a user can describe locates and sizes its leaks;
- the sensor set (analog channels used; the PLC's digital signals are always used,
  for segmentation and step timing);
- optionally the leak signatures of every candidate location
  (:class:`~pneufdd.diagnosis.effects.signatures.SignatureSet`), computed once per machine and
  sensor set.

It is saved to a portable ``.pnref`` file by :mod:`pneufdd.diagnosis.reference.file`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.detection.band import BandDetector
from pneufdd.diagnosis.detection.statistic import RUN_STATISTICS, CycleDistanceDetector
from pneufdd.diagnosis.effects.model import LeakEffectModel
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.errors import InputError, MachineError, describe
from pneufdd.features.step_summaries import sequence_from_records
from pneufdd.features.step_table import StepTable, feature_floor, feature_names
from pneufdd.sim import MachineDescription, parse_description

__all__ = ["MIN_REFERENCE_CYCLES", "DetectionSettings", "ReferenceModel"]


MIN_REFERENCE_CYCLES = 10
"""Fewest leak-free cycles a reference may be built from."""


RECOMMENDED_REFERENCE_CYCLES = 100
"""Leak-free cycles a reference should hold, in several recordings [-].

Rare leak-free cycle modes (parallel motions finishing in the other order, a timer one
scan short) are learned only when the reference holds some (``docs/reference.md``,
"Reference length")."""


@dataclass(frozen=True)
class DetectionSettings:
    """Tuning of the detectors, stored with the reference.

    Attributes
    ----------
    n_nuisance : int
        Supply-fluctuation directions projected out (section 4.4.1) [-].
    false_alarm_rate : float
        Target false-alarm probability per leak-free cycle and per leak-free run [-].
        The default, 0.1 %, is a fifth of the acceptance limit of 0.5 % leak-free runs
        flagged: the threshold is estimated from a few dozen reference cycles, and a
        design rate equal to the limit would exceed it on every other reference
        (``docs/detection.md``, "Run decision"). References saved before read 0.5 %.
    band_eps : float
        Band width of eq. 5.3 in standard deviations (2 or 3) [-].
    band_alarm_fraction : float
        The n % rule of section 5.3.2, as a fraction [-].
    startup_cycles : int
        Complete cycles at the start of each recording that are neither learned nor
        judged [-]. The first cycle of a recording may follow a stop of unknown length
        (the machine at rest: exhausted chambers at atmosphere, walls at room
        temperature), so it differs from the cycles of a running machine; a recording
        with no more complete cycles than this keeps them all. References saved
        before this setting existed read as 0.
    run_statistic : {"median", "mean"}
        How a run's cycle statistics are combined
        (:class:`~pneufdd.diagnosis.detection.statistic.CycleDistanceDetector`): the median, so
        that a few odd leak-free cycles do not flag a run. References saved before this
        setting existed read ``"mean"``.
    run_correlation : bool
        Let the run threshold count a run's cycles as correlated, by the intra-class
        correlation of the reference's held-out statistics within a recording
        (:class:`~pneufdd.diagnosis.detection.statistic.CycleDistanceDetector`). References saved
        before this setting existed read ``False``.
    channel_quanta : tuple of (str, float)
        Converter step of each quantised channel of the reference's recordings
        (:mod:`pneufdd.signals.quantisation`) [channel unit]: the spread of every
        feature and template sample of the channel is never below it. Empty when no
        channel is quantised (and for references saved before it existed).
    """

    n_nuisance: int = 2
    false_alarm_rate: float = 0.001
    band_eps: float = 3.0
    band_alarm_fraction: float = 0.05
    startup_cycles: int = 1
    run_statistic: str = "median"
    run_correlation: bool = True
    channel_quanta: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        if self.run_statistic not in RUN_STATISTICS:
            raise ValueError(
                f"run_statistic: received {self.run_statistic!r}; allowed: {list(RUN_STATISTICS)}"
            )
        if not isinstance(self.startup_cycles, int) or not 0 <= self.startup_cycles <= 10:
            raise ValueError(
                f"startup_cycles: received {self.startup_cycles!r}; allowed: an integer 0-10"
            )
        self._check_ranges()

    def _check_ranges(self) -> None:
        """Refuse values no detector can use (a file's settings are read through here)."""

        def number(name: str, low: float, high: float, allowed: str) -> None:
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not ok or not (math.isfinite(value) and low < value <= high):
                raise InputError(describe(f"detection setting {name!r}", value, allowed))

        number("false_alarm_rate", 0.0, 0.5, "a probability > 0 and <= 0.5")
        number("band_eps", 0.0, 10.0, "a width > 0 and <= 10 standard deviations")
        number("band_alarm_fraction", 0.0, 1.0, "a fraction > 0 and <= 1")
        n = self.n_nuisance
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= 1000:
            raise InputError(
                describe("detection setting 'n_nuisance'", n, "an integer from 0 to 1000")
            )

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form."""
        return {
            "n_nuisance": self.n_nuisance,
            "false_alarm_rate": self.false_alarm_rate,
            "band_eps": self.band_eps,
            "band_alarm_fraction": self.band_alarm_fraction,
            "startup_cycles": self.startup_cycles,
            "run_statistic": self.run_statistic,
            "run_correlation": self.run_correlation,
        } | ({"channel_quanta": dict(self.channel_quanta)} if self.channel_quanta else {})

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DetectionSettings:
        """Inverse of :meth:`to_dict`."""
        return cls(
            n_nuisance=int(data["n_nuisance"]),
            false_alarm_rate=float(data["false_alarm_rate"]),
            band_eps=float(data["band_eps"]),
            band_alarm_fraction=float(data["band_alarm_fraction"]),
            startup_cycles=int(data.get("startup_cycles", 0)),
            run_statistic=str(data.get("run_statistic", "mean")),
            run_correlation=bool(data.get("run_correlation", False)),
            channel_quanta=tuple(
                (str(k), float(v)) for k, v in dict(data.get("channel_quanta", {})).items()
            ),
        )

    def quantum(self, channel: str) -> float:
        """Converter step of ``channel``, 0.0 when it is not quantised [channel unit]."""
        return dict(self.channel_quanta).get(channel, 0.0)


@dataclass(frozen=True, eq=False)
class ReferenceModel:
    """Leak-free templates, feature statistics and signatures of one machine.

    Attributes
    ----------
    machine : str
        Machine name.
    machine_description : dict
        The machine description the reference was built with: the TOML mapping of
        ``docs/machine-format.md`` (JSON-compatible); empty when none was known
        (then nothing can be located or sized). See :attr:`description`.
    channels : tuple of str
        Analog channels of the sensor set (empty: digital signals only).
    units : tuple of str
        SI unit of each analog channel.
    n_steps : int
        PLC steps per cycle.
    features : ndarray, shape (n_cycles, n_features)
        Per-cycle feature vectors of the reference cycles [SI units].
    band_mean, band_std : ndarray, shape (n_channels, n_samples), optional
        Per-sample template mean and spread of eq. 5.21 [channel unit].
    trace_offsets : ndarray of int, shape (n_steps + 1,), optional
        Start sample of each step in the templates.
    trace_rate_hz : float
        Sample rate of the templates [Hz].
    supply_pressure : float
        Mean supply pressure ``P_In`` of the reference, NaN when not measured [Pa].
    signatures : SignatureSet, optional
        Leak signatures over :attr:`feature_names`.
    settings : DetectionSettings
        Detector tuning.
    sources : tuple of str
        Files the reference was built from.
    sequence : tuple of dict
        The machine's PLC step sequence as JSON-compatible records
        ``{"valves": [...], "switches": [[channel, state], ...]}``, used to segment runs
        exactly as the reference was segmented (empty: learn it from each run).
    localisation : LocalisationSettings
        Tuning of leak location and sizing.
    cycle_recording : ndarray of int, shape (n_cycles,), optional
        Index (in :attr:`sources`) of the recording each reference cycle came from;
        the detector's cross-validation leaves out one recording at a time when there
        are three or more (:mod:`pneufdd.diagnosis.detection.statistic`). None for references
        saved before it was stored, or built from one table of unknown origin.
    """

    machine: str
    machine_description: dict[str, Any]
    channels: tuple[str, ...]
    units: tuple[str, ...]
    n_steps: int
    features: FloatArray
    band_mean: FloatArray | None = None
    band_std: FloatArray | None = None
    trace_offsets: npt.NDArray[np.int64] | None = None
    trace_rate_hz: float = 100.0
    supply_pressure: float = float("nan")
    signatures: SignatureSet | None = None
    settings: DetectionSettings = field(default_factory=DetectionSettings)
    sources: tuple[str, ...] = ()
    sequence: tuple[dict[str, Any], ...] = ()
    localisation: LocalisationSettings = field(default_factory=LocalisationSettings)
    cycle_recording: npt.NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        feats = np.asarray(self.features, dtype=np.float64)
        if feats.ndim != 2 or feats.shape[1] != len(self.feature_names):
            raise InputError(
                describe(
                    "shape of reference features", feats.shape, f"(n, {len(self.feature_names)})"
                )
            )
        if self.cycle_recording is not None:
            groups = np.asarray(self.cycle_recording)
            if groups.shape != (feats.shape[0],) or groups.dtype.kind not in "iu":
                raise InputError(
                    describe(
                        "cycle_recording (recording of each reference cycle)",
                        f"shape {groups.shape}, dtype {groups.dtype}",
                        f"integers of shape ({feats.shape[0]},)",
                    )
                )
            object.__setattr__(self, "cycle_recording", groups.astype(np.int64))
        if feats.shape[0] < MIN_REFERENCE_CYCLES:
            raise InputError(
                describe(
                    "number of complete leak-free reference cycles",
                    feats.shape[0],
                    f">= {MIN_REFERENCE_CYCLES}",
                )
            )
        if not np.all(np.isfinite(feats)):
            raise InputError(describe("reference features", "NaN or infinite", "finite"))
        if len(self.units) != len(self.channels):
            raise InputError(describe("number of units", len(self.units), [len(self.channels)]))
        if self.signatures is not None and self.signatures.feature_names != self.feature_names:
            raise InputError(
                describe("signature features", "a different feature set", "the reference's")
            )
        description = self.description  # validates the description (cached)
        if description is not None and description.name != self.machine:
            raise MachineError(
                describe(
                    "name in the reference's machine description", description.name, [self.machine]
                )
            )
        object.__setattr__(self, "features", feats)
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "units", tuple(self.units))

    # --------------------------------------------------------------- build
    @classmethod
    def build(
        cls,
        table: StepTable,
        machine_description: Mapping[str, Any] | None = None,
        channels: Sequence[str] | None = None,
        signatures: SignatureSet | None = None,
        settings: DetectionSettings | None = None,
        sources: Sequence[str] = (),
        sequence: Sequence[Mapping[str, Any]] = (),
        localisation: LocalisationSettings | None = None,
        cycle_recording: npt.ArrayLike | None = None,
    ) -> ReferenceModel:
        """Build a reference from the step table of leak-free cycles.

        Parameters
        ----------
        table : StepTable
            Leak-free cycles; at least :data:`MIN_REFERENCE_CYCLES`.
        machine_description : mapping, optional
            The machine description (TOML mapping, ``MachineDescription.raw``).
        channels : sequence of str, optional
            Analog channels to keep (all of the table's by default; empty for the
            PLC's digital signals only).
        signatures : SignatureSet, optional
            Leak signatures; restricted to this reference's features.
        settings : DetectionSettings, optional
            Detector tuning.
        sources : sequence of str
            Names of the recordings used.
        sequence : sequence of mapping
            The PLC step sequence (see :attr:`sequence`).
        localisation : LocalisationSettings, optional
            Tuning of leak location and sizing.
        cycle_recording : array_like of int, shape (n_cycles,), optional
            Recording (index in ``sources``) of each cycle of ``table``.

        Returns
        -------
        ReferenceModel
        """
        if table.n_cycles < MIN_REFERENCE_CYCLES:
            raise InputError(
                describe(
                    "number of complete leak-free reference cycles",
                    table.n_cycles,
                    f">= {MIN_REFERENCE_CYCLES}",
                )
            )
        if channels is not None:
            table = table.select(list(channels))
        band_mean = band_std = None
        if table.traces is not None and table.channels:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # samples no cycle reaches
                band_mean = np.nanmean(table.traces, axis=0)
                band_std = np.nanstd(table.traces, axis=0, ddof=1)
        supply = float("nan")
        if "P_In" in table.channels:
            supply = float(np.mean(table.summaries[:, :, table.channels.index("P_In"), 0]))
        names = table.feature_names()
        return cls(
            machine=table.machine,
            machine_description=dict(machine_description or {}),
            channels=table.channels,
            units=table.units,
            n_steps=table.n_steps,
            features=table.features(),
            band_mean=band_mean,
            band_std=band_std,
            trace_offsets=table.trace_offsets if band_mean is not None else None,
            trace_rate_hz=table.trace_rate_hz,
            supply_pressure=supply,
            signatures=None if signatures is None else signatures.select(names),
            settings=settings or DetectionSettings(),
            sources=tuple(sources),
            sequence=tuple(dict(step) for step in sequence),
            localisation=localisation or LocalisationSettings(),
            cycle_recording=None if cycle_recording is None else np.asarray(cycle_recording),
        )

    # ----------------------------------------------------------- derived
    @property
    def n_cycles(self) -> int:
        """Number of reference cycles."""
        return int(self.features.shape[0])

    @property
    def feature_names(self) -> tuple[str, ...]:
        """Names of the per-cycle features."""
        return feature_names(self.channels, self.n_steps)

    @property
    def feature_units(self) -> tuple[str, ...]:
        """SI unit of each feature."""
        units = ["s"] * self.n_steps
        for unit in self.units:
            units.extend([unit] * (3 * self.n_steps))
        return tuple(units)

    @cached_property
    def description(self) -> MachineDescription | None:
        """The machine description, parsed and validated; None when there is none."""
        if not self.machine_description:
            return None
        return parse_description(
            self.machine_description, f"machine description of reference {self.machine!r}"
        )

    @cached_property
    def fault_screens(self) -> dict[tuple[str, str, float], FloatArray | None]:
        """Screening simulations of fault hypotheses, ``(kind, location, size) ->
        feature change`` (:func:`pneufdd.diagnosis.localisation.faults.fit_faults`).

        They do not depend on the run (the twin's common seed), so they are kept for
        this reference's lifetime in memory: one set per reference, never saved.
        """
        return {}

    def leak_effects(self, simulation_cycles: int = 2, threads: int = 1) -> LeakEffectModel | None:
        """The leak-effect model of this machine and sensor set; None without signatures.

        Its signatures are :attr:`signatures`; its simulations run the digital twin of
        :attr:`description` (none without a description or a PLC sequence), on up to
        ``threads`` threads at once.
        """
        if self.signatures is None:
            return None
        sequence = sequence_from_records(self.sequence) if self.sequence else ()
        return LeakEffectModel.from_description(
            self.signatures,
            self.description,
            sequence,
            self.channels,
            simulation_cycles,
            threads=threads,
        )

    @cached_property
    def detector(self) -> CycleDistanceDetector:
        """The per-cycle statistic fitted on the reference cycles (deterministic)."""
        floor = np.array(
            [
                max(feature_floor(u), self.settings.quantum(name.split(".")[0]))
                for name, u in zip(self.feature_names, self.feature_units, strict=True)
            ]
        )
        return CycleDistanceDetector(
            n_nuisance=self.settings.n_nuisance,
            false_alarm_rate=self.settings.false_alarm_rate,
            scale_floor=floor,
            run_statistic=self.settings.run_statistic,
            run_correlation=self.settings.run_correlation,
        ).fit(self.features, groups=self.cycle_recording)

    def band_detector(self, channel: str | None = None) -> BandDetector | None:
        """The band detector of eq. 5.21 over all channels, or over one channel."""
        if self.band_mean is None or self.band_std is None:
            return None
        floor = np.array(
            [
                max(feature_floor(u), self.settings.quantum(c))
                for c, u in zip(self.channels, self.units, strict=True)
            ]
        )[:, None]
        floored = np.maximum(self.band_std, floor)
        if channel is None:
            mean, std = self.band_mean.ravel(), floored.ravel()
        else:
            i = self.channels.index(channel)
            mean, std = self.band_mean[i], floored[i]
        return BandDetector.from_statistics(
            mean,
            std,
            eps=self.settings.band_eps,
            alarm_fraction=self.settings.band_alarm_fraction,
            min_std=0.0,
        )

    def with_signatures(self, signatures: SignatureSet | None) -> ReferenceModel:
        """A copy with ``signatures`` (restricted to this reference's features)."""
        return replace(
            self, signatures=None if signatures is None else signatures.select(self.feature_names)
        )
