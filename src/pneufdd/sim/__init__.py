"""The digital twin: machine description (TOML), PLC sequence, compiled integrator, sensors.

>>> from pneufdd.sim import builtin_machines
>>> builtin_machines()
('carton-sorter', 'festo-dsd', 'press-fit-cell')

May import: :mod:`pneufdd.physics`, :mod:`pneufdd.recording` and the shared helpers.
"""

from __future__ import annotations

import sys
import types
from typing import TYPE_CHECKING, Any

from pneufdd._lazy import lazy_getattr

if TYPE_CHECKING:
    from pneufdd.sim.description import MachineDescription, parse_description
    from pneufdd.sim.leaks import Leak, LeakSpec, parse_leak_size
    from pneufdd.sim.loading import builtin_machines, load_machine
    from pneufdd.sim.result import SimulatedStroke, SimulationResult
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
    "SimulatedStroke",
    "SimulationResult",
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

# Imported on first use, so that ``import pneufdd`` (and the CLI's --help) does not
# load numba and compile kernels for code that never evaluates physics.
_LAZY = {
    "MachineDescription": "pneufdd.sim.description",
    "parse_description": "pneufdd.sim.description",
    "Leak": "pneufdd.sim.leaks",
    "LeakSpec": "pneufdd.sim.leaks",
    "parse_leak_size": "pneufdd.sim.leaks",
    "builtin_machines": "pneufdd.sim.loading",
    "load_machine": "pneufdd.sim.loading",
    "SimulationResult": "pneufdd.sim.result",
    "SimulatedStroke": "pneufdd.sim.result",
    "SIMULATOR_VERSION": "pneufdd.sim.simulate",
    "MachineStalledError": "pneufdd.sim.simulate",
    "as_exported": "pneufdd.sim.simulate",
    "run_simulation": "pneufdd.sim.simulate",
    "simulate": "pneufdd.sim.simulate",
    "machine_to_toml": "pneufdd.sim.variation",
    "vary_machine": "pneufdd.sim.variation",
    "write_machine": "pneufdd.sim.variation",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


class _Package(types.ModuleType):
    """Keeps the package's ``simulate`` the function when its submodule is imported.

    Importing ``pneufdd.sim.simulate`` binds the submodule to the package attribute
    of the same name; the eager ``from pneufdd.sim.simulate import simulate`` used to
    rebind it to the function, which the lazy import has to do here.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _LAZY and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
