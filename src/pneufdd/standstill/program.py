"""A standstill plan as a PLC program: IEC 61131-3 Structured Text, a table, a twin.

:func:`structured_text` writes a function block ``FB_StandstillLeakTest``: on a rising
``Start`` it steps through the plan's states; in each it drives the valves (a 5/2
bistable valve is pulsed until its end switch, a monostable one held or released, a
5/3 closed-centre valve held energised at the end whose line it pressurises, or
returned to its centre), waits for the end switches (``MOVE_TIMEOUT``: ``Error``),
holds ``SETTLE_TIME``, then measures for ``WINDOW_TIME`` (``Measuring`` TRUE; in the
decay mode ``ShutOff`` TRUE closes the supply shut-off valve). ``StateNo`` is the
state being held. :func:`state_table` is the same as a table (CSV and Markdown) for
the PLC programmer. :func:`twin_description` is the same sequence as a machine
description's ``[[step]]`` list, to run the test on the twin
(:mod:`pneufdd.standstill.twin`).
"""

from __future__ import annotations

import copy
import csv
import io
from typing import Any

from pneufdd import __version__
from pneufdd.sim import MachineDescription
from pneufdd.standstill.plan import StandstillPlan, StandstillState

__all__ = ["state_table", "structured_text", "twin_description"]


def _command(kind: str, ident: str, position: str, end: str) -> dict[str, str]:
    """Per solenoid, its ST expression for an actuator held at ``position``."""
    to_end = f"S_{ident}_B" if end == "extended" else f"S_{ident}_A"
    if kind == "5/2-monostable":
        return {f"U_{ident}_A": "TRUE" if position == "A" else "FALSE"}
    if kind == "5/2-bistable":  # a pulse until the end switch; the valve stays there
        if position == "A":
            return {f"U_{ident}_A": f"NOT S_{ident}_B", f"U_{ident}_B": "FALSE"}
        return {f"U_{ident}_A": "FALSE", f"U_{ident}_B": f"NOT S_{ident}_A"}
    if position == "A":  # 5/3 closed centre held at A: line A pressurised
        return {f"U_{ident}_A": "TRUE", f"U_{ident}_B": "FALSE"}
    if position == "B":
        return {f"U_{ident}_A": "FALSE", f"U_{ident}_B": "TRUE"}
    # centre: driven to its end, then released (both lines cut off)
    drive = f"U_{ident}_A" if end == "extended" else f"U_{ident}_B"
    other = f"U_{ident}_B" if end == "extended" else f"U_{ident}_A"
    return {drive: f"NOT {to_end}", other: "FALSE"}


def _in_position(state: StandstillState) -> str:
    ends = [f"S_{i}_B" if e == "extended" else f"S_{i}_A" for i, e in state.ends.items()]
    return " AND ".join(ends)


def _solenoids(plan: StandstillPlan) -> list[str]:
    out = []
    for ident, kind in plan.valve_kinds.items():
        out.append(f"U_{ident}_A")
        if kind != "5/2-monostable":
            out.append(f"U_{ident}_B")
    return out


