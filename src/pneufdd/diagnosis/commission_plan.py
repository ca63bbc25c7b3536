"""The commissioning procedure: a known test orifice fitted at each port in turn.

A plant's description is a guess (bores, valve capacity, tubes, the regulator), so the
twin's leak signatures are a guess too. While the machine runs, a technician fits a
test orifice of known size (a nozzle of given diameter, or the GR-3/8B leak valve at a
number of turns, Table 3.3) at one port, lets the machine run ``K`` cycles while it is
recorded, removes it, and goes on to the next port. The recordings then correct the
leak-effect model per location (:mod:`pneufdd.diagnosis.commissioning`;
``docs/commissioning.md``).

This module writes the procedure: which ports, which orifice, how many cycles, and the
orifice's nominal flow at the machine's nominal supply pressure (the size the
diagnosis states, ``docs/twin.md`` "Leaks"). With a second, larger orifice every port
is visited twice (one recording per orifice): the correction is then measured at two
sizes and interpolated between them, where one size could only be carried to the
others unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pneufdd.diagnosis.reference.model import ReferenceModel
from pneufdd.errors import InputError, describe
from pneufdd.physics.units import pa_to_bar_gauge
from pneufdd.sim.leaks import parse_leak_size, resolve_leaks

__all__ = [
    "DEFAULT_CYCLES",
    "MAX_COMMISSION_CYCLES",
    "CommissioningPlan",
    "TestLeak",
    "plan_commissioning",
]

DEFAULT_CYCLES = 20
"""Cycles recorded with the test orifice fitted (after the first, a start-up cycle) [-]."""

MAX_COMMISSION_CYCLES = 10_000
"""Most cycles a plan asks for at one port (``docs/limits.md``) [-]."""

PLAN_FORMAT = 2
"""Version of ``plan.json`` (1: one orifice, still read)."""

SECOND = "@2"
"""Suffix of a port's recording with the second orifice (``DNC_B@2.parquet``)."""


@dataclass(frozen=True)
class TestLeak:
    """One recording of the plan: a test orifice fitted at one port.

    Attributes
    ----------
    key : str
        The recording's name: the port (first orifice) or the port and ``@2`` (second).
    port : str
        The location the orifice is fitted at.
    orifice : str
        The orifice as given (``"1.0mm"``, ``"2turns"``).
    mass_flow : float
        Its flow at the nominal supply pressure, 20 degC [kg/s].
    slpm : float
        The same flow in SLPM.
    """

    __test__ = False  # not a pytest class

    key: str
    port: str
    orifice: str
    mass_flow: float
    slpm: float


