"""The leaks of a localisation, costed: flows, intervals, totals, repair order.

Between the search (:mod:`pneufdd.diagnosis.localisation`) and the report: each
located leak gets its mean flow over the operating cycle (from the signatures' mean
flows, with a supply leak's interaction), its nominal pressure, its 95 % flow
interval from the fit, its expected repair cost (:func:`~pneufdd.diagnosis.cost.repair_cost`)
and its annual cost (eq. 1.1, :func:`~pneufdd.diagnosis.cost.cost_leaks`); the leaks
together their totals with intervals (:func:`~pneufdd.diagnosis.cost.leak_totals`)
and the order to repair them.
"""

from __future__ import annotations

import math

import numpy as np

from pneufdd.diagnosis.cost import (
    CostSettings,
    LeakTotals,
    cost_leaks,
    leak_totals,
    repair_cost,
    repair_order,
)
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.findings import LeakFinding
from pneufdd.diagnosis.localisation.search import Localisation, SizedLocation
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.location import SUPPLY

__all__ = ["cost_localisation"]

_Z_95 = 1.959963984540054
"""Half-width of a two-sided 95 % interval in standard deviations [-]."""


def _average_flows(
    signatures: SignatureSet, found: tuple[SizedLocation, ...]
) -> list[float | None]:
    """Mean leaked flow of each leak over the operating cycle [kg/s] (None: unknown).

    Line leaks next to a supply leak blow from a lower pressure: each one's mean
    flow, and its share of the supply leak's change, come from their pair
    interaction (:meth:`SignatureSet.average_flows_with_supply`), the supply leak's
    changes summed over the line leaks.
    """
    index = signatures.locations.index
    averages = [signatures.average_flow(index(leak.location), leak.mass_flow) for leak in found]
    supply = [k for k, leak in enumerate(found) if leak.location == SUPPLY]
    if len(found) < 2 or len(supply) != 1:
        return averages
    s = supply[0]
    supply_alone = averages[s]
    supply_change = 0.0
    for k, leak in enumerate(found):
        if k == s:
            continue
        both = signatures.average_flows_with_supply(
            index(leak.location), leak.mass_flow, found[s].mass_flow
        )
        if both is None:
            return averages
        averages[k] = both[0]
        supply_change += both[1] - (supply_alone or 0.0)
    if supply_alone is not None:
        averages[s] = max(supply_alone + supply_change, 0.0)
    return averages


def _nominal_pressures(
    reference: ReferenceModel, signatures: SignatureSet, found: tuple[SizedLocation, ...]
) -> list[float]:
    """Pressure at which each leak's nominal flow is stated [Pa]."""
    pressures = []
    for leak in found:
        p = float(signatures.nominal_pressure[signatures.locations.index(leak.location)])
        if not math.isfinite(p) or p <= 0:
            p = reference.supply_pressure
        pressures.append(p if math.isfinite(p) and p > 0 else 6.0e5)
    return pressures


def _average_slopes(signatures: SignatureSet, found: tuple[SizedLocation, ...]) -> list[float]:
    """Derivative of each leak's mean flow by its nominal flow [-] (1: continuous)."""
    slopes = []
    for leak in found:
        loc = signatures.locations.index(leak.location)
        size = max(leak.mass_flow, 1e-9)
        here = signatures.average_flow(loc, size)
        there = signatures.average_flow(loc, 1.01 * size)
        slopes.append(1.0 if here is None or there is None else (there - here) / (0.01 * size))
    return slopes


def _actuator_kinds(reference: ReferenceModel) -> dict[str, str]:
    """Kind of each actuator of the reference's description (empty without one)."""
    description = reference.description
    return {} if description is None else {a.id: a.kind for a in description.actuators}


def cost_localisation(
    reference: ReferenceModel,
    signatures: SignatureSet,
    localisation: Localisation,
    settings: CostSettings,
) -> tuple[list[LeakFinding], float, LeakTotals | None, tuple[int, ...]]:
    """The located leaks costed, largest annual cost first; the total annual cost,
    the totals with intervals (None without leaks) and the repair order."""
    found = localisation.leaks
    kinds = _actuator_kinds(reference)
    # the largest size searched at each leak's location bounds its interval: a size
    # the run does not determine (a flat stretch of its effect) has no other bound
    stretch = reference.localisation.max_extrapolation
    caps = [
        float(signatures.sizes[signatures.locations.index(leak.location), -1]) * stretch
        for leak in found
    ]
    intervals = []
    for i, leak in enumerate(found):
        half = _Z_95 * math.sqrt(localisation.flow_variance(np.eye(len(found))[i]))
        high = min(leak.mass_flow + half, max(caps[i], leak.mass_flow))
        intervals.append((max(leak.mass_flow - half, 0.0), high))
    repairs = [
        repair_cost(leak.location, kinds.get(leak.location.actuator or ""), settings)
        for leak in found
    ]
    averages = _average_flows(signatures, found)
    leaks, total = cost_leaks(
        [leak.location for leak in found],
        [leak.mass_flow for leak in found],
        _nominal_pressures(reference, signatures, found),
        [leak.confidence for leak in found],
        [leak.ambiguity_group for leak in found],
        settings,
        averages,
        [leak.group_mass_flows for leak in found],
        intervals,
        repairs,
    )
    if not found:
        return leaks, total, None, ()
    totals = leak_totals(
        [leak.mass_flow for leak in found],
        [leak.mass_flow if a is None else a for leak, a in zip(found, averages, strict=True)],
        _average_slopes(signatures, found),
        lambda weights: localisation.flow_variance(np.asarray(weights, dtype=np.float64)),
        settings,
        sum(caps),
    )
    return leaks, total, totals, repair_order(leaks)