def structured_text(plan: StandstillPlan) -> str:
    """The plan as an IEC 61131-3 Structured Text function block (module docstring)."""
    solenoids = _solenoids(plan)
    switches = [f"S_{i}_{s}" for i in plan.valve_kinds for s in "AB"]
    n = len(plan.states)
    decay = plan.mode == "decay"
    lines = [
        "FUNCTION_BLOCK FB_StandstillLeakTest",
        f"(* Standstill leak test of machine {plan.machine}, written by pneufdd {__version__}",
        f"   (pneufdd standstill plan; docs/standstill.md). Mode: {plan.mode}.",
        "   Each state: drive the valves, wait for the end switches, hold SETTLE_TIME, then",
        "   measure for WINDOW_TIME (Measuring = TRUE"
        + (", ShutOff = TRUE closes the supply shut-off valve" if decay else "")
        + ").",
        "   Record "
        + (plan.supply_pressure_channel if decay else plan.supply_flow_channel)
        + ", the solenoids and the end switches"
        + (", and ShutOff as U_SHUTOFF," if decay else "")
        + " throughout (pneufdd standstill analyse).",
    ]
    for k, state in enumerate(plan.states, start=1):
        lines.append(f"   State {k}: {state.name}; pressurised: {', '.join(state.pressurised)}")
    lines += ["*)", "VAR_INPUT", "    Start : BOOL; (* rising edge starts the test *)"]
    lines += [f"    {s} : BOOL;" for s in switches]
    lines += ["END_VAR", "VAR_OUTPUT"]
    lines += [f"    {s} : BOOL;" for s in solenoids]
    lines += [
        "    ShutOff : BOOL; (* TRUE: supply shut-off valve closed (decay mode only) *)",
        "    Measuring : BOOL; (* TRUE during the measurement window *)",
        f"    StateNo : INT; (* 1..{n}: the state held; 0: idle *)",
        "    Done : BOOL;",
        "    Error : BOOL; (* an end switch not reached within MOVE_TIMEOUT *)",
        "END_VAR",
        "VAR",
        "    Phase : INT; (* 0 move, 1 settle, 2 measure *)",
        "    StartEdge : R_TRIG;",
        "    TMove : TON;",
        "    TSettle : TON;",
        "    TWindow : TON;",
        "    InPosition : BOOL;",
        "END_VAR",
        "VAR CONSTANT",
        f"    SETTLE_TIME : TIME := T#{round(plan.settle_s * 1000)}MS;",
        f"    WINDOW_TIME : TIME := T#{round(plan.window_s * 1000)}MS;",
        "    MOVE_TIMEOUT : TIME := T#10S;",
        f"    LAST_STATE : INT := {n};",
        "END_VAR",
        "",
        "StartEdge(CLK := Start);",
        "IF StartEdge.Q THEN",
        "    StateNo := 1; Phase := 0; Done := FALSE; Error := FALSE;",
        "END_IF;",
        "",
        "CASE StateNo OF",
    ]
    for k, state in enumerate(plan.states, start=1):
        lines.append(f"{k}: (* {state.name} *)")
        commands: dict[str, str] = {}
        for ident, kind in plan.valve_kinds.items():
            commands.update(_command(kind, ident, state.positions[ident], state.ends[ident]))
        lines += [f"    {sol} := {commands[sol]};" for sol in solenoids]
        lines.append(f"    InPosition := {_in_position(state)};")
    lines += [
        "ELSE",
        *[f"    {sol} := FALSE;" for sol in solenoids],
        "    InPosition := FALSE;",
        "END_CASE;",
        "",
        "TMove(IN := (StateNo > 0) AND (Phase = 0), PT := MOVE_TIMEOUT);",
        "IF (Phase = 0) AND InPosition THEN Phase := 1; END_IF;",
        "IF TMove.Q THEN Error := TRUE; StateNo := 0; Phase := 0; END_IF;",
        "TSettle(IN := (StateNo > 0) AND (Phase = 1), PT := SETTLE_TIME);",
        "IF TSettle.Q THEN Phase := 2; END_IF;",
        "TWindow(IN := (StateNo > 0) AND (Phase = 2), PT := WINDOW_TIME);",
        "Measuring := (StateNo > 0) AND (Phase = 2);",
        f"ShutOff := {'Measuring' if decay else 'FALSE'};",
        "IF TWindow.Q THEN",
        "    Phase := 0;",
        "    IF StateNo >= LAST_STATE THEN StateNo := 0; Done := TRUE;",
        "    ELSE StateNo := StateNo + 1; END_IF;",
        "END_IF;",
        "END_FUNCTION_BLOCK",
    ]
    return "\n".join(lines) + "\n"


def _describe_command(kind: str, ident: str, position: str, end: str) -> str:
    if kind == "5/2-monostable":
        return f"U_{ident}_A {'on' if position == 'A' else 'off'}"
    if kind == "5/2-bistable":
        return f"pulse U_{ident}_{'A' if position == 'A' else 'B'} until S_{ident}_" + (
            "B" if position == "A" else "A"
        )
    if position in "AB":
        return f"U_{ident}_{position} held on"
    return f"to the {end} end, then U_{ident}_A and U_{ident}_B off (centre)"


