"""A schematic of a machine's air circuit from its description, with leaks placed on it.

Drawn as SVG (no script, text escaped): the supply (house air, regulator) feeds the
valve manifold; each actuator of the description hangs below its valve (its kind and
valve type named), its extend line ``<ACT>_A`` into the cap end and its retract line
``<ACT>_B`` into the rod end, a vacuum ejector if the machine has one. Each leak is a
red circle on its line (``supply``, ``<ACT>_A`` or ``<ACT>_B``), its area proportional
to its flow, labelled with location and flow [SLPM]; a location the schematic does not
have is listed under it. Locations follow ``docs/machine-format.md``.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["schematic_svg"]

_COLUMN = 120
_LEFT = 150
_BUS_Y = 60
_VALVE_Y = 95
_ACT_Y = 215


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


def _leak_mark(x: float, y: float, leak: Mapping[str, Any], below: bool = False) -> str:
    flow = leak.get("flow_slpm")
    size = float(flow) if isinstance(flow, int | float) and math.isfinite(flow) else 0.0
    radius = 6.0 + 3.0 * math.sqrt(max(size, 0.0) / 10.0)
    text = f"{leak['location']} {size:.1f} SLPM" if size else f"{leak['location']} size unknown"
    return (
        f"<g class='leak' data-location='{_e(leak['location'])}'>"
        f"<title>{_e(text)}</title>"
        f"<circle cx='{x:.1f}' cy='{y:.1f}' r='{min(radius, 22.0):.1f}' fill='#d62728' "
        "fill-opacity='0.75' stroke='#7f0000'/>"
        f"<text x='{x - 20:.1f}' y='{y + 34 if below else y - 10:.1f}' font-size='11' "
        f"fill='#7f0000'>{_e(text)}</text>"
        "</g>"
    )


def _actuator(
    index: int, actuator: Mapping[str, Any]
) -> tuple[str, dict[str, tuple[float, float]]]:
    x0 = _LEFT + index * _COLUMN
    name = str(actuator.get("id", f"A{index + 1}"))
    kind = str(actuator.get("kind", "linear"))
    valve = actuator.get("valve", {})
    valve_kind = str(valve.get("kind", "valve")) if isinstance(valve, Mapping) else "valve"
    xa, xb = x0 + 25, x0 + 75
    parts = [
        f"<line x1='{x0 + 50}' y1='{_BUS_Y}' x2='{x0 + 50}' y2='{_VALVE_Y}' stroke='#444'/>",
        f"<rect x='{x0 + 15}' y='{_VALVE_Y}' width='70' height='28' fill='#eef' stroke='#336'/>",
        f"<text x='{x0 + 50}' y='{_VALVE_Y + 18}' font-size='10' text-anchor='middle'>"
        f"{_e(valve_kind[:14])}</text>",
        f"<line x1='{xa}' y1='{_VALVE_Y + 28}' x2='{xa}' y2='{_ACT_Y}' stroke='#1f77b4'/>",
        f"<line x1='{xb}' y1='{_VALVE_Y + 28}' x2='{xb}' y2='{_ACT_Y}' stroke='#2ca02c'/>",
        f"<text x='{xa - 3}' y='{_ACT_Y - 6}' font-size='9' text-anchor='end'>A</text>",
        f"<text x='{xb + 3}' y='{_ACT_Y - 6}' font-size='9'>B</text>",
        f"<rect x='{x0 + 10}' y='{_ACT_Y}' width='80' height='34' rx='3' fill='#f4f4f4' "
        "stroke='#222'/>",
        f"<line x1='{x0 + 50}' y1='{_ACT_Y}' x2='{x0 + 50}' y2='{_ACT_Y + 34}' stroke='#222'/>",
        f"<text x='{x0 + 50}' y='{_ACT_Y + 50}' font-size='12' font-weight='bold' "
        f"text-anchor='middle'>{_e(name)}</text>",
        f"<text x='{x0 + 50}' y='{_ACT_Y + 64}' font-size='10' text-anchor='middle' "
        f"fill='#555'>{_e(kind)}</text>",
    ]
    mid = (_VALVE_Y + 28 + _ACT_Y) / 2.0
    return "".join(parts), {f"{name}_A": (xa, mid), f"{name}_B": (xb, mid + 18)}


def schematic_svg(
    description: Mapping[str, Any] | None, leaks: Sequence[Mapping[str, Any]] = ()
) -> str:
    """SVG of the machine's circuit with ``leaks`` (``location``, ``flow_slpm``) on it.

    Parameters
    ----------
    description : mapping or None
        The machine description's TOML mapping (``[[actuator]]`` entries with ``id``,
        ``kind``, ``valve``; an optional ``[vacuum]``). None or empty: only the supply.
    leaks : sequence of mapping
        Active leaks: ``location`` and ``flow_slpm`` [SLPM: 0 degC, 1013 mbar].

    Examples
    --------
    >>> svg = schematic_svg({"actuator": [{"id": "DNC", "kind": "linear"}]},
    ...                     [{"location": "DNC_B", "flow_slpm": 40.0}])
    >>> svg.startswith("<svg") and "data-location='DNC_B'" in svg
    True
    """
    description = description or {}
    actuators = [a for a in description.get("actuator", []) if isinstance(a, Mapping)]
    vacuum = description.get("vacuum")
    columns = len(actuators) + (1 if isinstance(vacuum, Mapping) else 0)
    width = _LEFT + max(columns, 1) * _COLUMN + 20
    height = _ACT_Y + 80
    places: dict[str, tuple[float, float]] = {"supply": (70.0, _BUS_Y)}
    body = [
        f"<rect x='10' y='{_BUS_Y - 18}' width='46' height='36' rx='4' fill='#ddd' stroke='#222'/>",
        f"<text x='33' y='{_BUS_Y + 4}' font-size='10' text-anchor='middle'>supply</text>",
        f"<line x1='56' y1='{_BUS_Y}' x2='{width - 20}' y2='{_BUS_Y}' stroke='#444' "
        "stroke-width='3'/>",
        f"<text x='{_LEFT - 50}' y='{_BUS_Y - 8}' font-size='10' fill='#555'>manifold</text>",
    ]
    for i, actuator in enumerate(actuators):
        svg, spots = _actuator(i, actuator)
        body.append(svg)
        places.update(spots)
    if isinstance(vacuum, Mapping):
        x0 = _LEFT + len(actuators) * _COLUMN
        name = str(vacuum.get("id", "VAC"))
        body.append(
            f"<line x1='{x0 + 50}' y1='{_BUS_Y}' x2='{x0 + 50}' y2='{_ACT_Y}' stroke='#444'/>"
            f"<circle cx='{x0 + 50}' cy='{_ACT_Y + 17}' r='17' fill='#f4f4f4' stroke='#222'/>"
            f"<text x='{x0 + 50}' y='{_ACT_Y + 50}' font-size='12' font-weight='bold' "
            f"text-anchor='middle'>{_e(name)}</text>"
            f"<text x='{x0 + 50}' y='{_ACT_Y + 64}' font-size='10' text-anchor='middle' "
            "fill='#555'>vacuum ejector</text>"
        )
    unplaced = []
    for leak in leaks:
        spot = places.get(str(leak.get("location")))
        if spot is None:
            unplaced.append(str(leak.get("location")))
            continue
        body.append(_leak_mark(spot[0], spot[1], leak, below=leak.get("location") == "supply"))
    if unplaced:
        body.append(
            f"<text x='10' y='{height - 6}' font-size='11' fill='#7f0000'>not on the schematic: "
            f"{_e(', '.join(unplaced))}</text>"
        )
    title = _e(description.get("machine", {}).get("title", "") if description else "")
    return (
        f"<svg viewBox='0 0 {width} {height}' "
        f"width='100%' role='img' aria-label='air circuit schematic'>"
        f"<title>{title or 'air circuit'}</title>" + "".join(body) + "</svg>"
    )
