"""Issue 14: bad input never crashes, never destroys a file, never yields a confident answer.

The quick slice of the fuzz corpus (``tests/fuzzing.py``; the full corpus is ``make
fuzz``) runs in-process; an injected internal fault exits 3 from every command; the
CLI starts without the heavy subsystems.
"""

from __future__ import annotations

import ast
import functools
import os
import subprocess
import sys
from pathlib import Path

import pytest
import typer.main

import fuzzing
import fuzzing_bounds
import fuzzing_generators
from pneufdd.cli.app import app, main


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return fuzzing.make_base(tmp_path_factory.mktemp("fuzz-base"), full=False)


def test_every_command_is_fuzzed() -> None:
    commands = fuzzing.discover_commands()
    assert {"steps", "features", "reference build", "diagnose", "simulate"} <= set(commands)
    handled = {*fuzzing.BUILDERS, *fuzzing.NOT_FUZZED, *fuzzing_generators.COMMANDS}
    missing = [c for c in commands if c not in handled]
    assert missing == [], f"add an entry to fuzzing_generators.COMMANDS for {missing}"


def test_every_command_has_a_generator_entry() -> None:
    """Every command of ``pneufdd --help``, including campaign and demo and any added
    later, has an entry in the generators' table (``tests/fuzzing_generators.py``)."""
    commands = fuzzing.discover_commands()
    assert {"campaign", "demo", "monitor", "machines"} <= set(commands)
    missing = fuzzing_generators.missing_entries(commands)
    assert missing == [], f"add an Entry to fuzzing_generators.COMMANDS for {missing}"


def test_generators_draw_every_kind_of_value_reproducibly(base, tmp_path) -> None:
    import numpy as np

    def labels(folder):
        folder.mkdir()
        kit = fuzzing_generators.Kit(base, tmp_path, folder)
        rng = np.random.default_rng(fuzzing_generators.SEED)
        return [v[0] for v in fuzzing_generators.variants("diagnose", kit, rng)]

    first, again = labels(tmp_path / "a"), labels(tmp_path / "b")
    assert first == again
    kinds = {label.split("=")[0].split("_")[0] for label in first}
    assert {"--hours", "--price", "--threads", "input", "output", "nested", "name"} <= kinds
    assert "--hours='nan'" in first
    assert "--hours='1e308'" in first
    assert {"input_fifo_rec1.parquet", "output_dangling_--json", "output_loop_--report"} <= set(
        first
    )
    # an expensive command gets only what must be refused, never a value it would run with
    folder = tmp_path / "c"
    folder.mkdir()
    kit = fuzzing_generators.Kit(base, tmp_path, folder)
    found = fuzzing_generators.variants("campaign", kit, np.random.default_rng(1))
    assert found
    assert all(allowed == {2} for _, _, allowed, _, _ in found)


def test_quick_slice_of_the_fuzz_corpus(base, tmp_path) -> None:
    cases = fuzzing.build_corpus(base, tmp_path, full=False)
    assert len(cases) >= 150
    assert {c.command for c in cases} == set(fuzzing.BUILDERS)
    outcomes = fuzzing.run_corpus(cases, in_process=True)
    summary = fuzzing.summary(outcomes)
    bad = {o.case.name: o.problems for o in outcomes if o.problems}
    assert bad == {}
    assert summary["tracebacks"] == summary["internal_errors"] == 0
    assert summary["inputs_changed"] == summary["partial_outputs"] == 0
    codes = {o.case.name: o.code for o in outcomes}
    # the cases of the issue, by name: each a clean exit 2
    for name in (
        "diagnose/json_is_run",
        "diagnose/json_is_run_overwrite",
        "diagnose/report_is_reference_overwrite",
        "diagnose/json_and_report_same",
        "features/out_is_input_overwrite",
        "reference build/out_is_input_overwrite",
        "simulate/out_is_machine_overwrite",
        "diagnose/nan_all_first_analog",
        "diagnose/huge_1e308_flow",
        "diagnose/empty_flow",
        "diagnose/analog_t0_plus_1e9",
        "diagnose/analog_at_1hz",
        "diagnose/flow_labelled_pa",
        "diagnose/missing_switch",
        "diagnose/csv_file",
        "diagnose/metadata_steps_are_ints",
        "diagnose/metadata_step_without_set",
        "diagnose/ref_header_trace_rate_hz_0",
        "diagnose/ref_huge_shape",
        "diagnose/ref_damaged_deflate",
        "simulate/toml_latin1",
        "simulate/toml_nested_arrays_10000",
        "simulate/cycles_20_digits",
        "simulate/cycles_1e6",
        "diagnose/json_is_folder",
    ):
        assert codes[name] == 2, name
    # resource bounds and accepted values that crashed (issue 39): each a clean exit 2
    for name in fuzzing_bounds.QUICK:
        assert codes[name] == 2, name
    # 1 % NaN in short bursts: repaired, and the leak-free run stays leak-free
    assert codes["diagnose/nan_bursts_1pct"] == 0


def _dummy_argv(command) -> list[str]:
    """Arguments that parse for ``command`` (its body is replaced before it runs)."""
    argv: list[str] = []
    for param in command.params:
        if not param.required:
            continue
        choices = getattr(param.type, "choices", None)
        value = str(choices[0]) if choices else "1"
        if param.param_type_name == "argument":
            argv.append(value)
        else:
            argv += [param.opts[0], value]
    return argv


def _leaf_commands() -> list:
    found = []

    def walk(cmd, path: list[str]) -> None:
        sub = getattr(cmd, "commands", None)
        if sub:
            for name, child in sorted(sub.items()):
                walk(child, [*path, name])
        else:
            found.append((path, cmd))

    walk(typer.main.get_command(app), [])
    return found


