"""The standstill test run on the twin: the plan's sequence on a plant, leaks and all.

:func:`simulate_standstill` runs the plan's PLC sequence
(:func:`pneufdd.standstill.program.twin_description`) with the physics of a plant (a
description, or a plant drawn from one by :func:`pneufdd.sim.vary_machine`). In the
``flow`` mode the whole sequence runs once. In the ``decay`` mode every state runs on
its own for two cycles, the second with the supply shut-off valve closed
(``run_simulation(..., supply_open=(True, False))``): the state settles with the
supply open, then the connected volume loses its air through the leaks; the recording
gets the shut-off valve's PLC output ``U_SHUTOFF`` (1 = closed). Recordings
come as a DAQ exports them (:func:`pneufdd.sim.as_exported`: no metadata, so the
analysis cannot read the truth).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from pneufdd.recording import DIGITAL, Channel, Recording
from pneufdd.sim import MachineDescription, as_exported, run_simulation
from pneufdd.sim.simulate import DIGITAL_RATE_HZ
from pneufdd.standstill.analyse import SHUTOFF_CHANNEL
from pneufdd.standstill.plan import StandstillPlan
from pneufdd.standstill.program import twin_description

__all__ = ["simulate_standstill"]


def simulate_standstill(
    plant: MachineDescription,
    plan: StandstillPlan,
    leaks: Mapping[str, object] | None = None,
    seed: int = 0,
) -> list[Recording]:
    """Recordings of the standstill test of ``plan`` on ``plant`` with ``leaks``.

    Parameters
    ----------
    plant : MachineDescription
        The machine's physics (the plan comes from its description as written).
    plan : StandstillPlan
        The test.
    leaks : mapping, optional
        Location -> size, as :func:`pneufdd.sim.run_simulation` takes them.
    seed : int
        Seed of the runs (state ``k`` of the decay mode: ``seed + k``).

    Returns
    -------
    list of Recording
        One recording (flow mode) or one per state (decay mode).
    """
    if plan.mode == "flow":
        raw = twin_description(plant, plan)
        run = run_simulation(raw, cycles=1, leaks=dict(leaks or {}), seed=seed, keep_outputs=False)
        return [as_exported(run.recording)]
    out = []
    for k in range(len(plan.states)):
        raw = twin_description(plant, plan, state=k)
        run = run_simulation(
            raw,
            cycles=2,
            leaks=dict(leaks or {}),
            seed=seed + k,
            keep_outputs=False,
            supply_open=(True, False),
        )
        out.append(_with_shutoff(as_exported(run.recording), float(run.step_start[1, 0])))
    return out


def _with_shutoff(recording: Recording, closed_at: float) -> Recording:
    """``recording`` with the shut-off valve's PLC output, closed from ``closed_at`` [s],
    as the test's function block drives it and the DAQ records it."""
    t, _ = recording.channel(recording.digital_channels[0])
    values = (t >= closed_at).astype(np.uint8)
    shutoff = Channel(SHUTOFF_CHANNEL, values, DIGITAL_RATE_HZ, "1", DIGITAL, float(t[0]))
    channels = [recording.info(name) for name in recording.channels]
    return Recording([*channels, shutoff], recording.start_time, recording.metadata)
