r"""Commissioning with a test leak: the leak-effect model corrected per location.

For each port of a :class:`~pneufdd.diagnosis.commission_plan.CommissioningPlan` the
technician's recording (the machine running with the test orifice of known nominal
size :math:`a_0` fitted there) is diagnosed against the reference first: the leak must
be seen at that port or in its ambiguity group, otherwise the recording is refused
(the orifice was fitted elsewhere, or the port is mislabelled) and the location stays
uncorrected. The measured feature change :math:`\Delta x` (run mean minus reference
mean, the diagnosis's ``observed_change``) then corrects the location's signature
:math:`e_l` feature by feature: the plant's effect of a leak there is taken as the
twin's times a gain per feature, :math:`e'_{l,j}(a) = g_j e_{l,j}(a)` at every size
(a line that drops faster than described, a flow meter the supply feeds differently:
coherent, proportional differences). With the prior :math:`g_j \sim N(1, \tau^2)`
and the noise of the run and reference means :math:`s_j^2 = \sigma_j^2 (1/m + 1/n)`,
the posterior mean gain is

.. math::

    g_j = 1 + \frac{e_j (\Delta x_j - e_j)}{e_j^2 + s_j^2 / \tau^2},
    \qquad e_j = e_{l,j}(a_0),

so a feature the leak moves well above the noise takes the measured ratio
:math:`\Delta x_j / e_j`, and one it barely moves keeps the twin's signature.
:math:`\tau` = :data:`GAIN_PRIOR_SD` (0.5: a badly documented plant's leak effects
differ from the twin's by tens of percent, ``docs/assumptions.md``). The corrected
signature is the measured one at the test size (up to the shrinkage), blended with the
twin's shape at the other sizes of the ladder (its saturation and the stall limit stay
the twin's) and, through the pair interaction, for pairs. The plausible plants' model
error (``plant_deviations``) is kept as it was: the correction is not assumed to make
the model exact. Locations without an accepted recording keep the twin's signature.

With a second, larger test orifice at the port (:math:`a_1 < a_2`), the gains are
fitted at each test size and the corrected gain of a ladder size :math:`a` is
interpolated linearly in :math:`\ln a` between them, held at :math:`g(a_1)` below
:math:`a_1` and at :math:`g(a_2)` above :math:`a_2`: a plant whose line saturates at
another size than the twin's has another gain at another size, which one test size
cannot see (``docs/commissioning.md``, measured on festo-dsd).

A size gain (the plant's leak of size :math:`a` acting as the twin's of size
:math:`g a`) and a combination of the plausible plants' deviations were tried first on
development plants and did not lower the size errors (``docs/commissioning.md``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pneufdd.array_types import FloatArray
from pneufdd.diagnosis.commission_plan import CommissioningPlan, TestLeak
from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.diagnosis.recordings import run_table
from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError, describe
from pneufdd.features.step_table import StepTable
from pneufdd.physics.units import kg_s_to_slpm
from pneufdd.recording import Recording

__all__ = ["CommissioningResult", "PortResult", "commission", "fit_location", "gains_in_size"]

GAIN_PRIOR_SD = 0.5
"""Prior standard deviation of a feature's gain, plant over twin [-] (``docs/assumptions.md``)."""

CORRECTED, REFUSED, NOT_RUN = "corrected", "refused", "no recording"


@dataclass(frozen=True)
class LocationFit:
    """The correction of one location's signature by one test leak.

    Attributes
    ----------
    gains : ndarray, shape (n_features,)
        Posterior mean gain of each feature, plant over twin [-].
    gain_sd : ndarray, shape (n_features,)
        Posterior standard deviation of each gain [-].
    overall_gain : float
        Least-squares ratio of the measured to the twin's effect in noise units [-]
        (1.3: the plant's leak there moves its features 30 % more than the twin's).
    explained_twin, explained_corrected : float
        Fraction of the measured change's noise-weighted norm explained by the twin's
        signature at the test size and by the corrected one [-] (1: all).
    """

    gains: FloatArray
    gain_sd: FloatArray
    overall_gain: float
    explained_twin: float
    explained_corrected: float