def _break_every_command(monkeypatch: pytest.MonkeyPatch) -> None:
    def faulty(func):
        @functools.wraps(func)
        def broken(*args, **kwargs):
            raise ZeroDivisionError("injected fault")

        return broken

    infos = list(app.registered_commands)
    for group in app.registered_groups:
        infos += group.typer_instance.registered_commands
    for info in infos:
        monkeypatch.setattr(info, "callback", faulty(info.callback))


def test_internal_fault_exits_3_from_every_command(monkeypatch, capsys) -> None:
    commands = _leaf_commands()
    assert len(commands) >= 8
    _break_every_command(monkeypatch)
    for path, command in commands:
        code = main([*path, *_dummy_argv(command)])
        err = capsys.readouterr().err
        assert code == 3, (path, err)
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1, err
        assert "internal error: ZeroDivisionError: injected fault" in err
        assert "--debug" in err
        assert "Traceback" not in err


def test_debug_shows_the_traceback(monkeypatch, capsys) -> None:
    _break_every_command(monkeypatch)
    assert main(["--debug", "machines"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" in err
    assert "injected fault" in err


def test_internal_fault_in_a_real_process_exits_3(tmp_path) -> None:
    # a library function the command calls fails: the process exits 3, not 1
    script = (
        "import sys, pneufdd.sim.loading as loading\n"
        "def broken(*a, **k):\n"
        "    raise KeyError('injected')\n"
        "loading.builtin_machines = broken\n"
        "import pneufdd.sim\n"
        "pneufdd.sim.__dict__.pop('builtin_machines', None)\n"
        "from pneufdd.cli.app import main\n"
        "sys.exit(main(['machines']))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=False, cwd=tmp_path
    )
    assert proc.returncode == 3, proc.stderr
    assert "internal error: KeyError" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_usage_errors_stay_2() -> None:
    assert main(["diagnose"]) == 2
    assert main(["simulate", "--cycles", "many"]) == 2
    assert main(["no-such-command"]) == 2


def test_import_pneufdd_and_the_cli_stay_light() -> None:
    heavy = ("sklearn", "matplotlib", "pandas", "numba", "scipy", "pyarrow", "pywt")
    script = (
        "import sys, pneufdd, pneufdd.cli.app\n"
        "from pneufdd.cli.app import main\n"
        "main(['--version'])\n"
        f"print(sorted(m for m in {heavy!r} if m in sys.modules))\n"
    )
    env = dict(os.environ)
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, env=env
    )
    assert proc.stdout.splitlines()[-1] == "[]"


def _loaded_after(args: list[str], modules: tuple[str, ...]) -> list[str]:
    """Which of ``modules`` a fresh interpreter holds after ``pneufdd ARGS`` (exit 0)."""
    script = (
        "import sys, io, contextlib\n"
        "from pneufdd.cli.app import main\n"
        "quiet = io.StringIO()\n"
        "with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):\n"
        f"    code = main({args!r})\n"
        "assert code == 0, quiet.getvalue()\n"
        f"print(sorted(m for m in {modules!r} if m in sys.modules))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    loaded: list[str] = ast.literal_eval(proc.stdout.splitlines()[-1])
    return loaded


def test_machines_command_imports_no_numerics() -> None:
    assert _loaded_after(["machines"], ("numpy", "numba", "pydantic")) == []


def test_simulate_command_imports_only_what_a_simulation_needs(tmp_path: Path) -> None:
    """`pneufdd simulate` needs numba and pyarrow, not scipy.signal (0.5 s), the learners,
    or pandas (0.3 s, which ``pyarrow.array`` would import to check its argument)."""
    out = tmp_path / "run.parquet"
    heavy = ("scipy.signal", "scipy.stats", "sklearn", "matplotlib", "pywt", "pandas")
    args = ["simulate", "--machine", "press-fit-cell", "--out", str(out)]
    assert _loaded_after(args, heavy) == []
    assert out.stat().st_size > 0


def test_a_commands_peak_memory_is_its_own_not_the_harness(tmp_path) -> None:
    """``make fuzz`` reports each command's own peak resident set. wait4's ru_maxrss also
    held the forked copy of the harness (2 GB with its corpus: every command seemed to use
    1.8 GB); the peak is now the command's VmHWM, checked against GNU time as oracle."""
    import shutil
    import time

    ballast = bytearray(400 * 2**20)  # the harness holding a corpus
    ballast[::4096] = b"x" * len(ballast[::4096])  # resident, not just mapped
    case = fuzzing.Case("machines/list", "machines", ["machines"], tmp_path, [], [], frozenset({0}))
    outcome = fuzzing.run_case(case, in_process=False)
    assert outcome.code == 0, outcome.stderr
    assert outcome.problems == []
    assert outcome.peak_rss is not None
    assert 5 * 2**20 < outcome.peak_rss < 200 * 2**20  # the command's, far below the ballast
    assert outcome.cpu_s is not None
    assert 0.0 < outcome.cpu_s < outcome.seconds * 2 + 1.0  # its own CPU, both cores at most
    time_exe = shutil.which("time", path="/usr/bin")
    if time_exe is None:
        return
    exe = str(Path(sys.executable).with_name("pneufdd"))
    started = time.perf_counter()
    proc = subprocess.run([time_exe, "-v", exe, "machines"], capture_output=True, text=True,
                          check=True, cwd=tmp_path)  # fmt: skip
    assert time.perf_counter() > started
    line = next(x for x in proc.stderr.splitlines() if "Maximum resident set size" in x)
    oracle = int(line.split(":")[1]) * 1024
    assert abs(outcome.peak_rss - oracle) < 0.3 * oracle
    del ballast
