"""Order codes of pneumatic parts and the catalogue data behind them (issue 35).

A plant engineer rarely has a machine's description, but can read the order code on
every cylinder's and valve's nameplate. This package turns such a code into the values
a description takes: :mod:`.codes` splits a code into its parts, :mod:`.tables` reads
the tables shipped with the package (``data/*.csv``, every row with its source and
status), :mod:`.lookup` combines them into an actuator's equivalent piston and a
valve's Cv and xT. ``docs/catalogue.md`` lists the families, the forms and the tables.

May import: :mod:`pneufdd.physics` and the shared helpers only (it sits between
``physics`` and ``recording``, below ``sim``, whose descriptions accept codes).
"""

from __future__ import annotations

from pneufdd.catalogue.codes import (
    ACTUATOR_FORMS,
    VALVE_FORMS,
    ParsedCode,
    parse_actuator_code,
    parse_valve_code,
)
from pneufdd.catalogue.lookup import (
    CatalogueActuator,
    CatalogueValve,
    actuator_from_code,
    description_values,
    valve_from_code,
)

__all__ = [
    "ACTUATOR_FORMS",
    "VALVE_FORMS",
    "CatalogueActuator",
    "CatalogueValve",
    "ParsedCode",
    "actuator_from_code",
    "description_values",
    "parse_actuator_code",
    "parse_valve_code",
    "valve_from_code",
]