def _explained(weight: FloatArray, observed: FloatArray, model: FloatArray) -> float:
    total = float(np.sum((weight * observed) ** 2))
    left = float(np.sum((weight * (observed - model)) ** 2))
    return 1.0 - left / total if total > 0 else 0.0


def fit_location(
    reference: ReferenceModel,
    index: int,
    size: float,
    observed: FloatArray,
    n_cycles: int,
    prior_sd: float = GAIN_PRIOR_SD,
) -> LocationFit:
    """Fit the per-feature gains of location ``index`` to a test leak.

    Parameters
    ----------
    reference : ReferenceModel
        Reference with signatures.
    index : int
        Location index into the signatures.
    size : float
        Nominal flow of the test orifice [kg/s].
    observed : ndarray, shape (n_features,)
        Measured mean feature change with the orifice fitted [feature unit].
    n_cycles : int
        Cycles the change was averaged over [-].
    prior_sd : float
        Prior standard deviation of each gain [-].

    Examples
    --------
    A feature far above the noise takes the measured ratio, one in the noise keeps 1:

    >>> e, s = np.array([10.0, 0.01]), np.array([0.1, 0.1])
    >>> g = 1 + e * (np.array([12.0, 0.05]) - e) / (e**2 + (s / 0.5) ** 2)
    >>> g.round(3).tolist()
    [1.2, 1.01]
    """
    sig = reference.signatures
    if sig is None:
        raise InputError(describe("reference", "without leak signatures", "with signatures"))
    scale = np.asarray(reference.detector.scale_, dtype=np.float64)
    noise = scale * math.sqrt(1.0 / n_cycles + 1.0 / reference.n_cycles)
    twin = sig.effect(index, size)
    denominator = twin**2 + (noise / prior_sd) ** 2
    gains = 1.0 + twin * (observed - twin) / denominator
    gain_sd = noise / np.sqrt(denominator)
    weight = 1.0 / noise
    wt, wd = weight * twin, weight * observed
    overall = float(wt @ wd / (wt @ wt)) if float(wt @ wt) > 0 else 1.0
    return LocationFit(
        np.asarray(gains, dtype=np.float64),
        np.asarray(gain_sd, dtype=np.float64),
        overall,
        _explained(weight, observed, twin),
        _explained(weight, observed, gains * twin),
    )


def gains_in_size(fits: Sequence[tuple[float, LocationFit]], sizes: FloatArray) -> FloatArray:
    """Feature gains at ``sizes`` from the fits at the test sizes, log-linear in size.

    Parameters
    ----------
    fits : sequence of (float, LocationFit)
        Test size [kg/s] and the fit it gave, one per accepted test at the location.
    sizes : ndarray, shape (n_sizes,)
        Leak sizes to correct [kg/s].

    Returns
    -------
    ndarray, shape (n_sizes, n_features)
        Each size's gains: interpolated linearly in the logarithm of the size between
        the test sizes, the nearest test's gains outside them [-].

    Examples
    --------
    >>> f1 = LocationFit(np.array([1.2, 1.0]), np.zeros(2), 1.1, 0.9, 0.95)
    >>> f2 = LocationFit(np.array([0.8, 1.0]), np.zeros(2), 0.9, 0.9, 0.95)
    >>> gains_in_size([(1.0, f1), (4.0, f2)], np.array([0.5, 2.0, 9.0])).round(3).tolist()
    [[1.2, 1.0], [1.0, 1.0], [0.8, 1.0]]
    """
    ordered = sorted(fits, key=lambda item: item[0])
    at = np.log([size for size, _ in ordered])
    gains = np.stack([fit.gains for _, fit in ordered])  # (n_tests, n_features)
    where = np.log(np.asarray(sizes, dtype=np.float64))
    out = np.empty((where.size, gains.shape[1]))
    for j in range(gains.shape[1]):
        out[:, j] = np.interp(where, at, gains[:, j])
    return out


