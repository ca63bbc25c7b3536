r"""Leak signatures held within the plant's sensor ranges.

A sensor reads within its range: a pressure transducer of 0-10 bar(g) reads 0 bar(g)
at atmosphere and below it, a one-direction flow meter reads 0 at reverse flow. Where
the plant's reference sits at such a limit in some step (an exhausted line trapped
behind a closed-centre valve that reads 0 bar(g)), a leak cannot move the reading
further out, whatever the twin predicts for its own, slightly different line. The
twin's signature :math:`e_j` of feature :math:`j` (a step's mean, minimum or maximum of
a sensor's channel) is therefore applied to the plant's reference mean
:math:`\bar x_j` and held within the range :math:`[l, h]` of that sensor:

.. math::

    e'_j = \min(\max(\bar x_j + e_j, l), h) - \bar x_j .

Measured (issue 35, end to end with order codes on a festo-dsd plant at scale 2): the
calibrated twin's DNC blind side held 0.25 bar(g) after the retract stroke where the
plant's read 0 bar(g), so the twin predicted its 60 SLPM leak to pull that line down
by 640 reference standard deviations in three steps where the plant's reading could
not move; the leak was reported as a 21 SLPM DRQD_B leak (``docs/leak-effects.md``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.physics.units import bar_gauge_to_pa, slpm_to_kg_s
from pneufdd.sim import MachineDescription

__all__ = ["censor_at_sensor_range", "feature_ranges"]

RANGED_STATISTICS = ("mean", "min", "max")
"""Per-step features in their channel's unit, bounded by its sensor's range."""


def feature_ranges(
    description: MachineDescription, feature_names: Sequence[str]
) -> tuple[FloatArray, FloatArray]:
    """Lowest and highest reading of each feature's sensor, in SI units.

    Parameters
    ----------
    description : MachineDescription
        The machine with its sensors (their ranges in bar(g), SLPM or mm).
    feature_names : sequence of str
        Feature names (``P_DNC_A.min@5``, ``duration@3``).

    Returns
    -------
    low, high : ndarray, shape (n_features,)
        The range of the feature's sensor [Pa], [kg/s] or [m]; -inf and +inf for a
        feature without one (durations, a channel no sensor describes).

    Examples
    --------
    >>> from pneufdd.sim import load_machine
    >>> low, high = feature_ranges(load_machine("press-fit-cell"),
    ...                            ["P_In.min@2", "Q_In.mean@2", "duration@2"])
    >>> low.tolist()[0], float(low[2]), float(high[2])
    (101325.0, -inf, inf)
    """
    sensors = {s.channel: s for s in description.sensors}
    low = np.full(len(feature_names), -np.inf)
    high = np.full(len(feature_names), np.inf)
    for j, name in enumerate(feature_names):
        channel, _, rest = name.partition(".")
        sensor = sensors.get(channel)
        if sensor is None or rest.split("@")[0] not in RANGED_STATISTICS:
            continue
        if sensor.kind == "pressure":
            low[j], high[j] = bar_gauge_to_pa(sensor.range_low), bar_gauge_to_pa(sensor.range_high)
        elif sensor.kind == "flow":
            lo = sensor.range_low if sensor.direction == "forward" else -sensor.range_high
            low[j], high[j] = slpm_to_kg_s(lo), slpm_to_kg_s(sensor.range_high)
        else:  # position [mm]
            low[j], high[j] = sensor.range_low / 1000.0, sensor.range_high / 1000.0
    return low, high


def censor_at_sensor_range(
    signatures: SignatureSet,
    reference_mean: FloatArray,
    low: FloatArray,
    high: FloatArray,
) -> SignatureSet:
    """The signatures with every predicted reading held within its sensor's range.

    Parameters
    ----------
    signatures : SignatureSet
        The twin's signatures (feature changes).
    reference_mean : ndarray, shape (n_features,)
        The plant's leak-free mean of each feature [feature unit].
    low, high : ndarray, shape (n_features,)
        Each feature's sensor range [feature unit] (:func:`feature_ranges`).

    Returns
    -------
    SignatureSet
        A copy whose deltas move no reading out of its range (the pair interaction
        and the plausible plants' deviations are kept as they were).

    Examples
    --------
    A line the plant reads at 0 bar(g) (101,325 Pa) cannot read lower with a leak:

    >>> s = SignatureSet(("X_A",), np.array([[1.0, 2.0]]),
    ...                  np.array([[[-300.0, 5.0], [-600.0, 9.0]]]), ("a", "b"),
    ...                  np.array([6e5]))
    >>> out = censor_at_sensor_range(s, np.array([101_425.0, 0.0]),
    ...                              np.array([101_325.0, -np.inf]), np.full(2, np.inf))
    >>> out.deltas.tolist()
    [[[-100.0, 5.0], [-100.0, 9.0]]]
    """
    mean = np.asarray(reference_mean, dtype=np.float64)
    known = np.isfinite(mean)  # a feature without a reference mean keeps the twin's change
    low = np.where(known, low, -np.inf)
    high = np.where(known, high, np.inf)
    mean = np.where(known, mean, 0.0)
    deltas = np.clip(mean + signatures.deltas, low, high) - mean
    return replace(signatures, deltas=deltas)
