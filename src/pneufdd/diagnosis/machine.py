"""Which machine a recording comes from, and whether it matches a description.

A diagnosis needs the machine's description (``docs/machine-format.md``): its PLC
sequence segments the recordings, and its digital twin computes the leak
signatures, checks explanations by simulation and prices leaks. A simulated
recording carries its description in its metadata; a DAQ or PLC export (CSV, TDMS)
carries none, so the user supplies one (``pneufdd reference build --machine``). The
description travels in the reference (``.pnref``) from then on; nothing is looked up
by name.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from pneufdd.errors import ChannelError, InputError, MachineError, describe
from pneufdd.recording.model import Recording
from pneufdd.signals.events import SWITCH_PREFIX, VALVE_PREFIX
from pneufdd.sim import MachineDescription, load_machine, parse_description
from pneufdd.sim.loading import MachineLike

__all__ = [
    "MachineLike",
    "check_plc_channels",
    "recording_description",
    "recording_machine_name",
    "resolve_machine",
]

"""A built-in machine name, a TOML path, a parsed TOML mapping or a description."""


def recording_machine_name(recording: Recording) -> str | None:
    """The machine name in a recording's metadata (``machine``), or None."""
    machine = recording.metadata.get("machine")
    if isinstance(machine, Mapping):
        machine = machine.get("name")
    return machine if isinstance(machine, str) and machine else None


def recording_description(recording: Recording, where: str) -> MachineDescription | None:
    """The machine description a recording carries (simulated recordings do), or None.

    Raises
    ------
    MachineError
        If the recording carries a description that is not valid.
    """
    machine = recording.metadata.get("machine")
    if not isinstance(machine, Mapping):
        return None
    raw = machine.get("description")
    if raw is None:
        return None
    if not isinstance(raw, Mapping):
        raise MachineError(
            describe(f"{where}: metadata machine.description", raw, "a machine description table")
        )
    return parse_description(dict(raw), f"{where}: metadata machine.description")


def check_plc_channels(recording: Recording, machine: MachineDescription, where: str) -> None:
    """Check that a recording's PLC signals are the description's.

    Every solenoid output and switch of the description must be a digital channel of
    the recording, and the recording must have no valve-solenoid (``U_*``) or switch
    (``S_*``) channel the description does not know: either would segment the
    recording with the wrong sequence.

    Raises
    ------
    ChannelError
        Naming the file, the channels missing or unknown, and the machine.
    """
    expected = set(machine.solenoids) | set(machine.switches)
    have = {c for c in recording.digital_channels}
    missing = sorted(expected - have)
    if missing:
        raise ChannelError(
            f"{where} lacks PLC channel(s) {missing} of machine {machine.name!r}'s description; "
            f"its digital channels are {sorted(have)} (is this the right machine description?)"
        )
    unknown = sorted(c for c in have - expected if c.startswith((VALVE_PREFIX, SWITCH_PREFIX)))
    if unknown:
        raise ChannelError(
            f"{where} has PLC channel(s) {unknown} that machine {machine.name!r}'s description "
            f"does not have (its solenoids and switches: {sorted(expected)}); describe the "
            "machine the recording comes from"
        )


def resolve_machine(
    recordings: Sequence[Recording],
    labels: Sequence[str],
    machine: MachineLike | None = None,
) -> tuple[str, MachineDescription | None]:
    """The machine of a set of recordings: its name and description.

    Parameters
    ----------
    recordings : sequence of Recording
        Recordings of one machine.
    labels : sequence of str
        Their names (files) for messages.
    machine : str, Path, MachineDescription or mapping, optional
        The machine's description, supplied by the user (a built-in name is a
        shorthand for its description). It overrides a description the recordings
        carry; the recordings' machine name, when they have one, must be its name.

    Returns
    -------
    name : str
        Machine name.
    description : MachineDescription or None
        The description (None when neither the user nor the recordings give one:
        then the sequence is learned and nothing can be located or sized).

    Raises
    ------
    MachineError
        Recordings of several machines, or of another machine than ``machine``,
        or without any machine name and no ``machine``.
    ChannelError
        A recording whose PLC channels do not match the description.
    """
    names = {where: recording_machine_name(r) for r, where in zip(recordings, labels, strict=True)}
    named = {n for n in names.values() if n is not None}
    if len(named) > 1:
        raise MachineError(
            describe("machines of the recordings", names, "recordings of one machine")
        )
    description: MachineDescription | None
    if machine is not None:
        description = load_machine(machine if not isinstance(machine, Mapping) else dict(machine))
        if named and description.name not in named:
            raise MachineError(
                describe(
                    "machine named in the recordings",
                    sorted(named)[0],
                    [description.name],
                )
                + f" (the description given is of {description.name!r}: pass the description "
                "of the machine the recordings come from)"
            )
    else:
        description = None
        for rec, where in zip(recordings, labels, strict=True):
            description = recording_description(rec, where)
            if description is not None:
                break
        if description is None and not named:
            raise InputError(
                describe(
                    "machine of the recordings",
                    "no machine name or description in their metadata",
                    "a machine description (--machine FILE.toml or a built-in name)",
                )
            )
    if description is not None:
        for rec, where in zip(recordings, labels, strict=True):
            check_plc_channels(rec, description, where)
        return description.name, description
    return sorted(named)[0], None
