"""The prebuilt twin (numba.pycc, ahead of time) against numba's JIT: same numbers.

One real build (about 15 s: numba's ahead-of-time compiler and gcc) into a temporary
directory; the comparisons run in fresh processes, one that uses the prebuilt module
and one told to use the JIT (``PNEUFDD_PREBUILT=0``).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pneufdd.cli.app import main
from pneufdd.sim.prebuilt import (
    _prebuilt_twin,
    argument_layout,
    build_key,
    build_prebuilt_twin,
    load_prebuilt_twin,
    prebuilt_directory,
    prebuilt_path,
)

pytestmark = pytest.mark.skipif(
    (shutil.which("gcc") is None and shutil.which("cc") is None)
    or not (Path(sysconfig.get_paths()["include"]) / "Python.h").is_file(),
    reason="building the prebuilt twin needs a C compiler and Python's headers",
)

_RUN = r"""
import hashlib, json, sys
import numpy as np
from pneufdd.sim import run_simulation
from pneufdd.sim.prebuilt import compiled_twin

case = json.loads(sys.argv[1])
extra = {}
if case.get("faults"):
    extra["faults"] = case["faults"]
if case.get("ambient"):
    from pneufdd.sim.nuisances import nuisances_from_options
    options = (case["ambient"], None, case["payload"], case["dips"])
    extra["nuisances"] = nuisances_from_options(*options)
result = run_simulation("festo-dsd", cycles=2, leaks=case.get("leaks") or None, seed=11, **extra)
digests = {}
for name in result.recording.channels:
    time, values = result.recording.channel(name)
    data = np.ascontiguousarray(time).tobytes() + np.ascontiguousarray(values).tobytes()
    digests[name] = hashlib.sha256(data).hexdigest()
for name, values in sorted(result.outputs.items()):
    digests["outputs." + name] = hashlib.sha256(np.ascontiguousarray(values).tobytes()).hexdigest()
digests["strokes"] = hashlib.sha256(repr(result.strokes).encode()).hexdigest()
print(json.dumps({"origin": compiled_twin().origin, "numba": "numba" in sys.modules,
                  "kernel": "pneufdd.sim.kernel" in sys.modules, "digests": digests}))
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("prebuilt")
    older = directory / "pneufdd_twin_0000.cpython-311-x86_64-linux-gnu.so"
    older.write_bytes(b"an older build")
    path = build_prebuilt_twin(directory)
    assert path == prebuilt_path(directory)
    assert not older.exists()  # building replaces the older builds
    return directory


def _run(directory: Path, case: dict[str, Any], prebuilt: bool) -> dict[str, Any]:
    env = dict(os.environ, PNEUFDD_PREBUILT_DIR=str(directory))
    env["PNEUFDD_PREBUILT"] = "1" if prebuilt else "0"
    done = subprocess.run(
        [sys.executable, "-c", _RUN, json.dumps(case)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    result: dict[str, Any] = json.loads(done.stdout)
    return result


_FAULTS = {
    "faults": [
        "DNC=piston-leak:15slpm", "DNC_B=valve-leak-in:5slpm", "DNC_A=throttle:-30%",
        "DRQD=friction:+40%", "DGPL=valve-pilot:4.5bar", "DNC_B=cushion:0.02cv",
        "S_SLT_B=late:30ms", "supply=regulator:-0.2bar",
    ],
    "ambient": "15C..35C/30s",
    "payload": ["DNC=+1kg@10s"],
    "dips": "depth=2bar,duration=2s,rate=360/h,seed=2",
}  # fmt: skip
"""Every fault's and nuisance's branch of the kernel at once (issue 34)."""


@pytest.mark.parametrize(
    "case",
    [{}, {"leaks": {"DNC_B": 3}}, {"leaks": {"supply": "30slpm", "DNC_A": "1.2mm"}}, _FAULTS],
)
def test_prebuilt_twin_records_what_the_jit_records(built: Path, case: dict[str, Any]) -> None:
    prebuilt = _run(built, case, prebuilt=True)
    jit = _run(built, case, prebuilt=False)
    assert prebuilt["origin"] == str(prebuilt_path(built))
    assert jit["origin"] == "jit"
    assert len(prebuilt["digests"]) > 40  # 2 x 2 x 6 + supply channels, outputs, strokes
    assert prebuilt["digests"] == jit["digests"]
    # without a leak the prebuilt twin's process never imports numba, and no call fell
    # back to the JIT's kernel (its arguments had the layout the module is typed for)
    assert prebuilt["numba"] is (len(case) > 0)
    assert prebuilt["kernel"] is False
    assert jit["numba"] is True


def test_prebuilt_twin_is_found_only_under_the_sources_key(built: Path, tmp_path: Path) -> None:
    module = load_prebuilt_twin(built)
    assert module is not None
    assert callable(module.run_cycle)
    assert callable(module.first_order_recursion)
    assert callable(module.sensor_reading)
    assert callable(module.truth_rows)
    assert prebuilt_path(built).name.startswith("pneufdd_twin_" + build_key()[:24])
    # the same module under another key (other sources) is not loaded
    other = tmp_path / prebuilt_path(built).name.replace(build_key()[:24], "f" * 24)
    shutil.copy(prebuilt_path(built), other)
    assert load_prebuilt_twin(tmp_path) is None
    assert load_prebuilt_twin(tmp_path / "missing") is None


def test_build_twin_command_reports_an_up_to_date_build(
    built: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["build-twin", "--dir", str(built)]) == 0
    assert f"up to date: {prebuilt_path(built)}" in " ".join(capsys.readouterr().out.split())


def test_prebuilt_directory_follows_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PNEUFDD_PREBUILT_DIR", "/somewhere/else")
    assert prebuilt_directory() == Path("/somewhere/else")
    monkeypatch.delenv("PNEUFDD_PREBUILT_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", "/xdg")
    assert prebuilt_directory() == Path("/xdg/pneufdd/prebuilt")
    # numba's cache (the Makefile's .numba_cache) does not move it: `make demo` builds
    # where a plain shell looks (issue 31)
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/numba/cache")
    assert prebuilt_directory() == Path("/xdg/pneufdd/prebuilt")
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", "/home/someone")
    assert prebuilt_directory() == Path("/home/someone/.cache/pneufdd/prebuilt")


def test_prebuilt_functions_run_only_on_their_argument_layout(built: Path) -> None:
    module = load_prebuilt_twin(built)
    assert module is not None
    twin = _prebuilt_twin(module)
    # float32 samples: the ahead-of-time wrapper would read them as float64; the guard
    # hands them to the JIT, which compiles for them (y = x/2 + y/2)
    samples = np.ones(4, dtype=np.float32)
    assert argument_layout((samples, 0.5, 0.5)) != argument_layout((np.ones(4), 0.5, 0.5))
    np.testing.assert_allclose(
        twin.first_order_recursion(samples, 0.5, 0.5), [0.5, 0.75, 0.875, 0.9375]
    )
    assert twin.first_order_recursion(np.ones(3), 0.5, 0.5).tolist() == [0.5, 0.75, 0.875]


def test_prebuilt_wrappers_release_the_gil(built: Path) -> None:
    # numba's wrappers release the GIL with PyEval_SaveThread (the JIT's nogil=True);
    # a pycc module built without the release_gil flag never references it (checked
    # on a build without it: only PyGILState_Ensure/Release appear)
    assert b"PyEval_SaveThread" in prebuilt_path(built).read_bytes()
    assert b"PyEval_RestoreThread" in prebuilt_path(built).read_bytes()
