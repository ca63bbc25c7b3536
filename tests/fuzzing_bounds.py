"""Resource-bound cases of the fuzz corpus (issue 39, items 2, 3, 5 and 7).

Generators of small inputs that once took the machine down or crashed: sizes (a
``.pnref`` declaring 10^6 cycles, a Parquet file declaring 6 x 10^7 samples, a 5 MB tag
map, a 3.5 MB machine with thousands of actuators, 100,000 ignored CSV columns),
nesting (Parquet metadata and tag maps 100,000 deep), links (a folder linking to itself
and its parent under a ``**`` glob; ``/dev/zero`` as a tag map) and values (rates,
speeds, counts, costs and physical parameters at 1e-300, 1e308, inf and NaN). Each case
expects a clean exit 2 naming the option, file or field (``docs/limits.md``).

:func:`build_bounds` is called by :func:`fuzzing.build_corpus`; the quick slice keeps
the cheap cases of :data:`QUICK`.
"""

from __future__ import annotations

import io
import json
import os
import re
import zlib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

import fuzzing
from fuzzing import Case, _case_dir, _put

QUICK = frozenset(
    {
        "diagnose/ref_n_cycles_1e6",
        "diagnose/ref_false_alarm_rate_nan",
        "steps/metadata_nested_100k",
        "steps/map_role_newline",
        "simulate/meter_out_cv_1e-300",
        "monitor/replay_chunk_1e-300",
    }
)
"""The handful of cases ``make test``'s quick slice runs (each well under a second)."""


