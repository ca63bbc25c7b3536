"""Plausible plants of the signature uncertainty: drafted actuators vary further."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from pneufdd.diagnosis.effects.twin import DRAFTED_UNCERTAINTY_SCALE, plausible_plant
from pneufdd.sim import load_machine, vary_machine
from pneufdd.sim.description import DRAFT_MODEL


def _table(raw: dict[str, Any], ident: str) -> dict[str, Any]:
    return next(t for t in raw["actuator"] if t["id"] == ident)


def test_a_drafted_actuator_varies_at_the_drafted_scale_and_the_rest_as_given() -> None:
    raw = copy.deepcopy(load_machine("press-fit-cell").raw)
    _table(raw, "PRESS")["model"] = DRAFT_MODEL
    machine = load_machine(raw)
    assert [a.id for a in machine.actuators if a.drafted] == ["PRESS"]
    plant = plausible_plant(machine, 1.0, 11)
    same = vary_machine(machine, 1.0, 11)
    wide = vary_machine(machine, DRAFTED_UNCERTAINTY_SCALE, 11)
    for ident in ("FEED", "CLAMP", "EJECT"):
        assert _table(plant.raw, ident) == _table(same.raw, ident)
    assert _table(plant.raw, "PRESS") == _table(wide.raw, "PRESS")
    assert plant.raw["supply"] == same.raw["supply"]
    # the same draw, three times as far (log-normal parameters)
    base = _table(raw, "PRESS")["moving_mass_kg"]
    near = math.log(_table(same.raw, "PRESS")["moving_mass_kg"] / base)
    far = math.log(_table(plant.raw, "PRESS")["moving_mass_kg"] / base)
    assert near != 0.0
    assert far == pytest.approx(DRAFTED_UNCERTAINTY_SCALE * near, rel=0.02)  # values rounded


def test_a_description_without_drafted_actuators_is_varied_as_given() -> None:
    machine = load_machine("carton-sorter")
    assert plausible_plant(machine, 1.0, 3).raw == vary_machine(machine, 1.0, 3).raw
    assert plausible_plant(machine, 0.0, 3).raw == machine.raw
