"""Twin-in-the-loop calibration of a machine description to a plant's leak-free recordings.

Objective 5 of section 1.2: the model must explain the machine. The evidence is what
the plant's sensors and PLC give per step, averaged over the recordings' complete
cycles (:class:`Evidence`): the supply air (``Q_In`` integrated over the step, what a
swept volume costs), the step duration (what valve and throttle capacities and
friction allow), the mean supply pressure (the supply path) and, where fitted, the
mean line pressures. The twin (:func:`pneufdd.sim.simulate.run_simulation`) is run
for the candidate description and the misfit, weighted by the measurement
uncertainty, plus a Gaussian prior on every parameter (maximum a posteriori), is
minimised with ``scipy.optimize.least_squares``.

Parameters (:class:`Parameter`) are multipliers in log space (the supply set point
is an offset in psi): per actuator its volume (bore and rod by the square root, dead
volumes and tube length by the factor: the air per stroke), valve Cv, throttle
(meter-out) Cv and, with a line pressure sensor, friction; the supply set point and
line Cv; a vacuum nozzle. Uncertainties come from the Jacobian at the optimum; a
parameter whose posterior standard deviation is more than ``informed_ratio`` of its
prior's is *not informed* by the data: it is put back at its prior value, the others
are refitted, and the result says so.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares, lsq_linear

from pneufdd.array_types import FloatArray
from pneufdd.calibration.friction import FrictionIdentification, identify_friction
from pneufdd.calibration.gaps import gap_checked
from pneufdd.calibration.parameters import Parameter, actuator_table, machine_parameters
from pneufdd.calibration.valve import PathIdentification, identify_paths
from pneufdd.errors import InputError, NoCompleteCycleError, describe
from pneufdd.parallel import resolve_threads, thread_map
from pneufdd.recording.model import Recording
from pneufdd.signals.segmentation import plc_sequence, segment
from pneufdd.sim import MachineDescription, load_machine
from pneufdd.sim.result import SimulationResult
from pneufdd.sim.simulate import (
    ANALOG_RATE_HZ,
    RUN_END_IDLE_S,
    MachineStalledError,
    run_simulation,
)

__all__ = [
    "CalibrationResult",
    "Evidence",
    "Parameter",
    "calibrate_machine",
    "machine_parameters",
    "measure_evidence",
    "simulate_evidence",
    "volume_start",
]


AIR_REL_SIGMA = 0.02
"""Relative uncertainty of a step's mean supply air (meter span error, averaging) [-]."""
AIR_ABS_SIGMA_FRACTION = 0.005
"""Floor of that uncertainty, as a fraction of the mean air per step [-]."""
DURATION_SIGMA_S = 0.005
"""Uncertainty of a step's mean duration: the PLC scan and 100 Hz sampling [s]."""
PRESSURE_SIGMA_PA = 1500.0
"""Uncertainty of a step's mean pressure: 12-bit over 10 bar plus gauge error [Pa]."""
DIFF_STEP = 0.25
"""Finite-difference step of the Jacobian, in prior standard deviations [-]."""
SIM_CYCLES = 4
"""Twin cycles per evaluation; the first (start-up from rest) is not compared."""
FIT_FTOL = 1e-3
"""A least-squares run stops when an iteration lowers the misfit by less than this
fraction of it [-] (``scipy.optimize.least_squares`` ``ftol``; its default 1e-8 made
the second fit of a drafted festo-dsd take 12 Jacobians for the last 0.2 % of its
misfit, the twin's 1 ms step timing shrinking the trust region, issue 35)."""


