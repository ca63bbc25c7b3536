"""The lower-level simulation result (python-control style): true states plus the recording."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from pneufdd.recording import Recording
from pneufdd.sim.description import MachineDescription
from pneufdd.sim.leaks import LeakSpec

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["SimulatedStroke", "SimulationResult"]


@dataclass(frozen=True)
class SimulatedStroke:
    """One piston motion: leaving one end stop until arriving at the other.

    The start is the start of *sustained* travel, the "start-up of the acceleration
    curve" that section 3.3 uses to end the positioning time: the last breakaway
    after which the piston travelled 0.2 mm without sticking again. With F_cf > F_sf
    (section 4.2.3) a piston often creeps by stick-slip for some milliseconds
    (micro-slips of micrometres, re-sticking in between) before it moves off; that
    creep belongs to the positioning time and is kept in ``first_motion``.

    Attributes
    ----------
    actuator : str
        Actuator id.
    direction : int
        +1 extend (towards the B end), -1 retract.
    start : float
        Start of sustained travel [s].
    end : float
        Time it reached the end stop [s] (only completed strokes are listed).
    cycle : int
        Cycle index (0-based) in which the first motion (``first_motion``) occurred.
    first_motion : float
        Time of the first breakaway from the end stop, including stick-slip creep
        before ``start`` (``first_motion <= start``) [s].
    """

    actuator: str
    direction: int
    start: float
    end: float
    cycle: int
    first_motion: float

    @property
    def duration(self) -> float:
        """Stroke time t_s of section 3.3 [s]."""
        return self.end - self.start


@dataclass
class SimulationResult:
    """Everything one simulation produced.

    Attributes
    ----------
    time : ndarray
        Time of each output sample [s].
    outputs : dict of str to ndarray
        True internal states at ``time`` (SI): ``p_<node>`` pressures [Pa]
        (``reservoir``, ``manifold``, ``<ACT>_A``/``_B``), ``x_<ACT>`` positions [m],
        ``mdot_in_<ACT>_A`` flow from the manifold into a line [kg/s],
        ``mdot_exhaust_<ACT>_A`` flow out through the exhaust path [kg/s],
        ``mdot_leak_<loc>`` leak flows [kg/s], ``mdot_supply_line`` (through the
        ``Q_In`` meter), ``mdot_regulator``, ``mdot_vacuum`` [kg/s], ``stored_mass``
        (reservoir + manifold + chambers) [kg], cumulative masses ``mass_supplied``
        (through the supply line), ``mass_regulator``, ``mass_exhausted``,
        ``mass_leaked``, ``mass_vacuum`` [kg], ``vacuum_level`` [-], ``step`` (0-based);
        and, not on the time base: ``step_start`` (cycles x steps) [s] and per
        actuator ``stroke_start_<ACT>`` (sustained travel, see :class:`SimulatedStroke`),
        ``stroke_end_<ACT>``, ``stroke_first_motion_<ACT>`` [s],
        ``stroke_direction_<ACT>`` (+1 extend, -1 retract).
    step_start : ndarray
        Start time of every step, shape (cycles, steps) [s].
    strokes : list of SimulatedStroke
        Every piston motion.
    recording : Recording
        What the rig's sensors and PLC I/O record.
    machine : MachineDescription
        The simulated machine.
    leaks : list of LeakSpec
        Ground truth of the injected leaks.
    substeps : int
        Integration sub-steps taken.
    """

    time: npt.NDArray[np.float64]
    outputs: dict[str, npt.NDArray[Any]]
    step_start: npt.NDArray[np.float64]
    strokes: list[SimulatedStroke]
    recording: Recording
    machine: MachineDescription
    leaks: list[LeakSpec]
    substeps: int = 0
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def cycle_start(self) -> npt.NDArray[np.float64]:
        """Start time of each cycle (its first step) [s]."""
        return np.asarray(self.step_start[:, 0], dtype=np.float64)

    def strokes_of(self, actuator: str, direction: int | None = None) -> list[SimulatedStroke]:
        """Strokes of one actuator, optionally only one direction (+1 extend, -1 retract)."""
        return [
            s
            for s in self.strokes
            if s.actuator == actuator and (direction is None or s.direction == direction)
        ]

    def to_pandas(self) -> pd.DataFrame:
        """The internal time series as a DataFrame indexed by time [s] (``time_s``)."""
        import pandas as pd

        series = {k: v for k, v in self.outputs.items() if v.ndim == 1 and v.size == self.time.size}
        return pd.DataFrame(series, index=pd.Index(self.time, name="time_s"))