def corrected_signatures(
    signatures: SignatureSet, fits: Mapping[int, Sequence[tuple[float, LocationFit]]]
) -> SignatureSet:
    """The signatures with each fitted location's ladder scaled by its feature gains.

    ``fits`` maps a location index to its (test size [kg/s], fit) pairs; the gain of
    each ladder size is :func:`gains_in_size` (one test: its gains at every size).
    """
    deltas = signatures.deltas.copy()
    for index, tests in fits.items():
        deltas[index] = deltas[index] * gains_in_size(tests, signatures.sizes[index])
    return replace(signatures, deltas=deltas)


@dataclass(frozen=True)
class PortResult:
    """What commissioning made of one port.

    Attributes
    ----------
    port : str
        The location.
    orifice : str
        The test orifice of this recording (``"1.0mm"``; a plan with a second orifice
        has two results per port).
    status : str
        ``"corrected"``, ``"refused"`` (the leak was not seen there) or
        ``"no recording"``.
    source : str
        The recording's file ("" without one).
    reason : str
        Why it was refused ("" otherwise).
    test_size : float
        Nominal flow of the test orifice [kg/s].
    found : tuple of str
        Locations the uncorrected diagnosis reported (the leaks and their groups).
    size_before, size_after : float
        Size of the test leak at this port by the reference before and after the
        correction [kg/s] (NaN when not sized there); after is in-sample (the same
        recording corrected the model).
    fit : LocationFit or None
        The correction (None unless corrected).
    predicted, measured : ndarray, shape (n_features,)
        The twin's effect of the test leak and the measured change [feature unit].
    """

    port: str
    status: str
    orifice: str = ""
    source: str = ""
    reason: str = ""
    test_size: float = float("nan")
    found: tuple[str, ...] = ()
    size_before: float = float("nan")
    size_after: float = float("nan")
    fit: LocationFit | None = None
    predicted: FloatArray = field(default_factory=lambda: np.zeros(0))
    measured: FloatArray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self, feature_names: Sequence[str] = ()) -> dict[str, Any]:
        """JSON-compatible form (sizes in kg/s and SLPM)."""

        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        def slpm(x: float) -> float | None:
            return num(float(kg_s_to_slpm(x)))

        out: dict[str, Any] = {
            "port": self.port,
            "orifice": self.orifice,
            "status": self.status,
            "source": self.source,
            "reason": self.reason,
            "test_size_kg_s": num(self.test_size),
            "test_size_slpm": slpm(self.test_size),
            "found": list(self.found),
            "size_before_slpm": slpm(self.size_before),
            "size_after_slpm": slpm(self.size_after),
        }
        if self.fit is not None:
            out |= {
                "overall_gain": self.fit.overall_gain,
                "explained_by_twin": self.fit.explained_twin,
                "explained_corrected": self.fit.explained_corrected,
            }
        if self.measured.size and feature_names:
            out["features"] = list(feature_names)
            out["predicted_change"] = self.predicted.tolist()
            out["measured_change"] = self.measured.tolist()
            if self.fit is not None:
                out["feature_gains"] = self.fit.gains.tolist()
        return out


