"""Order codes in a draft: what a nameplate adds to what the PLC signals tell (issue 35).

``pneufdd machine draft --actuator PRESS=DSBC-63-100-PPVA-N3 --valve
PRESS=VUVG-L14-P53C`` drafts as before and then sets, for every actuator with a code,
the values its catalogue row gives (:mod:`pneufdd.catalogue`): kind, bore, rod, stroke
(or swivel angle and pinion radius), and by the family's documented rules the dead
volumes, the tube its port takes and the seal friction; for every valve with a code
its kind, Cv and xT. Each such line of the TOML ends with ``# from catalogue <code>:
<status>; <source>`` (or ``# assumed by the ... rule``), as the assumed ones end with
``# assumed``. An actuator drafted with a code is no longer *drafted* in the sense of
:data:`~pneufdd.sim.description.DRAFT_MODEL`: its ``model`` ends with
:data:`~pneufdd.sim.description.CODE_DRAFT_NOTE`, and calibration fits its volume as a
described one's (``docs/calibration.md``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from pneufdd.catalogue import actuator_from_code, valve_from_code
from pneufdd.catalogue.tables import ports
from pneufdd.errors import InputError, describe
from pneufdd.physics.valve_rating import cv_from_nominal_flow
from pneufdd.sim.description import CODE_DRAFT_NOTE

__all__ = ["PORT_VALVE_FLOW", "apply_actuator_code", "apply_valve_code", "check_code_ids"]

PORT_VALVE_FLOW = {
    "M3": 220.0,
    "M5": 220.0,
    "M7": 220.0,
    "G1/8": 560.0,
    "G1/4": 870.0,
    "G3/8": 870.0,
    "G1/2": 870.0,
}
"""Standard nominal flow [l/min (ANR)] assumed for the valve of an actuator whose order
code is known but whose valve's is not: the VUVG size that takes the cylinder's port
thread (L10 for M5, L14 for G1/8, L18 for G1/4 and up; ``docs/machines.md``'s
unverified figures). A valve fitted to the step durations would be worse (stop 23)."""


def check_code_ids(codes: Mapping[str, str], ids: Sequence[str], option: str) -> None:
    """Refuse a code for an actuator the signals do not have.

    Raises
    ------
    InputError
        Naming the option, the id and the actuators found.
    """
    for ident in codes:
        if ident not in ids:
            raise InputError(describe(f"{option} actuator id", ident, list(ids)))


def apply_actuator_code(
    act: dict[str, Any], i: int, code: str, notes: dict[str, str], measured_stroke: float | None
) -> None:
    """Set what ``code`` gives into the drafted ``act`` (the ``i``-th actuator).

    The stroke measured by a position sensor is kept in the note when it differs from
    the code's by more than 5 %: the code's stroke is the cylinder's, the travel between
    end stops may be shorter (external stops).
    """
    found = actuator_from_code(code)
    act["model"] = f"{found.code} {CODE_DRAFT_NOTE}"
    act["catalogue"] = found.code
    notes[f"actuator[{i}].catalogue"] = "the order code given (--actuator)"
    default_area = math.pi / 4.0 * float(act["bore_mm"]) ** 2
    if found.angle_deg is not None:
        act.pop("stroke_mm", None)
        notes.pop(f"actuator[{i}].stroke_mm", None)
    for key, value, note in found.values():
        act[key] = value
        notes[f"actuator[{i}].{key}"] = note
    if (
        measured_stroke is not None
        and "stroke_mm" in act
        and abs(measured_stroke - found.stroke_mm) > 0.05 * found.stroke_mm
    ):
        notes[f"actuator[{i}].stroke_mm"] += f" (X_ spans {measured_stroke:g} mm)"
    # a throttle set for the same speed on the larger piston passes more air
    ratio = found.piston_area_mm2 / default_area
    act["meter_out_cv"] = round(min(float(act["meter_out_cv"]) * ratio, 50.0), 4)
    notes[f"actuator[{i}].meter_out_cv"] = (
        f"assumed: the draft's throttle scaled with the piston area of {found.code}"
    )
    if "valve" in act:
        flow = PORT_VALVE_FLOW[found.row.port]
        act["valve"]["cv"] = round(cv_from_nominal_flow(flow, 0.9), 4)
        act["valve"]["xt"] = 0.9
        kind_note = notes[f"actuator[{i}].valve"].split("; cv, xt")[0]
        notes[f"actuator[{i}].valve"] = (
            f"{kind_note}; cv, xt assumed: a valve of {flow:.0f} l/min (ANR) for the "
            f"{found.row.port} port ({ports()[found.row.port].tube})"
        )


def apply_valve_code(act: dict[str, Any], i: int, code: str, notes: dict[str, str]) -> None:
    """Set what a valve's ``code`` gives into the drafted ``act``'s valve.

    The signals tell a 5/2 monostable (one solenoid) from a valve with two solenoids;
    a code that contradicts them is refused. Two solenoids without line pressure
    sensors look like a 5/2 bistable valve: a code saying 5/3 closed centre is taken.

    Raises
    ------
    InputError
        For a code whose valve kind contradicts the solenoids recorded.
    """
    found = valve_from_code(code)
    valve = act["valve"]
    drafted = str(valve["kind"])
    one_solenoid = drafted == "5/2-monostable"
    if one_solenoid != (found.kind == "5/2-monostable") or (
        drafted == "5/3-closed-centre" and found.kind == "5/2-bistable"
    ):
        raise InputError(
            describe(f"--valve {act['id']}={code} (a {found.kind} valve)", found.kind, [drafted])
            + f"; the recording's solenoids and line pressures show a {drafted} valve for "
            f"{act['id']}"
        )
    how = f"kind from catalogue {found.code}"
    valve["kind"] = found.kind
    valve["catalogue"] = found.code
    values = dict((k, (v, n)) for k, v, n in found.values())
    if "cv" in values:
        valve["cv"], note = values["cv"]
        valve["xt"] = values["xt"][0]
        notes[f"actuator[{i}].valve"] = f"{how}; cv, xt {note}"
    else:
        notes[f"actuator[{i}].valve"] = (
            f"{how} ({found.status}); cv, xt assumed (no flow data for it in the table)"
        )