@dataclass(frozen=True)
class Evidence:
    """Per-step means over complete cycles (one entry per step of the sequence).

    Attributes
    ----------
    supply_air_kg : ndarray
        ``Q_In`` integrated over the step [kg] (NaN without ``Q_In``).
    duration_s : ndarray
        Step duration [s].
    supply_pressure_pa : ndarray
        Mean ``P_In`` [Pa] (NaN without ``P_In``).
    line_pressure_pa : dict of str to ndarray
        Mean of each line pressure channel ``P_<ACT>_A/B`` [Pa].
    cycles : int
        Complete cycles averaged.
    cycles_skipped : tuple of (int, int, str)
        Cycles the gap rule left out (docs/data-quality.md): the recording's place in
        the list (0-based), the cycle's index in it and the channel with the gap.
    gaps_repaired : int
        Short gaps (up to 0.05 s) interpolated, over all recordings and channels.
    """

    supply_air_kg: FloatArray
    duration_s: FloatArray
    supply_pressure_pa: FloatArray
    line_pressure_pa: dict[str, FloatArray]
    cycles: int
    cycles_skipped: tuple[tuple[int, int, str], ...] = field(default_factory=tuple)
    gaps_repaired: int = 0

    def gap_line(self, names: Sequence[str]) -> str | None:
        """One line on what the gap rule did (None when the data had no gaps)."""
        if not self.cycles_skipped and not self.gaps_repaired:
            return None
        where = sorted({f"{names[k]} cycle {i} ({c})" for k, i, c in self.cycles_skipped})
        return (
            f"data gaps: {len(self.cycles_skipped)} cycle(s) skipped"
            + (f" ({', '.join(where)})" if where else "")
            + f", {self.gaps_repaired} short gap(s) interpolated (docs/data-quality.md)"
        )