@dataclass(frozen=True)
class CommissioningResult:
    """The corrected reference and what each port of the plan gave."""

    reference: ReferenceModel
    ports: tuple[PortResult, ...]

    @property
    def uncorrected(self) -> tuple[str, ...]:
        """Locations whose signature is still the twin's alone."""
        done = {p.port for p in self.ports if p.status == CORRECTED}
        sig = self.reference.signatures
        return tuple(str(x) for x in (sig.locations if sig else ()) if str(x) not in done)

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form."""
        names = self.reference.feature_names
        return {
            "machine": self.reference.machine,
            "ports": [p.to_dict(names) for p in self.ports],
            "uncorrected": list(self.uncorrected),
        }


def _size_at(result: Diagnosis, port: str) -> tuple[float, tuple[str, ...]]:
    """Size ``result`` gives a leak at ``port`` (NaN: not there) and the locations found."""
    found: list[str] = []
    size = float("nan")
    for leak in result.leaks:
        group = [str(x) for x in leak.ambiguity_group] or [str(leak.location)]
        found += [g for g in group if g not in found]
        if str(leak.location) == port:
            size = float(leak.mass_flow)
        elif port in group and math.isnan(size):
            flows = leak.group_mass_flows
            k = group.index(port)
            size = float(flows[k]) if k < len(flows) else float(leak.mass_flow)
    return size, tuple(found)


def commission(
    reference: ReferenceModel,
    plan: CommissioningPlan,
    runs: Mapping[str, tuple[str, Recording]],
    threads: int | None = 1,
) -> CommissioningResult:
    """Correct ``reference``'s leak-effect model with the plan's test-leak recordings.

    Parameters
    ----------
    reference : ReferenceModel
        The reference the plan was made for (with description and signatures).
    plan : CommissioningPlan
        The procedure that was followed.
    runs : mapping of str to (str, Recording)
        Test key (the port, or the port and ``@2`` for the second orifice,
        :meth:`CommissioningPlan.tests`) -> (file name, recording with that orifice
        fitted at that port).
    threads : int, optional
        Threads for the check by simulation (:func:`~pneufdd.diagnosis.engine.diagnose`).

    Returns
    -------
    CommissioningResult
        The corrected reference (a new object; ``reference`` is unchanged) and one
        :class:`PortResult` per recording the plan asks for.
    """
    sig = reference.signatures
    if sig is None:
        raise InputError(describe("--reference", "without leak signatures", "with signatures"))
    if plan.machine != reference.machine:
        raise InputError(describe("machine of --plan", plan.machine, [reference.machine]))
    tests = plan.tests()
    extra = sorted(set(runs) - {t.key for t in tests})
    if extra:
        raise InputError(describe("--run port", extra, [t.key for t in tests]))
    names = [str(x) for x in sig.locations]
    fits: dict[int, list[tuple[float, LocationFit]]] = {}
    results: dict[str, PortResult] = {}
    tables = {}
    for test in tests:
        if test.key not in runs:
            results[test.key] = PortResult(test.port, NOT_RUN, test.orifice,
                                           test_size=test.mass_flow)  # fmt: skip
            continue
        source, recording = runs[test.key]
        tables[test.key] = run_table(reference, recording, source)
        results[test.key] = _check(reference, names, test, source, tables[test.key], threads)
        fit = results[test.key].fit
        if fit is not None:
            fits.setdefault(names.index(test.port), []).append((test.mass_flow, fit))
    corrected = reference.with_signatures(corrected_signatures(sig, fits)) if fits else reference
    for key, table in tables.items():
        if results[key].status != CORRECTED:
            continue
        port = results[key].port
        after, _ = _size_at(diagnose(corrected, table, threads=threads, faults=False), port)
        results[key] = replace(results[key], size_after=after)
    return CommissioningResult(corrected, tuple(results[t.key] for t in tests))


def _check(
    reference: ReferenceModel,
    names: list[str],
    test: TestLeak,
    source: str,
    table: StepTable,
    threads: int | None,
) -> PortResult:
    """One test recording diagnosed with the uncorrected reference: refused or fitted."""
    sig = reference.signatures
    if sig is None:  # checked by commission
        raise InputError(describe("--reference", "without leak signatures", "with signatures"))
    # the technician fitted a leak: its size is what is measured, not other faults
    result = diagnose(reference, table, threads=threads, faults=False)
    port, size = test.port, test.mass_flow
    index = names.index(port)
    predicted = sig.effect(index, size)
    measured = np.asarray(result.observed_change, dtype=np.float64)
    before, found = _size_at(result, port)
    seen = PortResult(port, CORRECTED, test.orifice, source, "", size, found, before,
                      predicted=predicted, measured=measured)  # fmt: skip
    if not result.detected or math.isnan(before):
        where = ", ".join(found) if found else "nowhere (no leak located)"
        if not result.detected:
            where = "nowhere: not detected at all"
        reason = f"{source}: the test leak fitted at {port} was seen at {where}"
        return replace(seen, status=REFUSED, reason=reason)
    fit = fit_location(reference, index, size, measured, result.cycles_analyzed)
    return replace(seen, fit=fit)