def state_table(plan: StandstillPlan) -> tuple[str, str]:
    """The plan as a table for the PLC programmer: CSV text and Markdown text."""
    header = ["state", "name", *plan.valve_kinds, "pressurised", "settle_s", "window_s"]
    header.append("shut-off valve" if plan.mode == "decay" else "measure")
    rows = []
    for k, state in enumerate(plan.states, start=1):
        cells = [str(k), state.name]
        cells += [
            _describe_command(kind, ident, state.positions[ident], state.ends[ident])
            for ident, kind in plan.valve_kinds.items()
        ]
        cells += [" ".join(state.pressurised), f"{plan.settle_s:g}", f"{plan.window_s:g}"]
        cells.append(
            "closed during the window"
            if plan.mode == "decay"
            else f"median {plan.supply_flow_channel} over the window"
        )
        rows.append(cells)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    md = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    md += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in rows]
    return buf.getvalue(), "\n".join(md) + "\n"


def _step_actions(
    machine: MachineDescription, previous: StandstillState | None, state: StandstillState
) -> tuple[list[dict[str, Any]], list[str]]:
    """The ``do`` list and awaited switches that take the twin from ``previous`` to
    ``state`` (the description's command forms, docs/machine-format.md)."""
    do: list[dict[str, Any]] = []
    wait: list[str] = []
    for a in machine.actuators:
        target, end = state.positions[a.id], state.ends[a.id]
        before = previous.positions[a.id] if previous is not None else None
        switch = f"S_{a.id}_B" if end == "extended" else f"S_{a.id}_A"
        wait.append(switch)
        if target == before:
            continue
        kind = a.valve.kind
        if kind == "5/2-monostable":
            do.append({"set": f"U_{a.id}_A"} if target == "A" else {"reset": f"U_{a.id}_A"})
        elif kind == "5/2-bistable":
            sol = f"U_{a.id}_{'A' if target == 'A' else 'B'}"
            do.append({"set": sol, "until": switch})
        else:
            if before in ("A", "B"):
                do.append({"reset": f"U_{a.id}_{before}"})
            if target in ("A", "B"):
                do.append({"set": f"U_{a.id}_{target}"})
            elif before is None or state.ends[a.id] != (previous.ends[a.id] if previous else ""):
                sol = f"U_{a.id}_{'A' if end == 'extended' else 'B'}"
                do.append({"set": sol, "until": switch})
    return do, wait


def twin_description(
    machine: MachineDescription, plan: StandstillPlan, state: int | None = None
) -> dict[str, Any]:
    """``machine``'s description with the plan's sequence as its PLC program.

    The actuators start at their home ends (``initial``); each step drives one state,
    waits for its end switches and dwells ``settle_s + window_s``; the vacuum valve
    stays off. With ``state`` (an index of ``plan.states``) the program is that state
    alone, driven from home in one step: run for two cycles it holds the state for two
    dwells (the second with the supply shut off, :mod:`pneufdd.standstill.twin`). The
    physics is ``machine``'s (a plant's, to test the plan).
    """
    raw = copy.deepcopy(machine.raw)
    home = plan.states[0]
    for table in raw["actuator"]:
        table["initial"] = home.ends[table["id"]]
    picked = range(len(plan.states)) if state is None else (state,)
    steps = []
    previous: StandstillState | None = None
    for k in picked:
        do, wait = _step_actions(machine, previous, plan.states[k])
        step: dict[str, Any] = {"name": f"standstill: {plan.states[k].name}", "do": do}
        step["wait"] = wait
        step["dwell_s"] = plan.settle_s + plan.window_s
        steps.append(step)
        previous = plan.states[k]
    raw["step"] = steps
    raw["machine"] = {**raw["machine"], "title": f"standstill test of {machine.name}"}
    return raw