def _window_sums(
    time_t0: float, rate: float, values: FloatArray, start: FloatArray, end: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Sum [value x s] and mean of ``values`` over each [start, end)."""
    csum = np.concatenate([[0.0], np.cumsum(np.nan_to_num(values))])
    i0 = np.clip(np.round((start - time_t0) * rate).astype(np.int64), 0, values.size)
    i1 = np.clip(np.round((end - time_t0) * rate).astype(np.int64), 0, values.size)
    i1 = np.maximum(i1, i0 + 1).clip(max=values.size)
    total = (csum[i1] - csum[i0]) / rate
    mean = (csum[i1] - csum[i0]) / np.maximum(i1 - i0, 1)
    return total, mean


def _evidence_from_windows(
    recordings: Sequence[Recording],
    windows: Sequence[tuple[FloatArray, FloatArray]],
    line_channels: Sequence[str],
) -> Evidence:
    """Per-step evidence of ``recordings`` over their step ``windows`` (cycles x steps)."""
    n_steps = windows[0][0].shape[1]
    air: list[FloatArray] = []
    dur: list[FloatArray] = []
    pin: list[FloatArray] = []
    lines: dict[str, list[FloatArray]] = {c: [] for c in line_channels}
    for rec, (start, end) in zip(recordings, windows, strict=True):
        dur.append(end - start)
        for name, sink in (("Q_In", air), ("P_In", pin)):
            if name in rec.channels:
                info = rec.info(name)
                total, mean = _window_sums(
                    info.t0, info.rate_hz, np.asarray(info.values, np.float64), start, end
                )
                sink.append(total if name == "Q_In" else mean)
            else:
                sink.append(np.full(start.shape, np.nan))
        for name in line_channels:
            info = rec.info(name)
            _, mean = _window_sums(
                info.t0, info.rate_hz, np.asarray(info.values, np.float64), start, end
            )
            lines[name].append(mean)
    cycles = sum(w[0].shape[0] for w in windows)
    if cycles == 0:  # pragma: no cover - callers check
        raise NoCompleteCycleError("no complete cycle to calibrate on")

    def per_step(chunks: list[FloatArray]) -> FloatArray:
        stacked = np.concatenate(chunks, axis=0).reshape(-1, n_steps)
        out: FloatArray = np.mean(stacked, axis=0)
        return out

    return Evidence(
        supply_air_kg=per_step(air),
        duration_s=per_step(dur),
        supply_pressure_pa=per_step(pin),
        line_pressure_pa={k: per_step(v) for k, v in lines.items()},
        cycles=cycles,
    )


def measure_evidence(
    recordings: Sequence[Recording],
    machine: MachineDescription,
    line_channels: Sequence[str] = (),
    names: Sequence[str] | None = None,
) -> Evidence:
    """Per-step evidence of leak-free recordings, segmented with ``machine``'s sequence.

    The first complete cycle of a recording with three or more is left out (the twin's
    first cycle starts from rest, a plant's may follow a stop). The gap rule of
    ``diagnose`` applies (:func:`pneufdd.calibration.gaps.gap_checked`): NaN, infinite
    or out-of-range samples are interpolated over up to 0.05 s, and a cycle a longer
    gap touches is left out and reported (``Evidence.cycles_skipped``).

    Parameters
    ----------
    recordings : sequence of Recording
        Leak-free recordings.
    machine : MachineDescription
        Gives the sequence.
    line_channels : sequence of str
        Line pressure channels to average per step.
    names : sequence of str, optional
        The recordings' names (files) for messages; default ``recording 1``, ...

    Raises
    ------
    NoCompleteCycleError
        If no recording holds a complete cycle of the sequence, or a recording has
        fewer than half of its complete cycles free of long gaps.
    """
    return _measure(recordings, machine, line_channels, names)[0]


def _measure(
    recordings: Sequence[Recording],
    machine: MachineDescription,
    line_channels: Sequence[str],
    names: Sequence[str] | None,
) -> tuple[Evidence, list[Recording]]:
    """:func:`measure_evidence`, and the recordings whose gaps are all repaired."""
    sequence = plc_sequence(machine=machine)
    whole: list[Recording] = []
    windows = []
    kept: list[Recording] = []
    skipped: list[tuple[int, int, str]] = []
    repaired_gaps = 0
    for k, raw in enumerate(recordings):
        complete = list(segment(raw, sequence).complete)
        if not complete:
            continue
        where = names[k] if names is not None else f"recording {k + 1}"
        rec, usable, report = gap_checked(raw, complete, line_channels, where)
        skipped += [(k, index, channel) for index, channel in report.skipped]
        repaired_gaps += report.repaired_gaps
        if not report.skipped:
            whole.append(rec)
        # the start-up cycle is left out as without gaps: the result is the one of the
        # same recording without its damaged cycles
        first = 1 if len(complete) >= 3 else 0
        cycles = [c for i, c in enumerate(complete) if usable[i] and i >= first]
        if not cycles:
            continue
        start = np.array([[s.start_s for s in c.steps] for c in cycles])
        end = np.array([[s.end_s for s in c.steps] for c in cycles])
        if start.shape[1] != len(machine.steps):
            raise InputError(
                describe(
                    f"steps per cycle in recording {k + 1}", start.shape[1], str(len(machine.steps))
                )
            )
        windows.append((start, end))
        kept.append(rec)
    if not windows:
        raise NoCompleteCycleError(
            describe("complete cycles of the machine's sequence in the recordings", 0, ">= 1")
        )
    evidence = _evidence_from_windows(kept, windows, line_channels)
    evidence = dataclasses.replace(
        evidence, cycles_skipped=tuple(skipped), gaps_repaired=repaired_gaps
    )
    return evidence, whole


def simulate_evidence(
    machine: MachineDescription | dict[str, Any],
    line_channels: Sequence[str] = (),
    seed: int = 0,
    cycles: int = SIM_CYCLES,
) -> Evidence:
    """The twin's evidence: exact step times of ``cycles`` cycles, the first left out.

    Only the channels the evidence reads are recorded (``P_In``, ``Q_In`` and the line
    pressures): the others cost their sensor models and give nothing here, and every
    recorded channel is the one a run recording them all gives
    (:func:`~pneufdd.sim.simulate.run_simulation`).
    """
    desc = load_machine(machine)
    wanted = {"P_In", "Q_In", *line_channels}
    channels = [s.channel for s in desc.sensors if s.channel in wanted]
    result = run_simulation(desc, cycles=cycles, seed=seed, keep_outputs=False, channels=channels)
    return _evidence_from_windows([result.recording], [_step_windows(result)], line_channels)


def _step_windows(result: SimulationResult) -> tuple[FloatArray, FloatArray]:
    """Start and end of every step of a twin run [s], cycles x steps, the first cycle
    (started from rest) left out when there are more."""
    starts = result.step_start
    ends = np.r_[starts.ravel()[1:], result.recording.duration - RUN_END_IDLE_S].reshape(
        starts.shape
    )
    skip = 1 if starts.shape[0] > 1 else 0
    return starts[skip:], ends[skip:]


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter's calibration: its value, standard error and whether data informed it."""

    name: str
    value: float
    std: float
    prior_sigma: float
    informed: bool
    unit: str

    def describe(self) -> str:
        """``x 1.123 +- 4.5 %`` or ``+1.20 +- 0.30 psi``; ``(prior)`` when uninformed."""
        if self.unit == "psi":
            text = f"{self.value:+.2f} +- {self.std:.2f} psi"
        else:
            text = f"x {math.exp(self.value):.3f} +- {100 * self.std:.1f} %"
        return text if self.informed else "left at prior (not informed by the data)"


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate_machine` found."""

    before: MachineDescription
    after: MachineDescription
    measured: Evidence
    simulated_before: Evidence
    simulated_after: Evidence
    estimates: tuple[ParameterEstimate, ...]
    evaluations: int
    cost_before: float
    cost_after: float
    friction: tuple[FrictionIdentification, ...] = ()
    paths: tuple[PathIdentification, ...] = ()

    def fit_line(self) -> str:
        """One line: the median misfits before and after."""
        f = self.fit_summary()
        return (
            f"median misfit over steps: supply air {f['air_error_pct_median_after']:.2f} % "
            f"(before {f['air_error_pct_median_before']:.2f} %), durations "
            f"{f['duration_error_ms_median_after']:.1f} ms "
            f"(before {f['duration_error_ms_median_before']:.1f} ms), P_In "
            f"{f['supply_pressure_error_mbar_median_after']:.1f} mbar "
            f"(before {f['supply_pressure_error_mbar_median_before']:.1f} mbar)"
        )

    def calibrated_description(self, sources: str) -> MachineDescription:
        """``after`` with its title stating what it was calibrated to and how well."""
        raw = copy.deepcopy(self.after.raw)
        title = str(raw["machine"].get("title", raw["machine"]["name"])).split(" | calibrated")[0]
        raw["machine"]["title"] = f"{title} | calibrated to {sources}; {self.fit_line()}"
        return load_machine(raw)

    def identification_lines(self) -> tuple[str, ...]:
        """One line per friction identified from strokes and per fill path from a line
        flow."""
        friction = tuple(
            f"{f.actuator} friction from its strokes (eqs. 4.15-4.16): {f.describe()}"
            for f in self.friction
        )
        return friction + tuple(
            f"{p.actuator} fill path from its line flow (section 4.2.1): {p.describe()}"
            for p in self.paths
        )

    @property
    def not_informed(self) -> tuple[str, ...]:
        """Parameters left at their prior."""
        return tuple(e.name for e in self.estimates if not e.informed)

    def weighted_misfit(self) -> dict[str, float]:
        """The weighted misfit (sum of squares, what the fit minimises without its
        prior) by evidence, before and after: ``air_before``, ``durations_after``, ..."""
        out: dict[str, float] = {}
        for label, sim in (("before", self.simulated_before), ("after", self.simulated_after)):
            for part, r in _residual_parts(self.measured, sim).items():
                out[f"{part}_{label}"] = float(np.dot(r, r))
        return out

    def fit_summary(self) -> dict[str, float]:
        """Median absolute misfits before and after (air in %, durations in ms, P_In in mbar)."""
        out: dict[str, float] = {}
        for label, sim in (("before", self.simulated_before), ("after", self.simulated_after)):
            m = self.measured
            air = 100 * np.abs(sim.supply_air_kg - m.supply_air_kg) / np.abs(m.supply_air_kg)
            out[f"air_error_pct_median_{label}"] = float(np.nanmedian(air))
            dur = 1e3 * np.abs(sim.duration_s - m.duration_s)
            out[f"duration_error_ms_median_{label}"] = float(np.nanmedian(dur))
            pin = 1e-2 * np.abs(sim.supply_pressure_pa - m.supply_pressure_pa)
            out[f"supply_pressure_error_mbar_median_{label}"] = float(np.nanmedian(pin))
        return out


def _air_scale(air: FloatArray) -> FloatArray:
    """Uncertainty of each step's air [kg]: :data:`AIR_REL_SIGMA` of it, with a floor of
    :data:`AIR_ABS_SIGMA_FRACTION` of the mean step's."""
    out: FloatArray = AIR_REL_SIGMA * np.abs(air) + AIR_ABS_SIGMA_FRACTION * float(
        np.mean(np.abs(air))
    )
    return out


def _residual_parts(measured: Evidence, sim: Evidence) -> dict[str, FloatArray]:
    """Weighted residuals by evidence: supply air, durations, P_In, line pressures."""
    parts: dict[str, FloatArray] = {}
    if np.all(np.isfinite(measured.supply_air_kg)):
        scale = _air_scale(measured.supply_air_kg)
        parts["air"] = (sim.supply_air_kg - measured.supply_air_kg) / scale
    parts["durations"] = (sim.duration_s - measured.duration_s) / DURATION_SIGMA_S
    if np.all(np.isfinite(measured.supply_pressure_pa)):
        parts["supply_pressure"] = (
            sim.supply_pressure_pa - measured.supply_pressure_pa
        ) / PRESSURE_SIGMA_PA
    lines = []
    for name, values in measured.line_pressure_pa.items():
        # the shape over the steps only: a line gauge's offset (up to 1.5 % of its
        # span, docs/plant-variation.md) is not the twin's to explain
        twin = sim.line_pressure_pa[name]
        lines.append(((twin - twin.mean()) - (values - values.mean())) / (2 * PRESSURE_SIGMA_PA))
    if lines:
        parts["line_pressures"] = np.concatenate(lines)
    return {k: np.nan_to_num(v, nan=0.0) for k, v in parts.items()}


def _residuals(measured: Evidence, sim: Evidence) -> FloatArray:
    out: FloatArray = np.concatenate(list(_residual_parts(measured, sim).values()))
    return out


def _air_per_actuator(machine: MachineDescription, seed: int) -> tuple[FloatArray, FloatArray]:
    """The twin's supply air per step and each actuator's share of it [kg].

    Returns the per-step supply air of :func:`simulate_evidence` (the first cycle left
    out) and, per step and actuator, the air that entered the actuator's chambers
    through its valve (``mdot_in`` of both lines), averaged over the same cycles.
    """
    result = run_simulation(machine, cycles=SIM_CYCLES, seed=seed, keep_outputs=True)
    window = _step_windows(result)
    supply = _evidence_from_windows([result.recording], [window], ()).supply_air_kg
    shares = []
    for a in machine.actuators:
        inflow = result.outputs[f"mdot_in_{a.id}_A"] + result.outputs[f"mdot_in_{a.id}_B"]
        total, _ = _window_sums(float(result.time[0]), ANALOG_RATE_HZ, inflow, *window)
        shares.append(np.mean(total, axis=0))
    return supply, np.stack(shares, axis=1)


def volume_start(
    machine: MachineDescription,
    params: Sequence[Parameter],
    measured: Evidence,
    seed: int = 0,
) -> FloatArray:
    """Starting values of the volume parameters from the air each step draws [log].

    An actuator's air per stroke is proportional to its swept and dead volumes, so
    the measured supply air per step is, to first order, the twin's air of the
    other consumers plus each actuator's simulated air times its volume factor:
    a bounded linear least-squares fit (:func:`scipy.optimize.lsq_linear`, steps
    weighted as in the calibration, with the calibration's prior linearised and
    factors within two prior standard deviations) gives those factors. A drafted
    description assumes one bore for all actuators (a festo-dsd DNC drafted at 20 mm
    is 32 mm); started there, the twin-in-the-loop fit left DNC at x 1.02.
    Parameters other than volumes start at 0 (the description); so do all without
    a supply flow meter.
    """
    start = np.zeros(len(params))
    if not np.all(np.isfinite(measured.supply_air_kg)):
        return start
    index = {p.name: k for k, p in enumerate(params)}
    supply, shares = _air_per_actuator(machine, seed)
    # (actuator, its volume parameter) for actuators that draw air in the twin
    used = [
        (i, index[f"{a.id}.volume"])
        for i, a in enumerate(machine.actuators)
        if f"{a.id}.volume" in index and np.any(shares[:, i] > 0)
    ]
    if not used:
        return start
    sigma = np.array([params[k].prior_sigma for _, k in used])
    scale = _air_scale(measured.supply_air_kg)
    share = shares[:, [i for i, _ in used]]
    rest = supply - share.sum(axis=1)
    # the calibration's prior, linearised: (factor - 1) / sigma ~ N(0, 1)
    factors = lsq_linear(
        np.vstack([share / scale[:, None], np.diag(1.0 / sigma)]),
        np.concatenate([(measured.supply_air_kg - rest) / scale, 1.0 / sigma]),
        bounds=(np.exp(-2.0 * sigma), np.exp(2.0 * sigma)),
    ).x
    for (_, k), f, sd in zip(used, factors, sigma, strict=True):
        start[k] = math.log(float(f)) / sd
    return start


def _applied(
    base: dict[str, Any], params: Sequence[Parameter], values: FloatArray
) -> dict[str, Any]:
    raw = copy.deepcopy(base)
    for p, v in zip(params, values, strict=True):
        p.apply(raw, float(v))
    return raw


def _line_pressure_channels(
    machine: MachineDescription, recordings: Sequence[Recording], fit_line_pressures: bool
) -> tuple[str, ...]:
    """The line pressure channels every recording holds (none unless they are fitted)."""
    return tuple(
        s.channel
        for s in machine.sensors
        if fit_line_pressures
        and s.kind == "pressure"
        and s.location != "supply"
        and all(s.channel in r.channels for r in recordings)
    )


def _with_friction(
    raw: dict[str, Any], identified: Mapping[str, FrictionIdentification]
) -> dict[str, Any]:
    """A copy of the description ``raw`` with the friction identified from strokes."""
    base = copy.deepcopy(raw)
    for ident, found in identified.items():
        table = actuator_table(base, ident)
        table["static_friction_n"] = found.static_friction_n
        table["coulomb_friction_n"] = found.coulomb_friction_n
        table["viscous_friction_n_s_m"] = found.viscous_friction_n_s_m
    return base


class _TwinFit:
    """The maximum a posteriori fit of the parameters with the twin in the loop.

    The unknowns ``z`` are the parameters in prior standard deviations; the residual
    is the weighted misfit of the twin's evidence (:func:`_residuals`) followed by
    ``z`` (the Gaussian prior). Twin runs are cached by parameter values and counted
    in :attr:`evaluations`; a description the twin cannot run gets a large residual.
    """

    def __init__(
        self,
        base: dict[str, Any],
        params: Sequence[Parameter],
        measured: Evidence,
        lines: tuple[str, ...],
        seed: int,
        max_evaluations: int,
        progress: Callable[[str, int, int], None] | None,
        threads: int = 1,
    ) -> None:
        self.base = base
        self.threads = threads
        self.params = params
        self.measured = measured
        self.lines = lines
        self.seed = seed
        self.max_evaluations = max_evaluations
        self.progress = progress
        self.sigma = np.array([p.prior_sigma for p in params])
        self.evaluations = 0
        self._cache: dict[bytes, FloatArray] = {}

    def _values(self, z: FloatArray, free: npt.NDArray[np.bool_]) -> FloatArray:
        """Every parameter [its unit] for the ``free`` ones at ``z`` [prior sigmas]."""
        values = np.zeros(len(self.params))
        values[free] = z * self.sigma[free]
        return values

    def _misfit(self, values: FloatArray) -> FloatArray:
        """The weighted misfit of one twin run at ``values`` (no cache, no count) [-]."""
        try:
            sim = simulate_evidence(_applied(self.base, self.params, values), self.lines, self.seed)
            return _residuals(self.measured, sim)
        except (MachineStalledError, InputError):
            n = _residuals(self.measured, simulate_evidence(self.base, self.lines, self.seed)).size
            return np.full(n, 1e3)

    def _evaluate(self, points: Sequence[FloatArray]) -> None:
        """Run the twin at every point not yet cached, on :attr:`threads` threads.

        The twin's compiled kernel releases the GIL, so the runs of one Jacobian
        overlap on the cores; each run is a deterministic function of its point (one
        seed: common random numbers), so the result does not depend on the threads.
        """
        todo: dict[bytes, FloatArray] = {}
        for values in points:
            key = values.tobytes()
            if key not in self._cache and key not in todo:
                todo[key] = values
        if not todo:
            return
        misfits = thread_map(self._misfit, list(todo.values()), self.threads)
        for key, misfit in zip(todo, misfits, strict=True):
            self._cache[key] = misfit
            self.evaluations += 1
            if self.progress is not None:
                self.progress("calibrating (twin runs)", self.evaluations, 0)

    def residual(self, z: FloatArray, free: npt.NDArray[np.bool_]) -> FloatArray:
        """Weighted misfit and prior term of the ``free`` parameters at ``z`` [-]."""
        values = self._values(z, free)
        self._evaluate([values])
        out: FloatArray = np.concatenate([self._cache[values.tobytes()], z])
        return out

    def jacobian(self, z: FloatArray, free: npt.NDArray[np.bool_]) -> FloatArray:
        """Forward-difference Jacobian of :meth:`residual` [-]."""
        # forward differences of DIFF_STEP prior sigmas: large enough to see through
        # the twin's 1 ms step timing, small against the prior
        steps = [z + DIFF_STEP * np.eye(z.size)[k] for k in range(z.size)]
        self._evaluate([self._values(p, free) for p in [z, *steps]])
        r0 = self.residual(z, free)
        columns = [(self.residual(p, free) - r0) / DIFF_STEP for p in steps]
        out: FloatArray = np.stack(columns, axis=1)
        return out

    def fit(
        self, free: npt.NDArray[np.bool_], start: FloatArray
    ) -> tuple[FloatArray, FloatArray, float]:
        """Fit the ``free`` parameters from ``start``.

        Returns every parameter [prior sigmas] (0 when not free), its standard error
        [prior sigmas] (1 when not free) and the misfit per degree of freedom [-].
        """
        sol = least_squares(
            self.residual,
            start[free],
            jac=self.jacobian,
            args=(free,),
            method="trf",
            max_nfev=self.max_evaluations,
            x_scale=1.0,
            ftol=FIT_FTOL,
        )
        jac = np.asarray(sol.jac)
        dof = max(jac.shape[0] - jac.shape[1], 1)
        chi2 = 2.0 * float(sol.cost) / dof
        cov = np.linalg.pinv(jac.T @ jac)
        z = np.zeros(len(self.params))
        z[free] = sol.x
        std = np.full(len(self.params), 1.0)  # in prior units: uninformed = 1
        std[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        return z, std, chi2

    def fit_informed(
        self, start: FloatArray, informed_ratio: float
    ) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
        """Fit every parameter, then refit only those the data informed.

        Returns the parameters and their standard errors [prior sigmas] and which are
        informed; the others are left at their prior (0, standard error 1).
        """
        z, std, chi2 = self.fit(np.ones(len(self.params), dtype=bool), start)
        # informed: the data (not the prior) set it; judged on the posterior of the
        # weighted problem, before any inflation for misfit
        informed = std <= informed_ratio
        if not np.all(informed) and np.any(informed):
            z, std_refit, chi2 = self.fit(informed, np.where(informed, z, 0.0))
            std = np.where(informed, std_refit, 1.0)
        elif not np.any(informed):
            z = np.zeros(len(self.params))
        z = np.where(informed, z, 0.0)
        # reported standard errors: inflated by the misfit where the twin cannot
        # explain the data to within the measurement uncertainty
        std = np.where(informed, std * math.sqrt(max(1.0, chi2)), std)
        return z, std, informed


def _cost(measured: Evidence, sim: Evidence) -> float:
    """Weighted misfit (sum of squares) of the twin's evidence [-]."""
    r = _residuals(measured, sim)
    return float(np.dot(r, r))


def calibrate_machine(
    machine: MachineDescription | str | dict[str, Any],
    recordings: Sequence[Recording],
    fit_line_pressures: bool = True,
    informed_ratio: float = 0.7,
    max_evaluations: int = 40,
    seed: int = 0,
    progress: Callable[[str, int, int], None] | None = None,
    names: Sequence[str] | None = None,
    threads: int | None = None,
) -> CalibrationResult:
    """Calibrate ``machine`` to leak-free ``recordings`` with the twin in the loop.

    Parameters
    ----------
    machine : MachineDescription, str or dict
        The starting description (a drafted one, or the catalogue's).
    recordings : sequence of Recording
        Leak-free recordings of the plant (channels as the description names them).
    fit_line_pressures : bool
        Use the line pressure sensors' per-step means and fit friction: identified
        from the strokes where a position is recorded as well
        (:func:`pneufdd.calibration.friction.identify_friction`, eqs. 4.15-4.16),
        else with the twin in the loop.
    informed_ratio : float
        A parameter whose posterior standard deviation exceeds this fraction of its
        prior's is not informed by the data and is left at its prior [-].
    max_evaluations : int
        Most residual evaluations per least-squares run (the Jacobian's twin runs
        come on top).
    seed : int
        Seed of the twin (the same for every evaluation: common random numbers).
    progress : callable, optional
        ``progress(task, done, total)``.
    names : sequence of str, optional
        The recordings' names (files) for messages.
    threads : int, optional
        Twin runs of a Jacobian at once (the compiled kernel releases the GIL);
        None: every core this process may use. The result does not depend on it.

    Returns
    -------
    CalibrationResult

    Notes
    -----
    The gap rule of ``diagnose`` applies (docs/data-quality.md): short gaps (NaN,
    infinite or out-of-range samples up to 0.05 s) are interpolated; a cycle a longer
    gap touches is left out of the evidence and reported (``measured.cycles_skipped``),
    and a recording with such a gap is left out of the identifications (friction,
    fill paths), which work on whole strokes.
    """
    before = load_machine(machine)
    lines = _line_pressure_channels(before, recordings, fit_line_pressures)
    measured, whole = _measure(recordings, before, lines, names)
    identified = identify_friction(before, whole) if fit_line_pressures else {}
    paths = identify_paths(before, whole) if fit_line_pressures else {}
    params = machine_parameters(
        before, lines, tuple(identified), {k: p.path_cv for k, p in paths.items()}
    )
    base = _with_friction(before.raw, identified)
    twin = _TwinFit(
        base, params, measured, lines, seed, max_evaluations, progress, resolve_threads(threads)
    )
    start = load_machine(_applied(base, params, np.zeros(len(params))))
    z, std, informed = twin.fit_informed(
        volume_start(start, params, measured, seed), informed_ratio
    )
    values = z * twin.sigma
    after = load_machine(_applied(base, params, values))
    sim_before = simulate_evidence(before, lines, seed)
    sim_after = simulate_evidence(after, lines, seed)
    estimates = tuple(
        ParameterEstimate(
            p.name, float(v), float(s * p.prior_sigma), p.prior_sigma, bool(i), p.unit
        )
        for p, v, s, i in zip(params, values, std, informed, strict=True)
    )
    return CalibrationResult(
        before=before,
        after=after,
        measured=measured,
        simulated_before=sim_before,
        simulated_after=sim_after,
        estimates=estimates,
        evaluations=twin.evaluations,
        cost_before=_cost(measured, sim_before),
        cost_after=_cost(measured, sim_after),
        friction=tuple(identified.values()),
        paths=tuple(paths.values()),
    )
