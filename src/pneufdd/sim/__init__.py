"""The digital twin: machine description (TOML), PLC sequence, compiled integrator, sensors.

>>> from pneufdd.sim import builtin_machines
>>> builtin_machines()
('carton-sorter', 'festo-dsd', 'press-fit-cell')
"""

from __future__ import annotations

from pneufdd.sim.description import MachineDescription, parse_description
from pneufdd.sim.leaks import Leak, LeakSpec, parse_leak_size
from pneufdd.sim.loading import builtin_machines, load_machine
from pneufdd.sim.result import SimulationResult, Stroke
from pneufdd.sim.simulate import (
    SIMULATOR_VERSION,
    MachineStalledError,
    as_exported,
    run_simulation,
    simulate,
)
from pneufdd.sim.variation import machine_to_toml, vary_machine, write_machine

__all__ = [
    "SIMULATOR_VERSION",
    "Leak",
    "LeakSpec",
    "MachineDescription",
    "MachineStalledError",
    "SimulationResult",
    "Stroke",
    "as_exported",
    "builtin_machines",
    "load_machine",
    "machine_to_toml",
    "parse_description",
    "parse_leak_size",
    "run_simulation",
    "simulate",
    "vary_machine",
    "write_machine",
]
