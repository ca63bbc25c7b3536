"""``LeakDiagnoser``: scikit-learn conventions, SI settings, the public face."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from sklearn.base import clone

import pneufdd
from pneufdd.diagnosis.diagnoser import LeakDiagnoser, NotFittedError
from pneufdd.diagnosis.effects.twin import SIGNATURE_SIZES_SLPM
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.diagnosis.recordings import SIGNATURE_MASS_FLOWS, signature_ladder_slpm
from pneufdd.diagnosis.reference.model import DetectionSettings
from pneufdd.errors import InputError
from pneufdd.physics.units import kg_s_to_slpm, slpm_to_kg_s


def test_clone_gives_equal_params():
    diagnoser = LeakDiagnoser(
        channels=["P_In", "Q_In"],
        max_leaks=1,
        signature_mass_flows=(slpm_to_kg_s(20.0), slpm_to_kg_s(80.0)),
        uncertainty_plants=0,
        detection=DetectionSettings(startup_cycles=2),
        localisation=LocalisationSettings(min_mass_flow=1e-4),
        workers=1,
    )
    twin = clone(diagnoser)
    assert twin is not diagnoser
    assert twin.get_params() == diagnoser.get_params()
    assert twin.get_params()["localisation"].min_mass_flow == 1e-4
    assert twin.get_params()["detection"].startup_cycles == 2
    assert twin.get_params()["signature_mass_flows"] == diagnoser.signature_mass_flows
    # clone copies the settings and learns nothing
    assert not hasattr(twin, "reference_")
    with pytest.raises(NotFittedError, match="not fitted"):
        twin.diagnose("run.parquet")


def test_params_are_the_init_arguments_unchanged():
    diagnoser = LeakDiagnoser()
    params = diagnoser.get_params()
    assert sorted(params) == sorted(
        [
            "channels",
            "max_leaks",
            "simulate_explanations",
            "signature_mass_flows",
            "signature_cycles",
            "uncertainty_plants",
            "detection",
            "localisation",
            "workers",
            "progress",
        ]
    )
    assert params["signature_mass_flows"] is SIGNATURE_MASS_FLOWS
    assert diagnoser.set_params(max_leaks=1, channels=["Q_In"]) is diagnoser
    assert (diagnoser.max_leaks, diagnoser.channels) == (1, ["Q_In"])
    assert clone(diagnoser).get_params()["max_leaks"] == 1
    with pytest.raises(ValueError, match="signature_sizes_slpm"):
        diagnoser.set_params(signature_sizes_slpm=(20.0, 80.0))


def test_default_ladder_is_si_and_simulates_the_slpm_ladder_exactly():
    # the settings are SI; the twin's leak valves are set in SLPM, converted at the edge
    assert SIGNATURE_MASS_FLOWS[0] == pytest.approx(3.0 * 1.294 / 60_000.0, rel=1e-12)
    assert signature_ladder_slpm(SIGNATURE_MASS_FLOWS) == SIGNATURE_SIZES_SLPM
    # the bare round trip is not exact; the ladder must be (the same simulations)
    assert float(kg_s_to_slpm(slpm_to_kg_s(50.0))) != 50.0
    assert signature_ladder_slpm([slpm_to_kg_s(50.0), slpm_to_kg_s(12.5)]) == (50.0, 12.5)


def test_public_face_is_lazy_and_has_simulate():
    assert "simulate" in pneufdd.__all__
    assert "LeakFinding" in pneufdd.__all__
    from pneufdd import LeakFinding, simulate
    from pneufdd.diagnosis import findings
    from pneufdd.sim import simulate as sim_simulate

    assert simulate is sim_simulate
    assert LeakFinding is findings.LeakFinding
    code = (
        "import json, sys, pneufdd; "
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('numba', 'pneufdd', 'sklearn', 'pandas'))))"
    )
    loaded = json.loads(
        subprocess.run(
            [sys.executable, "-c", code], check=True, capture_output=True, text=True
        ).stdout
    )
    assert loaded == ["pneufdd", "pneufdd._lazy"]


def test_min_mass_flow_keeps_its_pnref_key():
    # the setting says what it is; the .pnref header keeps the key files always had,
    # so files written before load with the same value
    settings = LocalisationSettings(min_mass_flow=1e-4)
    data = settings.to_dict()
    assert data["min_flow"] == 1e-4
    assert "min_mass_flow" not in data
    assert list(data) == [  # the header's key order is unchanged too
        "min_flow" if name == "min_mass_flow" else name
        for name in LocalisationSettings.__dataclass_fields__
    ]
    assert LocalisationSettings.from_dict(data) == settings
    saved_before = {**LocalisationSettings().to_dict(), "min_flow": 8.6e-5}
    assert LocalisationSettings.from_dict(saved_before).min_mass_flow == 8.6e-5
    with pytest.raises(InputError, match="min_mass_flow"):
        LocalisationSettings.from_dict({"min_mass_flow": 1e-4})
