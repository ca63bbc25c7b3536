"""``LeakDiagnoser``: the public face of leak diagnosis, fitted once per machine.

It follows scikit-learn's conventions: settings are stored by ``__init__`` as given
(``get_params``, ``set_params`` and :func:`sklearn.base.clone` work),
:meth:`LeakDiagnoser.fit` learns from leak-free recordings of one machine and returns
the diagnoser, learned attributes end in ``_`` (``reference_``), and
:meth:`LeakDiagnoser.diagnose` refuses to run before ``fit``. The fitted state is the
reference model, saved and loaded as a ``.pnref`` file (JSON header + arrays, never
pickle).

The class's docstring has a worked example.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from sklearn.base import BaseEstimator

from pneufdd.diagnosis.cost import CostSettings
from pneufdd.diagnosis.effects.twin import UNCERTAINTY_PLANTS
from pneufdd.diagnosis.engine import diagnose
from pneufdd.diagnosis.findings import Diagnosis
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.diagnosis.machine import MachineLike
from pneufdd.diagnosis.recordings import (
    SIGNATURE_MASS_FLOWS,
    build_reference_from_recordings,
    run_table,
)
from pneufdd.diagnosis.reference.file import load_reference, save_reference
from pneufdd.diagnosis.reference.model import DetectionSettings, ReferenceModel
from pneufdd.errors import InputError, describe
from pneufdd.progress import Progress
from pneufdd.recording.model import Recording

__all__ = ["LeakDiagnoser", "NotFittedError"]

RecordingLike = Recording | str | Path


class NotFittedError(InputError):
    """``diagnose`` or ``save`` was called before ``fit`` (or ``load``)."""


def _recordings(items: Sequence[RecordingLike]) -> tuple[list[Recording], list[str]]:
    recordings, names = [], []
    for k, item in enumerate(items):
        if isinstance(item, Recording):
            recordings.append(item)
            names.append(f"recording {k + 1}")
        elif isinstance(item, str | Path):
            recordings.append(Recording.read(Path(item)))
            names.append(str(item))
        else:
            raise InputError(
                describe(
                    f"leak-free recording {k + 1}", type(item).__name__, "a Recording or a path"
                )
            )
    return recordings, names


class LeakDiagnoser(BaseEstimator):  # type: ignore[misc]
    """Detect, locate, size and cost compressed-air leaks on one machine.

    Parameters
    ----------
    channels : sequence of str, optional
        Analog channels of the sensor set (``["P_In", "Q_In"]``: the supply meter);
        None uses every analog channel of the recordings, an empty sequence only the
        PLC's digital signals.
    max_leaks : int or None
        Largest number of simultaneous leaks considered; None (the default): as many
        as the evidence supports, up to every location and
        :data:`~pneufdd.limits.MAX_LEAKS` [-].
    simulate_explanations : bool
        When the leak signatures do not explain a run (typically two large leaks),
        check the best explanations with the machine's digital twin.
    signature_mass_flows : sequence of float
        Ladder of leak flows simulated per location, at the nominal supply pressure
        (:data:`~pneufdd.diagnosis.recordings.SIGNATURE_MASS_FLOWS`; a ladder in SLPM is
        ``[slpm_to_kg_s(x) for x in sizes]``, :mod:`pneufdd.physics.units`) [kg/s].
    signature_cycles : int
        Simulated cycles per signature point [-].
    uncertainty_plants : int
        Plausible plants drawn around the machine description to measure how far a
        real machine's leak effects may differ from the twin's (0: trust the twin
        exactly) [-].
    detection : DetectionSettings, optional
        Detector tuning (false-alarm rate, fluctuation directions, band method).
    localisation : LocalisationSettings, optional
        Tuning of location and sizing; ``max_leaks`` and ``simulate_explanations``
        above take precedence over its fields of the same name.
    workers : int, optional
        Processes simulating signatures in parallel (default: one per CPU).
    progress : callable, optional
        ``progress(task, done, total)`` while fitting (:mod:`pneufdd.progress`).

    Attributes
    ----------
    reference_ : ReferenceModel
        The leak-free reference learned by :meth:`fit`: detector statistics, the
        machine description, leak signatures and settings.

    Examples
    --------
    Fit on two short leak-free runs of the press-fit cell's digital twin (a small
    ladder, no plausible plants, to keep it quick) and diagnose a run with one leak:

    >>> from pneufdd import LeakDiagnoser, simulate
    >>> from pneufdd.physics.units import slpm_to_kg_s
    >>> leak_free = [simulate("press-fit-cell", cycles=6, seed=s) for s in (1, 2)]
    >>> diagnoser = LeakDiagnoser(
    ...     channels=["P_In", "Q_In"],
    ...     signature_mass_flows=[slpm_to_kg_s(20.0), slpm_to_kg_s(80.0)],
    ...     signature_cycles=1,
    ...     uncertainty_plants=0,
    ...     workers=1,
    ... ).fit(leak_free)
    >>> run = simulate("press-fit-cell", cycles=8, leaks={"FEED_A": "50slpm"}, seed=3)
    >>> result = diagnoser.diagnose(run)
    >>> [str(leak.location) for leak in result.leaks]
    ['FEED_A']
    >>> 40.0 < result.leaks[0].flow_slpm < 60.0
    True
    """

    def __init__(
        self,
        channels: Sequence[str] | None = None,
        max_leaks: int | None = None,
        simulate_explanations: bool = True,
        signature_mass_flows: Sequence[float] = SIGNATURE_MASS_FLOWS,
        signature_cycles: int = 2,
        uncertainty_plants: int = UNCERTAINTY_PLANTS,
        detection: DetectionSettings | None = None,
        localisation: LocalisationSettings | None = None,
        workers: int | None = None,
        progress: Progress | None = None,
    ) -> None:
        self.channels = channels
        self.max_leaks = max_leaks
        self.simulate_explanations = simulate_explanations
        self.signature_mass_flows = signature_mass_flows
        self.signature_cycles = signature_cycles
        self.uncertainty_plants = uncertainty_plants
        self.detection = detection
        self.localisation = localisation
        self.workers = workers
        self.progress = progress

    def _localisation_settings(self) -> LocalisationSettings:
        return replace(
            self.localisation or LocalisationSettings(),
            max_leaks=self.max_leaks,
            simulate_explanations=self.simulate_explanations,
        )

    def fit(
        self,
        recordings: Sequence[RecordingLike],
        machine: MachineLike | None = None,
    ) -> LeakDiagnoser:
        """Learn the leak-free reference of one machine from its recordings.

        Parameters
        ----------
        recordings : sequence of Recording or path
            Leak-free recordings of one machine; together at least 10 complete
            cycles.
        machine : str, Path, MachineDescription or mapping, optional
            The machine's description (``docs/machine-format.md``; a built-in name
            is a shorthand). Needed when the recordings carry none (CSV, TDMS
            exports); without any, leaks are detected but not located or sized.

        Returns
        -------
        LeakDiagnoser
            ``self``, fitted.
        """
        if isinstance(recordings, Recording | str | Path):
            raise InputError(
                describe("recordings", type(recordings).__name__, "a list of recordings or paths")
            )
        loaded, names = _recordings(recordings)
        self.reference_ = build_reference_from_recordings(
            loaded,
            None if self.channels is None else tuple(self.channels),
            names,
            machine=machine,
            signature_cycles=self.signature_cycles,
            signature_mass_flows=tuple(float(x) for x in self.signature_mass_flows),
            uncertainty_plants=self.uncertainty_plants,
            settings=self.detection,
            localisation=self._localisation_settings(),
            progress=self.progress,
            workers=self.workers,
        )
        return self

    def _fitted(self) -> ReferenceModel:
        reference: ReferenceModel | None = getattr(self, "reference_", None)
        if reference is None:
            raise NotFittedError(
                "this LeakDiagnoser is not fitted: call fit(leak_free_recordings) or "
                "LeakDiagnoser.load('reference.pnref') first"
            )
        return reference

    def diagnose(self, recording: RecordingLike, cost: CostSettings | None = None) -> Diagnosis:
        """Detect, locate, size and cost the leaks of one run.

        Parameters
        ----------
        recording : Recording or path
            A run of the machine (complete cycles are judged; 10 make a good run).
        cost : CostSettings, optional
            Operating hours, electricity price and compressor efficiency of eq. 1.1.

        Returns
        -------
        Diagnosis
        """
        reference = self._fitted()
        if isinstance(recording, Recording):
            run, where = recording, "run"
        else:
            run, where = Recording.read(Path(recording)), str(recording)
        table = run_table(reference, run, where)
        return diagnose(reference, table, cost, reference.localisation)

    def save(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write the fitted reference to a ``.pnref`` file (atomically)."""
        return save_reference(self._fitted(), path, overwrite=overwrite)

    @classmethod
    def load(cls, path: str | Path) -> LeakDiagnoser:
        """A fitted diagnoser from a ``.pnref`` file, with the settings it was built with."""
        reference = load_reference(path)
        diagnoser = cls(
            channels=reference.channels,
            max_leaks=reference.localisation.max_leaks,
            simulate_explanations=reference.localisation.simulate_explanations,
            detection=reference.settings,
            localisation=reference.localisation,
        )
        diagnoser.reference_ = reference
        return diagnoser

    def __repr__(self) -> str:
        fitted = getattr(self, "reference_", None)
        state = f"fitted on {fitted.machine!r}" if fitted is not None else "not fitted"
        return (
            f"LeakDiagnoser(channels={self.channels!r}, max_leaks={self.max_leaks}, "
            f"simulate_explanations={self.simulate_explanations}) [{state}]"
        )