@dataclass(frozen=True)
class CommissioningPlan:
    """The commissioning procedure for one reference.

    Attributes
    ----------
    machine : str
        Machine name (the reference's).
    ports : tuple of str
        Locations to commission, in the order the technician visits them
        (``supply``, ``<ACT>_A``, ``<ACT>_B``).
    orifice : str
        The test orifice as given: ``"1.0mm"`` (nozzle diameter) or ``"2turns"``
        (GR-3/8B leak valve).
    nominal_mass_flow : float
        The orifice's flow at the machine's nominal supply pressure, 20 degC [kg/s].
    nominal_slpm : float
        The same flow in SLPM (0 degC, 1013 mbar).
    nominal_pressure : float
        The nominal supply pressure the size is stated at [Pa].
    cycles : int
        Machine cycles to record with the orifice fitted (plus one start-up cycle) [-].
    second_orifice : str
        A second, larger test orifice fitted at every port after the first ("": none).
    second_mass_flow : float
        Its flow at the nominal supply pressure, 20 degC [kg/s] (0 without).
    second_slpm : float
        The same flow in SLPM (0 without).

    Examples
    --------
    >>> p = CommissioningPlan("m", ("supply", "X_A"), "1mm", 1e-3, 46.4, 5.9e5, 20)
    >>> CommissioningPlan.from_dict(p.to_dict(), "plan.json") == p
    True
    >>> p.size_of("X_A")
    0.001
    >>> two = CommissioningPlan("m", ("X_A",), "1mm", 1e-3, 46.4, 5.9e5, 20, "2mm", 4e-3, 186.)
    >>> [(t.key, t.orifice) for t in two.tests()]
    [('X_A', '1mm'), ('X_A@2', '2mm')]
    >>> CommissioningPlan.from_dict(two.to_dict(), "plan.json") == two
    True
    """

    machine: str
    ports: tuple[str, ...]
    orifice: str
    nominal_mass_flow: float
    nominal_slpm: float
    nominal_pressure: float
    cycles: int
    second_orifice: str = ""
    second_mass_flow: float = 0.0
    second_slpm: float = 0.0

    def size_of(self, port: str) -> float:
        """Nominal flow of the (first) test orifice at ``port`` [kg/s] (the same at every port)."""
        if port not in self.ports:
            raise InputError(describe("port", port, list(self.ports)))
        return self.nominal_mass_flow

    def tests(self) -> list[TestLeak]:
        """Every recording the plan asks for, in the order the technician makes them."""
        out = []
        for port in self.ports:
            out.append(TestLeak(port, port, self.orifice, self.nominal_mass_flow,
                                self.nominal_slpm))  # fmt: skip
            if self.second_orifice:
                out.append(TestLeak(port + SECOND, port, self.second_orifice,
                                    self.second_mass_flow, self.second_slpm))  # fmt: skip
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible form (``plan.json``)."""
        return {
            "format": PLAN_FORMAT,
            "machine": self.machine,
            "ports": list(self.ports),
            "orifice": self.orifice,
            "nominal_mass_flow_kg_s": self.nominal_mass_flow,
            "nominal_slpm": self.nominal_slpm,
            "nominal_pressure_pa": self.nominal_pressure,
            "cycles": self.cycles,
            "second_orifice": self.second_orifice,
            "second_mass_flow_kg_s": self.second_mass_flow,
            "second_slpm": self.second_slpm,
            "steps": self.steps(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str) -> CommissioningPlan:
        """Inverse of :meth:`to_dict`; ``where`` names the file in errors."""
        if not isinstance(data, Mapping) or data.get("format") not in (1, PLAN_FORMAT):
            raise InputError(describe(where, "not a commissioning plan", "commission plan's JSON"))
        try:
            ports = tuple(str(p) for p in data["ports"])
            plan = cls(
                str(data["machine"]),
                ports,
                str(data["orifice"]),
                float(data["nominal_mass_flow_kg_s"]),
                float(data["nominal_slpm"]),
                float(data["nominal_pressure_pa"]),
                int(data["cycles"]),
                str(data.get("second_orifice", "")),
                float(data.get("second_mass_flow_kg_s", 0.0)),
                float(data.get("second_slpm", 0.0)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(describe(where, repr(exc), "commission plan's JSON")) from exc
        if not ports or len(set(ports)) != len(ports) or not plan.nominal_mass_flow > 0:
            raise InputError(describe(f"ports of {where}", list(ports), "unique, at least one"))
        if plan.second_orifice and not plan.second_mass_flow > plan.nominal_mass_flow:
            raise InputError(
                describe(f"second orifice of {where}", plan.second_orifice, "larger than the first")
            )
        if not 1 <= plan.cycles <= MAX_COMMISSION_CYCLES:
            raise InputError(
                describe(f"cycles of {where}", plan.cycles, f"1 to {MAX_COMMISSION_CYCLES}")
            )
        return plan

    def steps(self) -> list[str]:
        """The procedure, one instruction per step."""

        def what(orifice: str) -> str:
            if orifice.endswith("turns"):
                return f"the {orifice.removesuffix('turns')} turns GR-3/8B leak valve"
            return f"the {orifice} test nozzle"

        out = [
            f"Run the machine leak-free as in its reference ({self.machine}); keep it "
            "running through the whole procedure.",
        ]
        for k, port in enumerate(self.ports, start=1):
            where = "the supply manifold" if port == "supply" else f"line {port}"
            tests = [t for t in self.tests() if t.port == port]
            fits = "; then ".join(
                f"fit {what(t.orifice)} at {where} ({t.slpm:.1f} SLPM at "
                f"{pa_to_bar_gauge(self.nominal_pressure):.2f} bar(g)), record at least "
                f"{self.cycles + 1} complete cycles into one file named {t.key}.parquet, "
                "remove the orifice"
                for t in tests
            )
            out.append(f"Port {k}/{len(self.ports)} {port}: {fits}.")
        keys = [t.key for t in self.tests()]
        out.append(
            "Correct the reference: pneufdd commission apply --reference REF --plan PLAN "
            + " ".join(f"--run {p}={p}.parquet" for p in keys[:2])
            + (" ..." if len(keys) > 2 else "")
            + " --out CORRECTED.pnref"
        )
        return out

    def markdown(self) -> str:
        """The procedure for the technician, as Markdown."""
        second = (
            f"; then {self.second_orifice}, {self.second_slpm:.1f} SLPM"
            if self.second_orifice
            else ""
        )
        lines = [
            f"# Commissioning with a test leak: {self.machine}",
            "",
            f"Test orifice: {self.orifice}, {self.nominal_slpm:.1f} SLPM at the nominal "
            f"supply pressure{second}. Cycles per recording: {self.cycles} (plus one "
            "start-up cycle).",
            "",
        ]
        lines += [f"{k}. {step}" for k, step in enumerate(self.steps(), start=1)]
        return "\n".join(lines) + "\n"


def plan_commissioning(
    reference: ReferenceModel,
    ports: Sequence[str] | None = None,
    orifice: str | float = "1.0mm",
    cycles: int = DEFAULT_CYCLES,
    second_orifice: str | float | None = None,
) -> CommissioningPlan:
    """The commissioning procedure for ``reference``'s machine.

    Parameters
    ----------
    reference : ReferenceModel
        The reference to correct: it must carry its machine description and signatures.
    ports : sequence of str, optional
        Locations to visit, in order; default every location of the signatures.
    orifice : str or float
        Test orifice: ``"1.0mm"`` (nozzle) or a number of turns of the GR-3/8B leak
        valve (``2`` or ``"2turns"``); a flow (``"30slpm"``) is not an orifice a
        technician can fit and is refused.
    cycles : int
        Cycles to record at each port (1-10,000).
    second_orifice : str or float, optional
        A second, larger test orifice (the same forms as ``orifice``) fitted at every
        port after the first: the correction is then measured at two sizes
        (``docs/commissioning.md``).

    Returns
    -------
    CommissioningPlan
    """
    description = reference.description
    if description is None or reference.signatures is None:
        raise InputError(
            describe(
                f"reference of {reference.machine!r}",
                "without a machine description or leak signatures",
                "a reference built with its machine description (reference build --machine)",
            )
        )
    text = _orifice_text(orifice)
    if isinstance(cycles, bool) or not 1 <= int(cycles) <= MAX_COMMISSION_CYCLES:
        raise InputError(describe("--cycles", cycles, f"1 to {MAX_COMMISSION_CYCLES}"))
    known = [str(x) for x in reference.signatures.locations]
    chosen = list(known if ports is None else ports)
    bad = [p for p in chosen if p not in known]
    if bad or not chosen or len(set(chosen)) != len(chosen):
        raise InputError(describe("--ports", chosen, f"unique locations among {known}"))
    spec = resolve_leaks(description, {chosen[0]: text})[0]
    extra: tuple[str, float, float] = ("", 0.0, 0.0)
    if second_orifice is not None:
        text2 = _orifice_text(second_orifice)
        spec2 = resolve_leaks(description, {chosen[0]: text2})[0]
        if not spec2.nominal_mass_flow_kg_s > spec.nominal_mass_flow_kg_s:
            raise InputError(
                describe("second test orifice", text2, f"an orifice larger than {text}")
            )
        extra = (text2, spec2.nominal_mass_flow_kg_s, spec2.nominal_slpm)
    return CommissioningPlan(
        reference.machine,
        tuple(chosen),
        text,
        spec.nominal_mass_flow_kg_s,
        spec.nominal_slpm,
        spec.nominal_pressure_pa,
        int(cycles),
        *extra,
    )


def _orifice_text(orifice: str | float) -> str:
    """``"1.0mm"`` or ``"2turns"`` as the plan states it; a flow or a size <= 0 is refused."""
    value, unit = parse_leak_size(orifice, "--orifice-mm/--turns")
    if unit == "SLPM" or value <= 0:
        raise InputError(
            describe("test orifice", orifice, "a nozzle diameter > 0 mm or turns > 0 of GR-3/8B")
        )
    return f"{value:g}{unit}"