def _pnref(path: Path, *, features: Any = None, arrays: Any = None, **changes: Any) -> bytes:
    """``path``'s reference with header fields (``settings.x`` for a setting) changed."""
    edit = arrays
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: np.asarray(data[k]) for k in data.files}
    if edit is not None:
        arrays = edit(arrays)
    header = json.loads(str(arrays["header"]))
    for key, value in changes.items():
        if key.startswith("settings_"):
            header["settings"][key[len("settings_") :]] = value
        else:
            header[key] = value
    arrays["header"] = np.array(json.dumps(header))
    if features is not None:
        arrays["features"] = features(arrays["features"].copy())
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def _huge_band(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Band arrays of 3 x 10^7 samples a channel: 3.4 GB declared in a 3.5 MB file."""
    n_channels = arrays["band_mean"].shape[0] if "band_mean" in arrays else 2
    zeros = np.zeros((n_channels, 30_000_000))
    return {**arrays, "band_mean": zeros, "band_std": zeros}


def _nested_metadata(path: Path, depth: int) -> bytes:
    """``path``'s recording with metadata JSON nested ``depth`` deep (CRC kept valid)."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    kv = dict(table.schema.metadata)
    info = json.loads(kv[b"pneufdd.recording"])
    info["metadata"]["deep"] = "@@DEEP@@"
    raw = json.dumps(info).encode().replace(b'"@@DEEP@@"', b"[" * depth + b"]" * depth)
    kv[b"pneufdd.recording"] = raw
    kv[b"pneufdd.recording.crc32"] = str(zlib.crc32(raw)).encode()
    buf = io.BytesIO()
    pq.write_table(table.replace_schema_metadata(kv), buf)
    return buf.getvalue()


def _declared_samples(path: Path, folder: Path, name: str, samples: int) -> str:
    """A copy of ``path`` whose ``P_In`` holds ``samples`` constant samples (a few kB)."""
    from pneufdd import Recording
    from pneufdd.recording import Channel

    target = folder / name
    if not target.exists():
        rec = Recording.read(path)
        channels = [rec.info(n) for n in rec.channels]
        first = channels[0]
        channels[0] = Channel(
            first.name, np.full(samples, 6e5), first.rate_hz, first.unit, first.kind, first.t0
        )
        Recording(channels, start_time=rec.start_time, metadata=rec.metadata).write(target)
    return name


def _machine_text(base: dict[str, Path]) -> str:
    return base["toml"].read_text("utf-8")


def _first_actuator_set(text: str, key: str, value: str) -> bytes:
    """The machine with ``key = value`` in its first ``[[actuator]]`` (replaced or added)."""
    start = text.index("[[actuator]]")
    end = text.find("\n[[", start + 5)
    block = text[start : end if end > 0 else len(text)]
    line = re.compile(rf"^{re.escape(key)} = .*$", re.M)
    if line.search(block):
        new = line.sub(f"{key} = {value}", block, count=1)
    else:
        new = block.replace("[[actuator]]\n", f"[[actuator]]\n{key} = {value}\n", 1)
    return (text[:start] + new + text[start + len(block) :]).encode()


def _first_sensor_set(text: str, key: str, value: str) -> bytes:
    """The machine with ``key = value`` in its first ``[[sensor]]`` (replaced or added)."""
    start = text.index("[[sensor]]")
    end = text.find("\n[[", start + 5)
    block = text[start : end if end > 0 else len(text)]
    line = re.compile(rf"^{re.escape(key)} = (\[[^\]]*\]|.*)$", re.M)  # arrays span lines
    if line.search(block):
        new = line.sub(f"{key} = {value}", block, count=1)
    else:
        new = block.replace("[[sensor]]\n", f"[[sensor]]\n{key} = {value}\n", 1)
    return (text[:start] + new + text[start + len(block) :]).encode()


def _many_actuators(text: str, size: int) -> bytes:
    """The machine with copies of its first actuator appended up to ``size`` bytes."""
    start = text.index("[[actuator]]")
    end = text.find("\n[[", start + 5)
    block = text[start:end] + "\n"
    parts, total, k = [text], len(text), 0
    while total < size:
        copy = re.sub(r'^id = "\w+"', f'id = "X{k}"', block, count=1, flags=re.M)
        parts.append(copy)
        total += len(copy)
        k += 1
    return "".join(parts).encode()


def _tag_map(text: str, old: str, new: str) -> bytes:
    return text.replace(old, new, 1).encode()


def _cases_diagnose(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "bounds-diagnose")
    run = _put(folder, "run.parquet", base["run"])
    pnref = base["pnref"]
    refs: list[tuple[str, bytes, tuple[str, ...]]] = [
        ("ref_n_cycles_1e6", _pnref(pnref, n_cycles=1_000_000), ("n_cycles",)),
        ("ref_n_cycles_1e9", _pnref(pnref, n_cycles=10**9), ("n_cycles",)),
        ("ref_false_alarm_rate_nan", _pnref(pnref, settings_false_alarm_rate=float("nan")),
         ("false_alarm_rate",)),
        ("ref_false_alarm_rate_0", _pnref(pnref, settings_false_alarm_rate=0),
         ("false_alarm_rate",)),
        ("ref_false_alarm_rate_-1", _pnref(pnref, settings_false_alarm_rate=-1),
         ("false_alarm_rate",)),
        ("ref_false_alarm_rate_1.5", _pnref(pnref, settings_false_alarm_rate=1.5),
         ("false_alarm_rate",)),
        ("ref_band_eps_nan", _pnref(pnref, settings_band_eps=float("nan")), ("band_eps",)),
        ("ref_band_alarm_fraction_inf", _pnref(pnref, settings_band_alarm_fraction=1e309),
         ("band_alarm_fraction",)),
        ("ref_n_nuisance_-5", _pnref(pnref, settings_n_nuisance=-5), ("n_nuisance",)),
        ("ref_features_1e308", _pnref(pnref, features=lambda f: np.where(f == f, 1e308, f)),
         ("features",)),
        ("ref_band_3e7_samples", _pnref(pnref, arrays=_huge_band), ("arrays", "memory")),
        ("ref_features_inf", _pnref(pnref, features=lambda f: np.full_like(f, np.inf)),
         ("features",)),
    ]  # fmt: skip
    cases = []
    for name, content, words in refs:
        ref = _put(folder, f"{name}.pnref", content)
        cases.append(
            Case(f"diagnose/{name}", "diagnose",
                 ["diagnose", run, "--reference", ref, "--no-simulate"],
                 folder, [run, ref], [], mentions=(ref, *words))
        )  # fmt: skip
    ref = _put(folder, "ref.pnref", pnref)
    for option, value in (
        ("--hours", "1e308"),
        ("--hours", "inf"),
        ("--hours", "nan"),
        ("--price", "1e308"),
        ("--kw-per-100cfm", "inf"),
        ("--threads", "100000000"),
        ("--workers", "100000000"),
    ):
        cases.append(
            Case(f"diagnose/cost{option}_{value}", "diagnose",
                 ["diagnose", run, "--reference", ref, "--no-simulate", option, value],
                 folder, [run, ref], [], mentions=(option,))
        )  # fmt: skip
    # links: a folder holding a link to itself and to its parent, under a ** glob
    loop = folder / "loop" / "a" / "b"
    loop.mkdir(parents=True, exist_ok=True)
    _put(folder / "loop" / "a", "run.parquet", base["run"])
    for link, target in (("up", ".."), ("up2", "../.."), ("self", ".")):
        if not os.path.lexists(loop / link):
            os.symlink(target, loop / link)
    cases.append(
        Case("diagnose/glob_symlink_loops", "diagnose",
             ["diagnose", "loop/**/*.parquet", "--reference", ref, "--no-simulate"],
             folder, ["loop/a/run.parquet", ref], [], expect=frozenset({0, 1}))
    )  # fmt: skip
    return cases


def _cases_recordings(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "bounds-recordings")
    cases = []
    deep = _put(folder, "deep.parquet", _nested_metadata(base["run"], 100_000))
    mild = _put(folder, "deep65.parquet", _nested_metadata(base["run"], 65))
    for command in ("steps", "features", "machine draft"):
        for name in (deep, mild):
            argv = {
                "steps": ["steps", name],
                "features": ["features", name, "--out", "f.csv"],
                "machine draft": ["machine", "draft", name, "--out", "d.toml"],
            }[command]
            tag = "100k" if name == deep else "65"
            cases.append(
                Case(f"{command}/metadata_nested_{tag}", command, argv, folder, [name],
                     [a for a in argv if a.endswith((".csv", ".toml"))],
                     mentions=(name, "nesting"))
            )  # fmt: skip
    if full:  # 6 x 10^7 samples declared by a file of a few hundred kB
        big = _declared_samples(base["run"], folder, "samples_6e7.parquet", 60_000_000)
        for command, argv in (
            ("steps", ["steps", big]),
            ("diagnose", ["diagnose", big, "--reference", "ref.pnref", "--no-simulate"]),
        ):
            _put(folder, "ref.pnref", base["pnref"])
            cases.append(
                Case(f"{command}/declared_samples_6e7", command, argv, folder,
                     [big, "ref.pnref"], [], mentions=(big, "memory"))
            )  # fmt: skip
    return cases


def _cases_tag_maps(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "bounds-maps")
    csv, tags = fuzzing._plc_export(root)
    data = _put(folder, "plc.csv", csv)
    text = tags.read_text("utf-8")
    pressure = next(line for line in text.splitlines() if '"P_In"' in line)
    flow = next(line for line in text.splitlines() if '"Q_In"' in line)
    maps: list[tuple[str, bytes, tuple[str, ...]]] = [
        ("role_newline", _tag_map(text, '"P_In"', '"P_In\\n"'), ("role",)),
        ("role_trailing_space", _tag_map(text, '"P_In"', '"P_In "'), ("role",)),
        ("basis_list", _tag_map(text, flow, flow.split("basis")[0] + "basis = [1] }"),
         ("basis",)),
        ("basis_table", _tag_map(text, flow, flow.split("basis")[0] + "basis = { a = 1 } }"),
         ("basis",)),
        ("unit_int", _tag_map(text, pressure, pressure.split("unit")[0] + "unit = 5 }"),
         ("unit",)),
        ("rate_hz_inf", ("rate_hz = inf\n" + text).encode(), ("rate_hz",)),
        ("rate_hz_1e9", ("rate_hz = 1e9\n" + text).encode(), ("rate_hz",)),
        ("ignore_int", ("ignore = 5\n" + text).encode(), ("ignore",)),
        ("nested_100k", ("x = " + "[" * 100_000 + "]" * 100_000 + "\n" + text).encode(),
         ("nest",)),
        ("size_5mb", (text + "\n# " + "x" * (5 << 20) + "\n").encode(), ("size",)),
        ("unmapped_1mb", (text + "".join(f'"C{i}" = "U_C{i}_A"\n' for i in range(40_000)))
         .encode(), ("tag map", "column")),
    ]  # fmt: skip
    cases = []
    for name, content, words in maps:
        tag = _put(folder, f"{name}.toml", content)
        for command, argv in (
            ("steps", ["steps", data, "--map", tag]),
            ("import", ["import", data, "--map", tag, "--out", f"{name}.parquet"]),
        ):
            cases.append(
                Case(f"{command}/map_{name}", command, argv, folder, [data, tag],
                     [a for a in argv if a.endswith(".parquet") and a != data],
                     mentions=(tag, *words))
            )  # fmt: skip
    for command, argv in (
        ("steps", ["steps", data, "--map", "/dev/zero"]),
        ("import", ["import", data, "--map", "/dev/zero", "--out", "z.parquet"]),
    ):
        cases.append(
            Case(f"{command}/map_dev_zero", command, argv, folder, [data], [],
                 mentions=("/dev/zero",))
        )  # fmt: skip
    # an export at 1 GHz: import refuses it like every other command
    ghz = folder / "ghz.csv"
    if not ghz.exists():
        rows = "".join(f"{i * 1e-9:.12f},6.0,{(i // 100) % 2}\n" for i in range(3000))
        ghz.write_text("t,P,Y\n" + rows)
        (folder / "ghz.toml").write_text(
            '[columns]\nt = { role = "time", unit = "s" }\n'
            'P = { role = "P_In", unit = "bar" }\nY = "U_FEED_A"\n'
        )
    cases.append(
        Case("import/rate_1ghz", "import",
             ["import", "ghz.csv", "--map", "ghz.toml", "--out", "ghz.parquet"],
             folder, ["ghz.csv", "ghz.toml"], ["ghz.parquet"], mentions=("sample rate",))
    )  # fmt: skip
    if full:  # 100,000 ignored columns: linear (about 4 s), then imported
        wide = folder / "wide.csv"
        if not wide.exists():
            ignored = [f"ign{i}" for i in range(100_000)]
            zeros = ",".join(["0"] * len(ignored))
            with wide.open("w") as handle:
                handle.write(",".join(["t", "P", "Y", *ignored]) + "\n")
                for i in range(200):
                    handle.write(f"{i / 1000:.3f},6.0,{(i // 100) % 2},{zeros}\n")
            (folder / "wide.toml").write_text(
                "ignore = [" + ",".join(f'"{c}"' for c in ignored) + "]\n"
                '[columns]\nt = { role = "time", unit = "s" }\n'
                'P = { role = "P_In", unit = "bar" }\nY = "U_FEED_A"\n'
            )
        cases.append(
            Case("import/ignored_columns_100k", "import",
                 ["import", "wide.csv", "--map", "wide.toml", "--out", "wide.parquet"],
                 folder, ["wide.csv", "wide.toml"], ["wide.parquet"], expect=frozenset({0}))
        )  # fmt: skip
    return cases


def _cases_counts(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "bounds-counts")
    ref = _put(folder, "ref.parquet", base["ref"])
    text = _machine_text(base)
    cases = [
        Case("simulate/cycles_100000", "simulate",
             ["simulate", "--machine", fuzzing.MACHINE, "--cycles", "100000", "--out", "s.parquet"],
             folder, [], ["s.parquet"], mentions=("--cycles", "memory")),
        Case("vector-map/cycles_100000", "vector-map",
             ["vector-map", "--cycles", "100000", "--out", "vm"],
             folder, [], [], mentions=("cycles", "memory")),
        Case("reference build/uncertainty_plants_1e9", "reference build",
             ["reference", "build", ref, "--out", "r.pnref", "--uncertainty-plants", "1000000000"],
             folder, [ref], ["r.pnref"], mentions=("--uncertainty-plants",)),
        Case("reference build/signature_cycles_1e8", "reference build",
             ["reference", "build", ref, "--out", "r.pnref", "--signature-cycles", "100000000"],
             folder, [ref], ["r.pnref"], mentions=("--signature-cycles",)),
    ]  # fmt: skip
    machines: list[tuple[str, bytes, tuple[str, ...]]] = [
        ("meter_out_cv_1e-300", _first_actuator_set(text, "meter_out_cv", "1e-300"),
         ("meter_out_cv",)),
        ("meter_out_cv_a_1e-300", _first_actuator_set(text, "meter_out_cv_a", "1e-300"),
         ("meter_out_cv_a",)),
        ("moving_mass_1e-300", _first_actuator_set(text, "moving_mass_kg", "1e-300"),
         ("moving_mass_kg",)),
        ("dead_volume_1e-300", _first_actuator_set(text, "dead_volume_a_cm3", "1e-300"),
         ("dead_volume_a_cm3",)),
        ("friction_1e308", _first_actuator_set(text, "static_friction_n", "1e308"),
         ("static_friction_n",)),
        ("actuators_3_5mb", _many_actuators(text, 3_500_000), ("actuator",)),
        ("sensor_range_inf", _first_sensor_set(text, "range", "[0.0, inf]"), ("range",)),
        ("sensor_noise_1e308", _first_sensor_set(text, "noise", "1e308"), ("noise",)),
    ]  # fmt: skip
    for name, content, words in machines:
        toml = _put(folder, f"{name}.toml", content)
        cases.append(
            Case(f"simulate/{name}", "simulate",
                 ["simulate", "--machine", toml, "--cycles", "2", "--out", f"{name}.parquet"],
                 folder, [toml], [f"{name}.parquet"], mentions=(toml, *words))
        )  # fmt: skip
    if full:  # campaign is outside the corpus (hours a run); its bounds fail at once
        for option, value in (
            ("--run-cycles", "100000000"),
            ("--uncertainty-plants", "1000000000"),
            ("--reference-cycles", "100000000"),
            ("--leak-free-runs", "1000000000"),
        ):
            cases.append(
                Case(f"campaign/{option[2:]}_{value}", "campaign",
                     ["campaign", "--machine", fuzzing.MACHINE, "--out", "camp", option, value],
                     folder, [], [], mentions=(option[2:].replace("-", "_"), option))
            )  # fmt: skip
    return cases


def _cases_monitor(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "bounds-monitor")
    ref = _put(folder, "ref.pnref", base["pnref"])
    run = _put(folder, "run.parquet", base["run"])
    cases = []
    for label, query, words in (
        ("replay_chunk_1e-300", "chunk=1e-300", ("chunk",)),
        ("replay_chunk_inf", "chunk=inf", ("chunk",)),
        ("replay_speed_1e-300", "speed=1e-300", ("speed",)),
        ("replay_speed_nan", "speed=nan", ("speed",)),
    ):
        cases.append(
            Case(f"monitor/{label}", "monitor",
                 ["monitor", "--reference", ref, "--source", f"replay:{run}?{query}", "--once",
                  "--history", "sqlite:///h.db"],
                 folder, [ref, run], [], mentions=words)
        )  # fmt: skip
    for value in ("inf", "nan", "1e300"):
        cases.append(
            Case(f"monitor/arl0_{value}", "monitor",
                 ["monitor", "--reference", ref, "--source", f"replay:{run}?speed=max", "--once",
                  "--history", "sqlite:///h.db", "--arl0", value],
                 folder, [ref, run], [], mentions=("--arl0",))
        )  # fmt: skip
    cases.append(
        Case("monitor/tags_dev_zero", "monitor",
             ["monitor", "--reference", ref, "--source", f"replay:{run}?speed=max", "--once",
              "--history", "sqlite:///h.db", "--tags", "/dev/zero"],
             folder, [ref, run], [], mentions=("/dev/zero",))
    )  # fmt: skip
    # a history this process may not write (a read-only connection: root ignores modes)
    ro = folder / "ro.db"
    if not ro.exists():
        import sqlite3

        sqlite3.connect(ro).close()
    cases.append(
        Case("monitor/history_read_only", "monitor",
             ["monitor", "--reference", ref, "--source", f"replay:{run}?speed=max", "--once",
              "--history", "sqlite:///file:ro.db?mode=ro&uri=true"],
             folder, [ref, run], [], mentions=("--history",))
    )  # fmt: skip
    return cases


def build_bounds(
    base: dict[str, Path], root: Path, full: bool, commands: Iterable[str] | None = None
) -> list[Case]:
    """Every resource-bound case (``full``) or those of :data:`QUICK`, for ``commands``."""
    cases: list[Case] = []
    for make in (_cases_diagnose, _cases_recordings, _cases_tag_maps, _cases_counts,
                 _cases_monitor):  # fmt: skip
        cases.extend(make(base, root, full))
    wanted = None if commands is None else set(commands)
    return [
        c for c in cases if (full or c.name in QUICK) and (wanted is None or c.command in wanted)
    ]
