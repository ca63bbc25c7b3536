"""Issue 39: resource bounds before work, and accepted values that crashed.

Each case of the issue, with the outcome it now has: exit 2 and a message naming the
option, file or field and the limit (``docs/limits.md``). The fuzz corpus holds them
too (``tests/fuzzing_bounds.py``); here each is asserted exactly.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import sqlite3
from pathlib import Path

import numpy as np
import pytest

import fuzzing
import fuzzing_bounds
from pneufdd import limits
from pneufdd.cli.app import main
from pneufdd.errors import FileFormatError, InputError, MachineError, describe


def run(argv: list[str], folder: Path) -> tuple[int, str]:
    """``pneufdd argv`` in ``folder``: its exit code and its stderr on one line."""
    err = io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main([str(a) for a in argv])
    finally:
        os.chdir(cwd)
    return code, " ".join(err.getvalue().split())


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return fuzzing.make_base(tmp_path_factory.mktemp("limits-base"), full=False)


@pytest.fixture(scope="module")
def diagnose_cases(base, tmp_path_factory: pytest.TempPathFactory) -> dict[str, fuzzing.Case]:
    folder = tmp_path_factory.mktemp("limits-diagnose")
    return {c.name: c for c in fuzzing_bounds._cases_diagnose(base, folder, full=True)}


# ------------------------------------------------------------- the module


def test_json_depth_is_checked_without_recursion() -> None:
    limits.check_json_depth('{"a": [[["[[[[[[[[[[[["]]]}', "x")  # brackets in strings
    limits.check_json_depth("[" * 64 + "]" * 64, "x")
    with pytest.raises(FileFormatError, match=r"meta: nesting .* at most 64 levels"):
        limits.check_json_depth("[" * 100_000 + "]" * 100_000, "meta")


def test_small_text_files_are_regular_and_capped(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match=r"'/dev/zero': kind of file.*a regular file"):
        limits.read_text_capped(Path("/dev/zero"), "tag map")
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (limits.MAX_TEXT_FILE_BYTES + 1))
    with pytest.raises(FileFormatError, match=r"size \[bytes\].*<= 4,194,304"):
        limits.read_text_capped(big, "tag map")


def test_messages_are_clipped() -> None:
    message = describe("columns", [f"c{i}" for i in range(100_000)], "mapped")
    assert len(message) < 1_000
    assert "characters ...]" in message
    assert len(limits.clip_message("x" * 10**6)) <= limits.MAX_MESSAGE_CHARS + 10


def test_counts_and_memory_name_the_limit() -> None:
    with pytest.raises(InputError, match=r"--uncertainty-plants: received 1000000000.*1,000"):
        limits.check_count("--uncertainty-plants", 10**9, limits.MAX_UNCERTAINTY_PLANTS)
    with pytest.raises(InputError, match=r"needs about 58.3 GB.*at most 1.6 GB"):
        limits.check_memory("--cycles", 5.83e10)
    with pytest.raises(InputError, match="unbounded"):
        limits.check_memory("--cycles", math.inf)


# ------------------------------------------------------------ the commands


def test_simulate_and_vector_map_refuse_runs_past_the_memory_budget(tmp_path: Path) -> None:
    code, text = run(["simulate", "--machine", "press-fit-cell", "--cycles", "100000",
                      "--out", "s.parquet"], tmp_path)  # fmt: skip
    assert code == 2
    assert "cycles (--cycles): 100,000 cycles of 3.2 s" in text
    assert re.search(r"needs about 5\d\.\d GB of memory; allowed: at most 1\.6 GB", text)
    assert not (tmp_path / "s.parquet").exists()
    code, text = run(["vector-map", "--cycles", "100000", "--out", "vm"], tmp_path)
    assert code == 2
    assert "cycles (--cycles): 100,002 cycles" in text
    assert "at most 1.6 GB" in text


def test_reference_build_bounds_plants_and_signature_cycles(base, tmp_path: Path) -> None:
    ref = base["ref"]
    code, text = run(["reference", "build", ref, "--out", "r.pnref",
                      "--uncertainty-plants", "1000000000"], tmp_path)  # fmt: skip
    assert code == 2
    assert "--uncertainty-plants: received 1000000000; allowed: an integer from 0 to 1,000" in text
    code, text = run(["reference", "build", ref, "--out", "r.pnref",
                      "--signature-cycles", "100000000"], tmp_path)  # fmt: skip
    assert code == 2
    assert "--signature-cycles: received 100000000; allowed: an integer from 1 to 100" in text


@pytest.mark.parametrize(
    ("option", "value", "shown"),
    [
        ("--run-cycles", "100000000", "campaign run_cycles (--run-cycles): received 100000000; "
         "allowed: an integer from 1 to 10,000"),
        ("--uncertainty-plants", "1000000000", "campaign uncertainty_plants "
         "(--uncertainty-plants): received 1000000000; allowed: an integer from 0 to 1,000"),
        ("--leak-free-runs", "1000000000", "campaign leak_free_runs (--leak-free-runs): "
         "received 1000000000; allowed: an integer from 0 to 10,000"),
    ],
)  # fmt: skip
def test_campaign_counts_are_bounded(tmp_path: Path, option: str, value: str, shown: str) -> None:
    code, text = run(["campaign", "--machine", "press-fit-cell", "--out", "c", option, value],
                     tmp_path)  # fmt: skip
    assert code == 2
    assert shown in text
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("ref_n_cycles_1e6", ["'n_cycles' x 'feature_names' (1,000,000 x",
                              "of memory; allowed: at most 1.6 GB"]),
        ("ref_n_cycles_1e9", ["header field 'n_cycles': received 1000000000",
                              "an integer from 1 to 1,000,000"]),
        ("ref_false_alarm_rate_nan", ["'false_alarm_rate': received nan",
                                      "a probability > 0 and <= 0.5"]),
        ("ref_false_alarm_rate_0", ["'false_alarm_rate': received 0.0"]),
        ("ref_false_alarm_rate_-1", ["'false_alarm_rate': received -1.0"]),
        ("ref_false_alarm_rate_1.5", ["'false_alarm_rate': received 1.5"]),
        ("ref_band_eps_nan", ["'band_eps': received nan", "<= 10 standard deviations"]),
        ("ref_n_nuisance_-5", ["'n_nuisance': received -5", "an integer from 0 to 1000"]),
        ("ref_features_1e308", ["values of 'features'", "magnitude <= 1e+12"]),
        ("ref_band_3e7_samples", ["its arrays (", "bytes uncompressed): needs about",
                                  "allowed: at most 1.6 GB"]),
    ],
)  # fmt: skip
def test_pnref_headers_settings_and_values_are_validated(
    diagnose_cases, name: str, words: list[str]
) -> None:
    case = diagnose_cases[f"diagnose/{name}"]
    code, text = run(case.argv, case.folder)
    assert code == 2
    assert f"reference file '{name}.pnref'" in text
    for word in words:
        assert word in text


def test_parquet_samples_are_checked_against_memory_before_reading(
    base, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pneufdd.recording import parquet

    # the real case (6e7 samples in 0.4 MB) needs 0.5 GB to write: scale the factor instead
    monkeypatch.setattr(parquet, "READ_BYTES_PER_BYTE", 10**5)
    code, text = run(["steps", base["run"]], tmp_path)
    assert code == 2
    assert f"file '{base['run']}': samples declared by its channels" in text
    assert "of memory; allowed: at most 1.6 GB" in text


def test_nested_parquet_metadata_is_refused(base, tmp_path: Path) -> None:
    deep = tmp_path / "deep.parquet"
    deep.write_bytes(fuzzing_bounds._nested_metadata(base["run"], 100_000))
    for argv in (["steps", deep], ["diagnose", deep, "--reference", base["pnref"]]):
        code, text = run(argv, tmp_path)
        assert code == 2
        assert "'pneufdd.recording' metadata: nesting of JSON objects and arrays" in text
        assert "at most 64 levels" in text


def test_tag_maps_are_bounded_and_roles_matched_whole(base, tmp_path: Path) -> None:
    cases = {c.name: c for c in fuzzing_bounds._cases_tag_maps(base, tmp_path, full=False)}
    expected = {
        "steps/map_role_newline": "columns.'B_P1'.role: received 'P_In\\n'",
        "steps/map_basis_list": ".basis: received [1]; allowed: 'ANR', 'SLPM'",
        "steps/map_rate_hz_inf": "rate_hz: received inf; allowed: 50 to 1e+07 Hz",
        "steps/map_size_5mb": "size [bytes]: received 5",
        "steps/map_dev_zero": "'/dev/zero' is not a regular file",
        "import/map_nested_100k": "nested too deep",
        "import/rate_1ghz": "sample rate of channel 'P_In': received '1e+09 Hz'; allowed: 50 to",
    }
    for name, shown in expected.items():
        code, text = run(cases[name].argv, cases[name].folder)
        assert code == 2, name
        assert shown in text, (name, text)
    code, text = run(cases["steps/map_unmapped_1mb"].argv, cases["steps/map_unmapped_1mb"].folder)
    assert code == 2
    assert len(text) < 2_000


def test_import_is_linear_in_ignored_columns(tmp_path: Path) -> None:
    from pneufdd.recording import csv as csv_module

    ignored = [f"ign{i}" for i in range(csv_module.WIDE_COLUMNS + 10)]
    rows = "".join(f"{i / 1000:.3f},6.0,{(i // 100) % 2}," + ",".join("0" * len(ignored)) + "\n"
                   for i in range(300))  # fmt: skip
    (tmp_path / "w.csv").write_text(",".join(["t", "P", "Y", *ignored]) + "\n" + rows)
    (tmp_path / "w.toml").write_text(
        "ignore = [" + ",".join(f'"{c}"' for c in ignored) + "]\n"
        '[columns]\nt = { role = "time", unit = "s" }\nP = { role = "P_In", unit = "bar" }\n'
        'Y = "U_FEED_A"\n'
    )
    code, text = run(["import", "w.csv", "--map", "w.toml", "--out", "w.parquet"], tmp_path)
    assert code == 0, text
    # a row with too many fields is still refused when only the mapped columns are parsed
    with (tmp_path / "w.csv").open("a") as handle:
        handle.write("0.300,6.0,1," + ",".join("0" * (len(ignored) + 1)) + "\n")
    code, text = run(["import", "w.csv", "--map", "w.toml", "--out", "w2.parquet"], tmp_path)
    assert code == 2
    assert f"line 302 has {len(ignored) + 4} fields" in text


@pytest.mark.parametrize(
    ("key", "value", "shown"),
    [
        ("meter_out_cv", "1e-300", "meter_out_cv: received 1e-300; allowed: 0 (none) or from "
         "0.0001 to 50"),
        ("meter_out_cv_a", "1e-300", "meter_out_cv_a: received 1e-300"),
        ("moving_mass_kg", "1e-300", "moving_mass_kg: received 1e-300"),
        ("static_friction_n", "1e308", "static_friction_n: received 1e+308"),
    ],
)  # fmt: skip
def test_machine_parameters_have_physical_ranges(
    base, tmp_path: Path, key: str, value: str, shown: str
) -> None:
    toml = tmp_path / "m.toml"
    toml.write_bytes(fuzzing_bounds._first_actuator_set(base["toml"].read_text(), key, value))
    code, text = run(["simulate", "--machine", toml, "--cycles", "1", "--out", "s.parquet"],
                     tmp_path)  # fmt: skip
    assert code == 2
    assert "actuator[0]." + shown in text


def test_machine_actuator_count_is_bounded(base) -> None:
    import tomllib

    from pneufdd.sim.description import parse_description

    text = fuzzing_bounds._many_actuators(base["toml"].read_text(), 3_500_000).decode()
    with pytest.raises(MachineError, match=r"actuator \(count\): received '\d{1,3},?\d* tables'; "
                       r"allowed: at most 64"):  # fmt: skip
        parse_description(tomllib.loads(text), "many.toml")


@pytest.mark.parametrize(
    ("query", "shown"),
    [
        ("chunk=1e-300", "replay chunk [s] (replay:...?chunk=): received 1e-300; allowed: "
         "0.001 to 3600 s"),
        ("speed=1e-300", "replay speed (replay:...?speed=): received 1e-300; allowed: 0.1 to"),
        ("speed=nan", "replay speed (replay:...?speed=): received nan"),
    ],
)  # fmt: skip
def test_replay_options_are_bounded(base, tmp_path: Path, query: str, shown: str) -> None:
    code, text = run(["monitor", "--reference", base["pnref"], "--source",
                      f"replay:{base['run']}?{query}", "--once", "--history",
                      "sqlite:///h.db"], tmp_path)  # fmt: skip
    assert code == 2
    assert shown in text


def test_monitor_arl0_and_read_only_history(base, tmp_path: Path) -> None:
    argv = ["monitor", "--reference", base["pnref"], "--source",
            f"replay:{base['run']}?speed=max", "--once"]  # fmt: skip
    code, text = run([*argv, "--history", "sqlite:///h.db", "--arl0", "inf"], tmp_path)
    assert code == 2
    assert "in-control average run length (--arl0) [cycles]: received inf; allowed: > 1 and " \
           "<= 1e+09" in text  # fmt: skip
    code, _ = run([*argv, "--history", "sqlite:///w.db"], tmp_path)
    assert code in (0, 1)
    code, text = run([*argv, "--history", "sqlite:///file:w.db?mode=ro&uri=true"], tmp_path)
    assert code == 2
    assert "a database this user may write (attempt to write a readonly database)" in text
    with sqlite3.connect(tmp_path / "w.db") as conn:  # nothing recorded twice, nothing lost
        assert conn.execute("select count(*) from cycles").fetchone()[0] > 0


def test_cost_settings_are_bounded(base, tmp_path: Path) -> None:
    for option, value, shown in (
        ("--hours", "1e308", "hours (--hours): received 1e+308; allowed: 0 to 8784"),
        ("--price", "inf", "price_per_kwh (--price): received inf; allowed: 0 to 100"),
        ("--kw-per-100cfm", "1e9", "kw_per_100_cfm (--kw-per-100cfm): received 1000000000.0"),
        ("--repair-fitting", "-1", "repair_fitting (--repair-fitting): received -1.0; allowed: 0"),
        ("--repair-seal", "nan", "repair_seal (--repair-seal): received nan"),
        ("--seal-share", "1.5", "seal_share (--seal-share): received 1.5; allowed: 0 to 1 "),
        (
            "--threads",
            "100000000",
            "--threads: received 100000000; allowed: an integer from 1 to 1,024",
        ),
        ("--workers", "100000000", "--workers: received 100000000"),
    ):
        code, text = run(["diagnose", base["run"], "--reference", base["pnref"],
                          "--no-simulate", option, value], tmp_path)  # fmt: skip
        assert code == 2, text
        assert shown in text, text


def test_globs_do_not_follow_symlink_loops(base, tmp_path: Path) -> None:
    from pneufdd.diagnosis.batch import expand_runs

    loop = tmp_path / "loop" / "a" / "b"
    loop.mkdir(parents=True)
    (loop.parent / "run.parquet").write_bytes(base["run"].read_bytes())
    os.symlink("..", loop / "up")
    os.symlink("../..", loop / "up2")
    os.symlink(".", loop / "self")
    found = expand_runs([str(tmp_path / "loop" / "**" / "*.parquet")])
    assert found == [tmp_path / "loop" / "a" / "run.parquet"]


def test_detection_settings_are_validated_in_python_too() -> None:
    from pneufdd.diagnosis.reference.model import DetectionSettings

    with pytest.raises(InputError, match="'false_alarm_rate': received nan"):
        DetectionSettings(false_alarm_rate=float("nan"))
    with pytest.raises(InputError, match="'band_eps': received inf"):
        DetectionSettings(band_eps=math.inf)
    assert DetectionSettings().to_dict()["false_alarm_rate"] == 0.001
    assert json.loads(json.dumps(DetectionSettings().to_dict()))["n_nuisance"] == 2
    assert np.isfinite(DetectionSettings().band_eps)


def test_mqtt_payloads_are_bounded() -> None:
    from pneufdd.monitor.sources import parse_payload

    with pytest.raises(FileFormatError, match=r"MQTT payload: nesting .* at most 64 levels"):
        parse_payload("[" * 100_000 + "]" * 100_000)
    slow = '{"channels": {"P_In": {"t0": 0, "rate_hz": 1e-300, "values": [1, 2]}}}'
    with pytest.raises(InputError, match=r"rate_hz: received \(0.0, 1e-300\).*0.1 to 1e\+07 Hz"):
        parse_payload(slow)
    ragged = '{"channels": {"P_In": {"t0": 0, "rate_hz": 10, "values": [[1], [2, 3]]}}}'
    with pytest.raises(InputError, match=r"MQTT payload channel 'P_In'.*allowed: numbers"):
        parse_payload(ragged)
    with pytest.raises(InputError, match=r"MQTT payload size \[bytes\]"):
        parse_payload(b" " * (limits.MAX_PAYLOAD_BYTES + 1))


def test_parquet_channel_count_is_bounded_from_the_footer(
    base, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pneufdd.recording import parquet

    monkeypatch.setattr(parquet, "MAX_CHANNELS", 3)  # the real limit: 10,000 channel rows
    code, text = run(["steps", base["run"]], tmp_path)
    assert code == 2
    assert "number of channels: received 21; allowed: at most 3 (docs/limits.md)" in text
