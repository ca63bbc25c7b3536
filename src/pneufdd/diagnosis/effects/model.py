"""The leak-effect model: how leaks change one machine's features.

Location and sizing (:mod:`pneufdd.diagnosis.localisation.search`) ask one question: *what
does a set of leaks do to the per-step features of this machine and sensor set?*
:class:`LeakEffectModel` answers it in two ways, behind one interface:

- from the **signatures** (:class:`~pneufdd.diagnosis.effects.signatures.SignatureSet`):
  single leaks interpolated piecewise linearly in their size, a pair as the sum of
  two single effects plus a bilinear interaction (:meth:`LeakEffectModel.pair_coupling`);
  instantaneous, computed once when the reference is built;
- by **simulation** (:meth:`LeakEffectModel.simulate`) of any set of leaks with the
  digital twin of the machine description the reference carries
  (:class:`~pneufdd.diagnosis.effects.twin.TwinLeakEffect`); seconds per call, used
  only when the signatures do not explain a run.

The model is built from a reference (:meth:`ReferenceModel.leak_effects`), i.e. from
the description that reference was built with; the engine never looks a machine up.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.effects.twin import SIGNATURE_SEED, TwinLeakEffect
from pneufdd.location import SUPPLY, Location
from pneufdd.parallel import positive_count
from pneufdd.physics.units import slpm_to_kg_s
from pneufdd.signals.segmentation import StepSpec
from pneufdd.sim import MachineDescription
from pneufdd.sim.faults import Fault

__all__ = ["FaultSimulator", "LeakEffectModel", "Simulator"]

Simulator = Callable[[Mapping[Location, float]], FloatArray | None]
"""Feature change of a set of leaks ``{location: nominal flow [kg/s]}``, or None when
the machine cannot run with them [feature unit]."""

FaultSimulator = Callable[[Fault], FloatArray | None]
"""Feature change of one fault other than a leak (:class:`~pneufdd.sim.faults.Fault`),
or None when the machine cannot run with it [feature unit]."""

COUPLING_REFERENCE_SLPM = 30.0
"""Leak size at which a line leak's share of a supply leak's air draw is measured [SLPM]."""


class LeakEffectModel:
    """Feature changes caused by leaks on one machine and sensor set.

    Parameters
    ----------
    signatures : SignatureSet
        Single-leak effects on a size ladder (with the supply interaction).
    simulator : callable, optional
        Feature change of any set of leaks by simulation (:data:`Simulator`); None
        when no digital twin is available.
    threads : int
        Threads that run independent simulations at once.
    fault_simulator : callable, optional
        Feature change of a fault other than a leak by simulation
        (:data:`FaultSimulator`), with the same twin, seed and baseline as
        ``simulator``; None when no digital twin is available.
    machine : MachineDescription, optional
        The description the twin simulates.
    cycles : int
        Cycles the twin averages per simulation (0: no twin).

    Examples
    --------
    >>> sig = SignatureSet(("supply", "X_A"), np.array([[4.0], [4.0]]),
    ...     np.array([[[4.0, 4.0]], [[0.0, 8.0]]]), ("f1", "f2"), np.array([6e5, 6e5]))
    >>> model = LeakEffectModel(sig)
    >>> [str(x) for x in model.locations], model.effect(1, 2.0).tolist(), model.can_simulate
    (['supply', 'X_A'], [0.0, 4.0], False)
    """

    def __init__(
        self,
        signatures: SignatureSet,
        simulator: Simulator | None = None,
        threads: int = 1,
        fault_simulator: FaultSimulator | None = None,
        machine: MachineDescription | None = None,
        cycles: int = 0,
    ) -> None:
        self.signatures = signatures
        self.simulator = simulator
        self.threads = positive_count(threads, "simulation threads")
        self.fault_simulator = fault_simulator
        self.machine = machine
        """The description the twin simulates (None without a twin)."""
        self.cycles = cycles
        """Cycles averaged per simulation (0 without a twin)."""

    @classmethod
    def from_description(
        cls,
        signatures: SignatureSet,
        machine: MachineDescription | None,
        sequence: Sequence[StepSpec],
        channels: Sequence[str],
        cycles: int = 2,
        seed: int = SIGNATURE_SEED,
        threads: int = 1,
    ) -> LeakEffectModel:
        """The model of a reference: its signatures and its machine's digital twin.

        Parameters
        ----------
        signatures : SignatureSet
            The reference's signatures.
        machine : MachineDescription or None
            The description the reference was built with (None: no simulation).
        sequence : sequence of StepSpec
            The reference's PLC sequence.
        channels : sequence of str
            Analog channels of the sensor set.
        cycles : int
            Inner cycles averaged per simulation.
        seed : int
            Seed of every simulation (the signatures' seed: common random numbers).
        threads : int
            Threads that run independent simulations at once (:attr:`threads`; the
            twin's compiled kernel releases the GIL).
        """
        twin = None
        if machine is not None and sequence:
            # the signatures' leak-free run is the check's own when cycles and seed agree
            same_run = signatures.baseline_run == (cycles, seed)
            twin = TwinLeakEffect(
                machine,
                signatures.feature_names,
                sequence,
                channels,
                cycles,
                seed,
                signatures.baseline if same_run else None,
            )
        if twin is None:
            return cls(signatures, None, threads)
        return cls(signatures, twin, threads, twin.fault_change, machine, cycles)

    @property
    def locations(self) -> tuple[Location, ...]:
        """Candidate locations, in the order of the signatures."""
        return self.signatures.locations

    @property
    def can_simulate(self) -> bool:
        """True when :meth:`simulate` can run the machine with any set of leaks."""
        return self.simulator is not None

    def effect(self, location: int, size: float) -> FloatArray:
        """Signature effect of one leak at location index ``location`` [feature unit].

        Parameters
        ----------
        location : int
            Index into :attr:`locations`.
        size : float
            Nominal leak flow [kg/s].
        """
        return self.signatures.effect(location, size)

    def change(self, leaks: Mapping[int, float]) -> FloatArray:
        """Signature-model feature change of leaks ``{location index: size [kg/s]}``.

        The sum of the single effects plus, for two leaks, their bilinear interaction
        (:meth:`pair_coupling`) [feature unit].
        """
        total = np.zeros(self.signatures.n_features)
        for i, size in leaks.items():
            total = total + self.effect(i, size)
        if len(leaks) == 2:
            coupling = self.pair_coupling()
            (a, size_a), (b, size_b) = leaks.items()
            term = None if coupling is None else coupling(a, b)
            if term is not None:
                total = total + size_a * size_b * term
        return total

    def simulate(self, leaks: Mapping[int, float]) -> FloatArray | None:
        """Simulated feature change of leaks ``{location index: size [kg/s]}``.

        Returns None when the machine cannot run with them, or without a simulator.
        """
        if self.simulator is None:
            return None
        return self.simulator({self.locations[i]: size for i, size in leaks.items()})

    def simulate_fault(self, fault: Fault) -> FloatArray | None:
        """Simulated feature change of one fault other than a leak [feature unit].

        The same twin, seed and leak-free baseline as :meth:`simulate` (common random
        numbers). Returns None when the machine cannot run with it, or without a
        simulator.
        """
        if self.fault_simulator is None:
            return None
        return self.fault_simulator(fault)

    def pair_coupling(
        self, reference_size: float | None = None
    ) -> Callable[[int, int], FloatArray | None] | None:
        r"""Bilinear interaction of two simultaneous leaks, per unit of both sizes.

        A supply leak lowers the pressure every line leak sees; its interaction with
        line ``m`` is simulated and stored (``SignatureSet.interaction_slope``,
        :math:`K_m`). A line leak ``l`` lowers the supply pressure too, in proportion
        to the supply air it draws: the fraction :math:`f_l` of a supply leak of the
        same nominal size, measured on the signatures as the ratio of their
        supply-flow (``Q_In.mean``) changes. Two leaks then interact as (an extension
        of the vector sum of eqs. 5.23-5.24 with the supply-pressure coupling of
        section 5.3.1.5)

        .. math::

            \Delta x = e_l(a_l) + e_m(a_m) + a_l a_m (f_l K_m + f_m K_l),
            \qquad f_{supply} = 1,\; K_{supply} = 0.

        Parameters
        ----------
        reference_size : float, optional
            Size at which :math:`f_l` is measured; the supply ladder's point nearest
            :data:`COUPLING_REFERENCE_SLPM` by default [kg/s].

        Returns
        -------
        callable or None
            ``coupling(l, m)`` -> interaction per unit of both sizes
            [feature unit / (kg/s)^2], or None for a pair it cannot model (two line
            leaks without a supply-flow feature); None when the signatures carry no
            interaction or no supply location.
        """
        sig = self.signatures
        if sig.interaction is None or SUPPLY not in sig.locations:
            return None
        supply = sig.locations.index(SUPPLY)
        if reference_size is None:
            ladder = sig.sizes[supply]
            near = float(slpm_to_kg_s(COUPLING_REFERENCE_SLPM))
            reference_size = float(ladder[np.argmin(np.abs(ladder - near))])
        flow = np.array([name.startswith("Q_In.mean") for name in sig.feature_names])
        share: FloatArray | None = None
        if np.any(flow):
            base = float(np.sum(sig.effect(supply, reference_size)[flow]))
            if base > 0:
                share = np.array(
                    [
                        float(np.sum(sig.effect(loc, reference_size)[flow])) / base
                        for loc in range(len(sig.locations))
                    ]
                )
                share[supply] = 1.0
        slopes = [
            np.zeros(sig.n_features) if loc == supply else sig.interaction_slope(loc)
            for loc in range(len(sig.locations))
        ]

        def coupling(first: int, second: int) -> FloatArray | None:
            k1, k2 = slopes[first], slopes[second]
            if k1 is None or k2 is None:
                return None
            if supply in (first, second):
                return k1 + k2
            if share is None:
                return None
            return np.asarray(share[first] * k2 + share[second] * k1, dtype=np.float64)

        return coupling
