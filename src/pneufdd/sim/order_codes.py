"""Order codes in a machine description: the values an actuator's or valve's code gives.

``catalogue = "DSBC-32-100-PPVA-N3"`` in an ``[[actuator]]`` table (or its ``valve``)
fills every key the table lacks with the catalogue's value (``docs/catalogue.md``,
``docs/machine-format.md``); :func:`pneufdd.sim.description.parse_description` calls
:func:`with_catalogue` before it reads the tables.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

from pneufdd.errors import InputError, MachineError, describe

__all__ = ["from_catalogue", "with_catalogue"]


def from_catalogue(table: object, where: str, part: str) -> dict[str, Any]:
    """The keys an order code gives that ``table`` lacks, with the code's values.

    ``part`` is ``"actuator"`` or ``"valve"`` (:func:`~pneufdd.catalogue.
    description_values`); a code that does not resolve raises a :class:`MachineError`
    naming ``where``. Values given in the table win over the code's (a measured dead
    volume, a Cv identified on a bench); a ``kind`` that contradicts the code's is
    refused.
    """
    from pneufdd.catalogue import description_values
    from pneufdd.catalogue.lookup import valve_kind_from_code

    if not isinstance(table, Mapping) or not isinstance(table.get("catalogue"), str):
        return {}  # no code, or one refused with its key path by the reader
    code = table["catalogue"]
    try:
        if part == "valve" and "cv" in table and "xt" in table:
            # the table states the flow: only the code's kind is needed (no ratings)
            values: tuple[tuple[str, float | str], ...] = (("kind", valve_kind_from_code(code)),)
        else:
            values = description_values(code, part)
    except InputError as exc:
        raise MachineError(f"{where}.catalogue: {exc}") from exc
    fill: dict[str, Any] = {}
    for key, value in values:
        if key == "kind" and "kind" in table and table["kind"] != value:
            raise MachineError(
                describe(f"{where}.kind", table["kind"], [value])
                + f" (order code {code!r} is a {value}; remove kind or the code)"
            )
        if key in ("stroke_mm", "angle_deg", "lever_mm") and (
            "stroke_mm" in table or "angle_deg" in table
        ):
            continue  # the table states the stroke (or the angle and lever) itself
        if key not in table:
            fill[key] = value
    return fill


def with_catalogue(data: Mapping[str, Any], source: str) -> Mapping[str, Any]:
    """``data`` with every value an actuator's or valve's order code gives filled in.

    A copy where a code fills a key (the caller's mapping is not changed), so the
    description's raw mapping states every value explicitly, as if written by hand;
    ``data`` itself when the tables state them all (the built-in machines).
    """
    actuators = data.get("actuator")
    if not isinstance(actuators, list):
        return data
    fills = []
    for i, table in enumerate(actuators):
        valve = table.get("valve") if isinstance(table, Mapping) else None
        fills.append(
            (
                from_catalogue(table, f"{source}: actuator[{i}]", "actuator"),
                from_catalogue(valve, f"{source}: actuator[{i}].valve", "valve"),
            )
        )
    if not any(a or v for a, v in fills):
        return data
    out = dict(data)  # only the actuator tables are copied: the steps are large
    out["actuator"] = copy.deepcopy(actuators)
    for table, (act_fill, valve_fill) in zip(out["actuator"], fills, strict=True):
        table.update(act_fill)
        if valve_fill:
            table["valve"].update(valve_fill)
    return out
