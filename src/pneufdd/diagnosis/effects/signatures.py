"""Leak signatures: the per-step fingerprint of a leak at each candidate location.

Section 5.3.1 reads the location of a leak from *which* steps its flow difference
shows in (a supply leak: a constant offset in all 58 steps, Fig. 5.8; a DNC_B leak:
a distinct pattern in steps 2 and 58, Fig. 5.9) and its size from *how much*
(5.3.1.5). A :class:`SignatureSet` makes that knowledge explicit and machine
independent: for every candidate location (``supply``, ``<ACT>_A``, ``<ACT>_B``) and a
few leak sizes it stores the change of every per-step feature (durations, mean/min/max
of flow and pressure) against the leak-free machine. The effects are not exactly
linear in the size (the flow meters saturate, leaks slow actuators), so the effect of
any size is interpolated piecewise linearly through the computed sizes and the origin.

Signatures are computed once per machine and sensor set, with the simulator (see
:mod:`pneufdd.diagnosis.effects.twin`), and stored in the reference file.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.piecewise import PiecewiseLinear
from pneufdd.errors import InputError, describe
from pneufdd.location import SUPPLY, Location

__all__ = ["SignatureSet", "feature_columns"]


def feature_columns(feature_names: Sequence[str], names: Sequence[str], what: str) -> list[int]:
    """Columns of ``names`` in ``feature_names`` (a sensor subset's); an ``InputError``
    naming ``what`` and up to five of them when some are not there."""
    index = {n: i for i, n in enumerate(feature_names)}
    missing = [n for n in names if n not in index]
    if missing:
        raise InputError(describe(what, missing[:5], "features of the signatures"))
    return [index[n] for n in names]


@dataclass(frozen=True, eq=False)
class SignatureSet:
    """Feature changes caused by leaks of known size at each candidate location.

    Attributes
    ----------
    locations : tuple of Location
        Candidate locations: ``supply``, ``<ACT>_A``, ``<ACT>_B`` (names are accepted
        and parsed).
    sizes : ndarray, shape (n_locations, n_sizes)
        Leak sizes simulated, as the leak's mass flow at its nominal pressure,
        increasing along each row [kg/s].
    deltas : ndarray, shape (n_locations, n_sizes, n_features)
        Mean feature change (leak minus leak-free) at each size [feature unit].
    feature_names : tuple of str
        Names of the features (columns of :meth:`StepTable.features`).
    nominal_pressure : ndarray, shape (n_locations,)
        Absolute pressure at which each location's size is stated [Pa].
    interaction : ndarray, shape (n_locations, n_features), optional
        Non-additive part of the effect of a leak at each location together with a
        supply leak: ``effect(l + supply) - effect(l) - effect(supply)`` at the sizes
        ``interaction_sizes`` [feature unit]. A supply leak lowers the pressure every
        line sees, so line leaks act differently with it; the term is modelled as
        bilinear in the two sizes. Zero for ``supply`` itself.
    interaction_sizes : ndarray, shape (2,), optional
        Line and supply leak sizes at which ``interaction`` was simulated [kg/s].
    mean_flow : ndarray, shape (n_locations, n_sizes), optional
        Mean leaked mass flow over a machine cycle at each simulated size [kg/s]: the
        air the leak really loses. A ``supply`` leak blows all cycle (about its size);
        a leak on an actuator line only while that line holds pressure. See
        :meth:`average_flow`.
    mean_flow_interaction : ndarray, shape (n_locations, 2), optional
        With a supply leak, at ``interaction_sizes``: the change of the line leak's
        mean flow and of the supply leak's mean flow caused by the other leak [kg/s]
        (a supply leak lowers the pressure the line leak blows from). Modelled as
        bilinear in the two sizes (:meth:`average_flows_with_supply`); zero for
        ``supply`` itself. Needs ``mean_flow`` and ``interaction_sizes``.
    plant_deviations : ndarray, shape (n_plants, n_locations, n_dev_sizes, n_features), optional
        Model uncertainty of the signatures: on each of ``n_plants`` plausible plants
        drawn around the description (:func:`pneufdd.sim.vary_machine`; a real machine
        differs from its catalogue description), the effect of the same leak minus
        the signature's, at every location and at :attr:`deviation_sizes`
        (:func:`~pneufdd.diagnosis.effects.twin.signature_spread`) [feature unit].
        Their spread is the covariance of the signatures' error on a real machine.
    deviation_sizes : ndarray, shape (n_dev_sizes,), optional
        Leak sizes of :attr:`plant_deviations`, increasing [kg/s].
    baseline : ndarray, shape (n_features,), optional
        Mean features of the twin's leak-free run the deltas are taken from [feature
        unit]: the simulation check (:class:`~pneufdd.diagnosis.effects.twin.TwinLeakEffect`)
        subtracts the same run, and takes it from here instead of simulating it again
        when its cycles and seed are :attr:`baseline_run`.
    baseline_run : tuple of (int, int), optional
        Inner cycles averaged and seed of that leak-free run. Both or neither.

    Examples
    --------
    >>> s = SignatureSet(("supply",), np.array([[1.0, 2.0]]),
    ...                  np.array([[[1.0, 10.0], [3.0, 20.0]]]), ("a", "b"),
    ...                  np.array([6e5]))
    >>> s.effect(0, 1.5).tolist()       # halfway between the two sizes
    [2.0, 15.0]
    >>> s.effect(0, 0.5).tolist()       # between the origin and the first size
    [0.5, 5.0]
    >>> s.effect(0, 4.0).tolist()       # beyond the last size: the last segment extended
    [7.0, 40.0]
    """

    locations: tuple[Location, ...]
    sizes: FloatArray
    deltas: FloatArray
    feature_names: tuple[str, ...]
    nominal_pressure: FloatArray
    interaction: FloatArray | None = None
    interaction_sizes: FloatArray | None = None
    mean_flow: FloatArray | None = None
    mean_flow_interaction: FloatArray | None = None
    plant_deviations: FloatArray | None = None
    deviation_sizes: FloatArray | None = None
    baseline: FloatArray | None = None
    baseline_run: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        locations = tuple(
            loc if isinstance(loc, Location) else Location.parse(loc) for loc in self.locations
        )
        sizes = np.asarray(self.sizes, dtype=np.float64)
        deltas = np.asarray(self.deltas, dtype=np.float64)
        pressure = np.asarray(self.nominal_pressure, dtype=np.float64)
        names = tuple(self.feature_names)
        n_loc = len(locations)
        if len(set(locations)) != n_loc or n_loc == 0:
            raise InputError(
                describe("signature locations", [str(x) for x in locations], "unique, at least one")
            )
        if sizes.ndim != 2 or sizes.shape[0] != n_loc or sizes.shape[1] < 1:
            raise InputError(describe("shape of signature sizes", sizes.shape, f"({n_loc}, >=1)"))
        if not np.all(np.isfinite(sizes)) or np.any(sizes <= 0) or np.any(np.diff(sizes) <= 0):
            raise InputError(
                describe("signature sizes [kg/s]", sizes.tolist(), "positive, increasing")
            )
        expected = (n_loc, sizes.shape[1], len(names))
        if deltas.shape != expected:
            raise InputError(describe("shape of signature deltas", deltas.shape, [expected]))
        if not np.all(np.isfinite(deltas)):
            raise InputError(describe("signature deltas", "NaN or infinite", "finite values"))
        if pressure.shape != (n_loc,):
            raise InputError(describe("shape of nominal_pressure", pressure.shape, [(n_loc,)]))
        if (self.interaction is None) != (self.interaction_sizes is None):
            raise InputError(
                describe("interaction and interaction_sizes", "only one", "both or neither")
            )
        if self.interaction is not None and self.interaction_sizes is not None:
            inter = np.asarray(self.interaction, dtype=np.float64)
            isz = np.asarray(self.interaction_sizes, dtype=np.float64)
            if inter.shape != (n_loc, len(names)) or not np.all(np.isfinite(inter)):
                raise InputError(
                    describe("shape of interaction", inter.shape, [(n_loc, len(names))])
                )
            if isz.shape != (2,) or np.any(isz <= 0):
                raise InputError(describe("interaction_sizes [kg/s]", isz.tolist(), "2 sizes > 0"))
            object.__setattr__(self, "interaction", inter)
            object.__setattr__(self, "interaction_sizes", isz)
        if self.mean_flow is not None:
            mean = np.asarray(self.mean_flow, dtype=np.float64)
            if mean.shape != sizes.shape:
                raise InputError(describe("shape of mean_flow", mean.shape, [sizes.shape]))
            if not np.all(np.isfinite(mean)) or np.any(mean < 0):
                raise InputError(describe("mean_flow [kg/s]", mean.tolist(), "finite, >= 0"))
            object.__setattr__(self, "mean_flow", mean)
        if self.mean_flow_interaction is not None:
            mfi = np.asarray(self.mean_flow_interaction, dtype=np.float64)
            if self.mean_flow is None or self.interaction_sizes is None:
                raise InputError(
                    describe(
                        "mean_flow_interaction",
                        "given alone",
                        "with mean_flow and interaction_sizes",
                    )
                )
            if mfi.shape != (n_loc, 2) or not np.all(np.isfinite(mfi)):
                raise InputError(
                    describe("shape of mean_flow_interaction", mfi.shape, [(n_loc, 2)])
                )
            object.__setattr__(self, "mean_flow_interaction", mfi)
        if (self.plant_deviations is None) != (self.deviation_sizes is None):
            raise InputError(
                describe("plant_deviations and deviation_sizes", "only one", "both or neither")
            )
        if self.plant_deviations is not None and self.deviation_sizes is not None:
            dev = np.asarray(self.plant_deviations, dtype=np.float64)
            dsz = np.asarray(self.deviation_sizes, dtype=np.float64)
            if dsz.ndim != 1 or dsz.size < 1 or np.any(dsz <= 0) or np.any(np.diff(dsz) <= 0):
                raise InputError(
                    describe("deviation_sizes [kg/s]", dsz.tolist(), "positive, increasing")
                )
            want = (n_loc, dsz.size, len(names))
            if dev.ndim != 4 or dev.shape[1:] != want or dev.shape[0] < 1:
                raise InputError(
                    describe("shape of plant_deviations", dev.shape, f"(n_plants, {want})")
                )
            if not np.all(np.isfinite(dev)):
                raise InputError(describe("plant_deviations", "NaN or infinite", "finite"))
            object.__setattr__(self, "plant_deviations", dev)
            object.__setattr__(self, "deviation_sizes", dsz)
        self._check_baseline(len(names))
        object.__setattr__(self, "locations", locations)
        object.__setattr__(self, "sizes", sizes)
        object.__setattr__(self, "deltas", deltas)
        object.__setattr__(self, "feature_names", names)
        object.__setattr__(self, "nominal_pressure", pressure)

    def _check_baseline(self, n_features: int) -> None:
        if (self.baseline is None) != (self.baseline_run is None):
            raise InputError(describe("baseline and baseline_run", "only one", "both or neither"))
        if self.baseline is None or self.baseline_run is None:
            return
        base = np.asarray(self.baseline, dtype=np.float64)
        if base.shape != (n_features,) or not np.all(np.isfinite(base)):
            raise InputError(
                describe("shape of the signatures' baseline", base.shape, [(n_features,)])
            )
        run = tuple(int(x) for x in self.baseline_run)
        if len(run) != 2 or run[0] < 1:
            raise InputError(
                describe("baseline_run (cycles, seed)", list(self.baseline_run), "cycles >= 1")
            )
        object.__setattr__(self, "baseline", base)
        object.__setattr__(self, "baseline_run", run)

    @property
    def n_features(self) -> int:
        """Number of features per signature."""
        return len(self.feature_names)

    def effect(self, location: int, size: float) -> FloatArray:
        """Feature change of a leak of ``size`` at location index ``location``.

        Piecewise linear through the origin and the simulated sizes; beyond the
        largest size the last segment is extended linearly.

        Parameters
        ----------
        location : int
            Index into :attr:`locations`.
        size : float
            Leak mass flow at nominal pressure [kg/s].

        Returns
        -------
        ndarray, shape (n_features,)
            Feature change [feature unit].
        """
        return self.piecewise(location, size)

    @cached_property
    def piecewise(self) -> PiecewiseLinear:
        """The signatures as one :class:`PiecewiseLinear` function per location."""
        return PiecewiseLinear(self.sizes, self.deltas)

    def slope(self, location: int, size: float | None = None) -> FloatArray:
        """Secant signature per unit size, ``effect(size) / size`` [feature unit per kg/s].

        With ``size`` None (or not positive), the slope of the smallest simulated size.
        """
        if size is None or size <= 0:
            size = float(self.sizes[location, 0])
        return self.effect(location, size) / size

    def select(self, names: Sequence[str]) -> SignatureSet:
        """Restrict the signatures to the features ``names`` (a sensor subset)."""
        cols = feature_columns(self.feature_names, names, "features without a signature")
        return SignatureSet(
            self.locations,
            self.sizes,
            self.deltas[:, :, cols],
            tuple(names),
            self.nominal_pressure,
            None if self.interaction is None else self.interaction[:, cols],
            self.interaction_sizes,
            self.mean_flow,
            self.mean_flow_interaction,
            None if self.plant_deviations is None else self.plant_deviations[..., cols],
            self.deviation_sizes,
            None if self.baseline is None else self.baseline[cols],
            self.baseline_run,
        )

    @property
    def n_plants(self) -> int:
        """Number of plausible plants behind the model uncertainty (0: none)."""
        return 0 if self.plant_deviations is None else int(self.plant_deviations.shape[0])

    def with_plant_deviations(
        self, deviations: FloatArray | None, sizes: FloatArray | None
    ) -> SignatureSet:
        """A copy with :attr:`plant_deviations` at :attr:`deviation_sizes` (None: none)."""
        return replace(self, plant_deviations=deviations, deviation_sizes=sizes)

    @cached_property
    def _deviation_model(self) -> PiecewiseLinear | None:
        if self.plant_deviations is None or self.deviation_sizes is None:
            return None
        k, n_loc, n_sizes, n_feat = self.plant_deviations.shape
        values = np.moveaxis(self.plant_deviations, 0, 2).reshape(n_loc, n_sizes, k * n_feat)
        return PiecewiseLinear(np.tile(self.deviation_sizes, (n_loc, 1)), values)

    def deviations(self, location: int, size: float) -> FloatArray | None:
        """Each plausible plant's deviation from the signature of one leak.

        Interpolated piecewise linearly in the size through the origin (no leak, no
        deviation), like the signatures.

        Parameters
        ----------
        location : int
            Index into :attr:`locations`.
        size : float
            Leak mass flow at nominal pressure [kg/s].

        Returns
        -------
        ndarray, shape (n_plants, n_features), or None
            Plant effect minus signature effect [feature unit]; None without
            :attr:`plant_deviations`.
        """
        model = self._deviation_model
        if model is None:
            return None
        return np.asarray(model(location, size).reshape(self.n_plants, self.n_features))

    def duty(self, location: int, size: float) -> float | None:
        """Fraction of its nominal flow a leak loses on average over a machine cycle.

        ``mean_flow / size`` at the simulated sizes, interpolated linearly in the
        size; below the smallest and beyond the largest size the end values are
        kept (a leak's duty depends on the size only through how fast it drains
        its line). A ``supply`` leak's duty is about 1 (it leaks all cycle); a leak on
        a line of a 5/3 closed-centre valve blows only until the isolated chamber is
        empty.

        Parameters
        ----------
        location : int
            Index into :attr:`locations`.
        size : float
            Leak mass flow at nominal pressure [kg/s].

        Returns
        -------
        float or None
            Duty [-], None when the signatures hold no mean flows.

        Examples
        --------
        A line leak that loses all its flow at size 1 but half of it at size 2:

        >>> s = SignatureSet(("X_B",), np.array([[1.0, 2.0]]), np.zeros((1, 2, 1)),
        ...                  ("a",), np.array([6e5]), mean_flow=np.array([[1.0, 1.0]]))
        >>> s.duty(0, 1.5), s.duty(0, 0.5), s.duty(0, 4.0), s.average_flow(0, 4.0)
        (0.75, 1.0, 0.5, 2.0)
        """
        if self.mean_flow is None:
            return None
        ratio = self.mean_flow[location] / self.sizes[location]
        return float(np.interp(max(float(size), 0.0), self.sizes[location], ratio))

    def average_flow(self, location: int, size: float) -> float | None:
        """Mean leaked mass flow over a machine cycle of a leak of ``size`` [kg/s].

        ``size * duty(location, size)``; None when the signatures hold no mean flows.
        """
        duty = self.duty(location, size)
        return None if duty is None else max(float(size), 0.0) * duty

    def interaction_slope(self, location: int) -> FloatArray | None:
        """Bilinear interaction with a supply leak per unit of both sizes.

        Returns ``interaction[location] / (line size * supply size)``
        [feature unit per (kg/s)^2], or None when not available.
        """
        if self.interaction is None or self.interaction_sizes is None:
            return None
        line, supply = self.interaction_sizes
        return np.asarray(self.interaction[location] / (line * supply), dtype=np.float64)

    def average_flows_with_supply(
        self, line: int, line_size: float, supply_size: float
    ) -> tuple[float, float] | None:
        """Mean flows of a line leak and a supply leak leaking together [kg/s].

        Each leak's :meth:`average_flow` plus the bilinear interaction
        ``mean_flow_interaction[line] * (line_size / l0) * (supply_size / s0)`` with
        ``(l0, s0)`` the :attr:`interaction_sizes`, floored at zero.

        Parameters
        ----------
        line : int
            Index of the line location into :attr:`locations`.
        line_size, supply_size : float
            Nominal sizes of the two leaks [kg/s].

        Returns
        -------
        tuple of float or None
            Mean flows of the line leak and of the supply leak [kg/s]; None without
            ``mean_flow_interaction`` or a ``supply`` location.
        """
        if (
            self.mean_flow_interaction is None
            or self.interaction_sizes is None
            or SUPPLY not in self.locations
        ):
            return None
        supply = self.locations.index(SUPPLY)
        line_alone = self.average_flow(line, line_size)
        supply_alone = self.average_flow(supply, supply_size)
        if line_alone is None or supply_alone is None:
            return None
        l0, s0 = self.interaction_sizes
        scale = max(float(line_size), 0.0) / l0 * max(float(supply_size), 0.0) / s0
        d_line, d_supply = self.mean_flow_interaction[line] * scale
        return max(line_alone + float(d_line), 0.0), max(supply_alone + float(d_supply), 0.0)
