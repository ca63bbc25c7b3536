"""Bad-input fuzz suite of the ``pneufdd`` command (issue 14).

A corpus generator mutates valid inputs (recordings, references, machine files and
options) the way real users and real DAQ files do, and a runner invokes every
command over them and checks, for each invocation:

* no traceback and no internal error (exit 3);
* the exit code is one the case allows (0/1 on usable input, 2 on bad input);
* an exit 2 prints one ``error:`` line naming the file, channel, key or option;
* every input file is unchanged (bytes and mode);
* no partial output: after a failure no output file and no temporary file exists;
  after a success every output exists and parses;
* in a subprocess (``make fuzz``): no hang (killed and counted after
  :data:`CASE_TIMEOUT_S`), under an address-space cap of :data:`MEMORY_CAP_BYTES`,
  and a resident set that stays under :data:`RSS_LIMIT_BYTES` (the command's own peak,
  its ``VmHWM`` read every 50 ms: see :func:`_watch_peak`).

Commands are discovered from :data:`pneufdd.cli.app.app`; each needs an entry in the
generators' table (:data:`fuzzing_generators.COMMANDS`, one line) and may have
hand-written cases in :data:`BUILDERS`, so a command added later is caught by
``test_every_command_has_a_generator_entry`` until it joins the corpus.

``python tests/fuzzing.py`` (``make fuzz``) runs the full corpus in subprocesses and
prints the summary; ``tests/test_fuzz_cli.py`` runs a quick slice in-process.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile
import zlib
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pneufdd import Recording
from pneufdd.recording import Channel

MACHINE = "press-fit-cell"
"""The smallest built-in machine (4 actuators, 7 steps): cheap to simulate."""

SEED = 97_000_001
"""Seed of the base recordings and the bit flips (issue 39 third round: 97,000,000 and
above; earlier rounds used 96,000,101; never used while developing methods)."""

EXIT_OK, EXIT_LEAK, EXIT_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
CASE_TIMEOUT_S = 120.0
"""A command still running after this long is a hang: killed and counted [s]."""
MEMORY_CAP_BYTES = 4_000_000_000
"""Address space each command may map (``RLIMIT_AS``), like a 4 GB container [bytes]."""
RSS_LIMIT_BYTES = 2 * 1024**3
"""A command whose resident set grew past this counts as a memory problem [bytes]."""
EXIT_HANG = -9
LIVE_S = 25.0
"""How long a live case runs before it is stopped (its source retried meanwhile) [s]."""

# --------------------------------------------------------------------- cases


@dataclass
class Case:
    """One invocation: ``argv`` run in ``folder``, and what it may do.

    ``inputs`` are files the command reads (checked unchanged); ``outputs`` the files
    it may write (absent after a failure, present and readable after success);
    ``expect`` the allowed exit codes; ``mentions``: on exit 2 the message names at
    least one of these (file, channel, key or option); ``secrets``: never printed.
    """

    name: str
    command: str
    argv: list[str]
    folder: Path
    inputs: list[str]
    outputs: list[str] = field(default_factory=list)
    expect: frozenset[int] = frozenset({EXIT_INPUT})
    mentions: tuple[str, ...] = ()
    secrets: tuple[str, ...] = ()
    """Texts (passwords) that may appear in no output of the command."""
    live: bool = False
    """A live command that rightly waits for its source (a broker not up yet): it is
    stopped after :data:`LIVE_S` and checked for what it printed meanwhile."""
    absent: tuple[str, ...] = ()
    """Files that must not exist afterwards (the target of an output's dangling link)."""
    optional: tuple[str, ...] = ()
    """Outputs a success may leave unwritten (an alarm log without alarms)."""


@dataclass
class Outcome:
    """What one invocation did, and what was wrong with it (``problems``)."""

    case: Case
    code: int
    stderr: str
    seconds: float
    problems: list[str]
    peak_rss: int | None = None
    """Largest resident set of the command's process [bytes] (None in-process)."""
    cpu_s: float | None = None
    """CPU time the command used, user and system [s] (None in-process): a command killed
    at the time limit with little CPU was starved by a loaded machine, not hung."""


# --------------------------------------------------------------- base inputs


def _simulate(cycles: int, seed: int, leaks: dict[str, str] | None = None) -> Recording:
    from pneufdd.sim import as_exported, load_machine, simulate

    rec = simulate(load_machine(MACHINE), cycles=cycles, leaks=leaks or {}, seed=seed)
    return rec if leaks is None else as_exported(rec)


def make_base(folder: Path, full: bool = False) -> dict[str, Path]:
    """Valid inputs every mutation starts from, written into ``folder`` (cached)."""
    from pneufdd.cli.app import main
    from pneufdd.sim import load_machine
    from pneufdd.sim.variation import write_machine

    folder.mkdir(parents=True, exist_ok=True)
    base = {
        "ref": folder / "ref.parquet",
        "run": folder / "run.parquet",
        "pnref": folder / "ref.pnref",
        "toml": folder / "machine.toml",
    }
    if full:
        base["leak"] = folder / "leak.parquet"
    if not base["ref"].exists():
        _simulate(11, SEED).write(base["ref"])
    if not base["run"].exists():
        if full:
            _simulate(4, SEED + 1).write(base["run"])
        else:  # the quick slice diagnoses the reference recording itself
            shutil.copy(base["ref"], base["run"])
    if full and not base["leak"].exists():
        _simulate(4, SEED + 2, {"PRESS_A": "40slpm"}).write(base["leak"])
    if not base["toml"].exists():
        write_machine(load_machine(MACHINE), base["toml"], header="fuzz base")
    if not base["pnref"].exists():
        with contextlib.redirect_stderr(io.StringIO()):
            code = main(
                [
                    "reference",
                    "build",
                    str(base["ref"]),
                    "--out",
                    str(base["pnref"]),
                    "--no-signatures",
                ]
            )
        if code != 0:
            raise RuntimeError(f"base reference failed with exit {code}")
    return base


# ----------------------------------------------------------------- mutations


def _channels(rec: Recording) -> list[Channel]:
    return [rec.info(n) for n in rec.channels]


def _replace(rec: Recording, channel: str, **changes: Any) -> Recording:
    out = []
    for ch in _channels(rec):
        if ch.name == channel:
            fields = {
                "name": ch.name,
                "values": ch.values,
                "rate_hz": ch.rate_hz,
                "unit": ch.unit,
                "kind": ch.kind,
                "t0": ch.t0,
            }
            fields.update(changes)
            if fields["name"] is None:
                continue
            ch = Channel(
                fields["name"],
                fields["values"],
                fields["rate_hz"],
                fields["unit"],
                fields["kind"],
                fields["t0"],
            )
        out.append(ch)
    return Recording(out, rec.start_time, rec.metadata)


def _drop(rec: Recording, channel: str) -> Recording:
    return Recording([c for c in _channels(rec) if c.name != channel], rec.start_time, rec.metadata)


def _map_analog(rec: Recording, fn: Callable[[Channel], Channel | None]) -> Recording:
    out = []
    for ch in _channels(rec):
        new = fn(ch) if ch.kind == "analog" else ch
        if new is not None:
            out.append(new)
    return Recording(out, rec.start_time, rec.metadata)


def _with(
    ch: Channel,
    values: Any = None,
    rate: float | None = None,
    t0: float | None = None,
    unit: str | None = None,
) -> Channel:
    return Channel(
        ch.name,
        ch.values if values is None else values,
        ch.rate_hz if rate is None else rate,
        ch.unit if unit is None else unit,
        ch.kind,
        ch.t0 if t0 is None else t0,
    )


def _bursts(values: np.ndarray, fraction: float, seed: int, fill: float = np.nan) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = values.astype(np.float64).copy()
    width = 10
    starts = rng.integers(0, v.size - width, max(1, int(fraction * v.size / width)))
    v[(starts[:, None] + np.arange(width)).ravel()] = fill
    return v


def recording_mutations(rec: Recording) -> Iterator[tuple[str, Recording | None, tuple[str, ...]]]:
    """(name, mutated recording, words the error must mention) for data mutations.

    A None recording marks a mutation handled elsewhere. Data mutations keep a valid
    file: the command must judge the content (gaps are repaired or skipped, nonsense
    refused naming the channel).
    """
    analog = rec.analog_channels
    first = analog[0]
    flow = next(c for c in analog if c.startswith("Q_"))
    yield (
        "nan_all_first_analog",
        _replace(rec, first, values=np.full(rec.info(first).values.size, np.nan)),
        (first,),
    )
    yield (
        "inf_all_flow",
        _replace(rec, flow, values=np.full(rec.info(flow).values.size, np.inf)),
        (flow,),
    )
    yield (
        "huge_1e308_flow",
        _replace(rec, flow, values=np.full(rec.info(flow).values.size, 1e308)),
        (flow,),
    )
    yield (
        "huge_1e308_spikes",
        _map_analog(rec, lambda c: _with(c, _bursts(c.values, 0.01, 3, 1e308))),
        (),
    )
    yield "empty_flow", _replace(rec, flow, values=np.zeros(0)), (flow,)
    yield "nan_bursts_1pct", _map_analog(rec, lambda c: _with(c, _bursts(c.values, 0.01, 4))), ()
    yield (
        "inf_bursts_1pct",
        _map_analog(rec, lambda c: _with(c, _bursts(c.values, 0.01, 5, np.inf))),
        (),
    )
    yield "nan_bursts_30pct", _map_analog(rec, lambda c: _with(c, _bursts(c.values, 0.3, 6))), ()
    yield (
        "nan_half_of_flow",
        _replace(
            rec,
            flow,
            values=np.where(
                np.arange(rec.info(flow).values.size) > rec.info(flow).values.size // 2,
                np.nan,
                rec.info(flow).values,
            ),
        ),
        (),
    )
    yield "analog_t0_plus_1e9", _map_analog(rec, lambda c: _with(c, t0=c.t0 + 1e9)), ("time",)
    yield "analog_t0_minus_1e3", _map_analog(rec, lambda c: _with(c, t0=c.t0 - 1e3)), ("time",)
    yield "analog_at_1hz", _map_analog(rec, lambda c: _with(c, c.values[::1000], rate=1.0)), ("Hz",)
    yield (
        "analog_rate_mislabelled_10x",
        _map_analog(rec, lambda c: _with(c, rate=c.rate_hz * 10)),
        (),
    )
    yield "flow_labelled_pa", _replace(rec, flow, unit="Pa"), (flow,)
    yield "pressure_labelled_kg_s", _replace(rec, first, unit="kg/s"), (first,)
    yield "pressure_in_bar_values", _replace(rec, first, values=rec.info(first).values / 1e5), ()
    yield "negative_pressure", _replace(rec, first, values=-rec.info(first).values), (first,)
    switch = next(c for c in rec.digital_channels if c.startswith("S_"))
    valve = next(c for c in rec.digital_channels if c.startswith("U_"))
    yield "missing_switch", _drop(rec, switch), (switch,)
    yield "missing_valve", _drop(rec, valve), (valve,)
    yield "missing_flow", _drop(rec, flow), (flow,)
    yield "switch_stuck_on", _replace(rec, switch, values=np.ones_like(rec.info(switch).values)), ()
    yield (
        "valves_never_fire",
        Recording(
            [
                _with(c, np.zeros_like(c.values)) if c.name.startswith("U_") else c
                for c in _channels(rec)
            ],
            rec.start_time,
            rec.metadata,
        ),
        (),
    )
    yield (
        "truncated_half",
        Recording(
            [_with(c, c.values[: c.values.size // 2]) for c in _channels(rec)],
            rec.start_time,
            rec.metadata,
        ),
        (),
    )
    yield (
        "truncated_one_cycle",
        Recording(
            [_with(c, c.values[: int(3.5 * c.rate_hz)]) for c in _channels(rec)],
            rec.start_time,
            rec.metadata,
        ),
        (),
    )
    yield (
        "digital_t0_plus_5s",
        Recording(
            [c if c.kind == "analog" else _with(c, t0=c.t0 + 5.0) for c in _channels(rec)],
            rec.start_time,
            rec.metadata,
        ),
        (),
    )
    for name, md in metadata_mutations(rec.metadata):
        yield (
            f"metadata_{name}",
            Recording(_channels(rec), rec.start_time, md),
            ("metadata", "machine"),
        )


def metadata_mutations(metadata: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any]]]:
    """Malformed free metadata, chiefly the machine description a recording carries."""

    def edit(fn: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
        md = copy.deepcopy(metadata)
        fn(md)
        return md

    def desc(md: dict[str, Any]) -> dict[str, Any]:
        return md["machine"]["description"]

    yield "steps_are_ints", edit(lambda md: desc(md).__setitem__("step", [1, 2, 3]))
    yield "step_without_set", edit(lambda md: desc(md)["step"][0]["do"][0].pop("set"))
    yield "step_do_is_string", edit(lambda md: desc(md)["step"][0].__setitem__("do", "U_FEED_A"))
    yield "no_steps", edit(lambda md: desc(md).__setitem__("step", []))
    yield "description_is_list", edit(lambda md: md["machine"].__setitem__("description", [1]))
    yield "machine_is_int", edit(lambda md: md.__setitem__("machine", 7))
    yield "machine_name_other", edit(lambda md: md["machine"].__setitem__("name", "festo-dsd"))
    yield (
        "actuator_bore_null",
        edit(lambda md: desc(md)["actuator"][0].__setitem__("bore_mm", None)),
    )
    yield (
        "actuator_bore_negative",
        edit(lambda md: desc(md)["actuator"][0].__setitem__("bore_mm", -25.0)),
    )
    yield "supply_psig_string", edit(lambda md: desc(md)["supply"].__setitem__("house_psig", "108"))
    yield (
        "sensor_range_nested",
        edit(lambda md: desc(md)["sensor"][0].__setitem__("range", [[[[0.0]]]])),
    )
    yield "deeply_nested", edit(lambda md: md.__setitem__("extra", _nested(200)))
    yield "cycle_start_null", edit(lambda md: md.__setitem__("cycle_start_s", None))


def _nested(depth: int) -> Any:
    value: Any = 1
    for _ in range(depth):
        value = {"a": [value]}
    return value


def parquet_mutations(path: Path) -> Iterator[tuple[str, bytes]]:
    """Valid Parquet, CRCs intact, with malformed pneufdd content: null or absurd
    rates and offsets, a null or garbled start time, a wrong channel count."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    kv = dict(table.schema.metadata or {})
    info = json.loads(kv[b"pneufdd.recording"])

    def write(tab: Any, new_info: Any = None) -> bytes:
        meta = dict(kv)
        if new_info is not None:
            raw = json.dumps(new_info).encode()
            meta[b"pneufdd.recording"] = raw
            meta[b"pneufdd.recording.crc32"] = str(zlib.crc32(raw)).encode()
        buf = io.BytesIO()
        pq.write_table(tab.replace_schema_metadata(meta), buf, row_group_size=1)
        return buf.getvalue()

    def column(name: str, values: list[Any]) -> Any:
        idx = table.column_names.index(name)
        return table.set_column(idx, name, pa.array(values, type=table.schema.field(name).type))

    n = table.num_rows
    rates = table.column("rate_hz").to_pylist()
    t0s = table.column("t0_s").to_pylist()
    names = table.column("name").to_pylist()
    yield "parquet_rate_null", write(column("rate_hz", [None, *rates[1:]]))
    yield "parquet_rate_nan", write(column("rate_hz", [float("nan"), *rates[1:]]))
    yield "parquet_rate_zero", write(column("rate_hz", [0.0, *rates[1:]]))
    yield "parquet_rate_negative", write(column("rate_hz", [-1000.0, *rates[1:]]))
    yield "parquet_t0_null", write(column("t0_s", [None, *t0s[1:]]))
    yield "parquet_t0_inf", write(column("t0_s", [float("inf"), *t0s[1:]]))
    yield "parquet_name_null", write(column("name", [None, *names[1:]]))
    yield "parquet_kind_bogus", write(column("kind", ["sideways"] * n))
    yield "parquet_unit_furlong", write(column("unit", ["furlong"] * n))
    yield "parquet_n_samples_lie", write(column("n_samples", [10**12] * n))
    yield "parquet_start_time_null", write(table, {**info, "start_time": None})
    yield "parquet_start_time_garbage", write(table, {**info, "start_time": "yesterday"})
    yield "parquet_n_channels_wrong", write(table, {**info, "n_channels": n + 3})
    yield "parquet_n_channels_string", write(table, {**info, "n_channels": "many"})
    yield "parquet_metadata_list", write(table, {**info, "metadata": [1, 2]})
    yield "parquet_info_is_list", write(table, [info])


def truncations(data: bytes) -> Iterator[tuple[str, bytes]]:
    """The file cut at several places (and emptied)."""
    yield "empty", b""
    yield "one_byte", data[:1]
    for fraction in (0.05, 0.3, 0.5, 0.9):
        yield f"cut_{int(100 * fraction)}pct", data[: int(len(data) * fraction)]
    yield "minus_1_byte", data[:-1]
    yield "minus_8_bytes", data[:-8]


def bit_flips(data: bytes, count: int, seed: int) -> Iterator[tuple[str, bytes]]:
    """``count`` copies of ``data`` with 1-8 random bits flipped (heads and tails too)."""
    rng = np.random.default_rng(seed)
    n = len(data)
    for k in range(count):
        buf = bytearray(data)
        region = k % 3  # head, tail, anywhere
        for _ in range(int(rng.integers(1, 9))):
            if region == 0:
                pos = int(rng.integers(0, min(n, 512)))
            elif region == 1:
                pos = int(rng.integers(max(0, n - 2048), n))
            else:
                pos = int(rng.integers(0, n))
            buf[pos] ^= 1 << int(rng.integers(0, 8))
        yield f"bitflip_{k}", bytes(buf)


def pnref_mutations(path: Path) -> Iterator[tuple[str, bytes, tuple[str, ...]]]:
    """Damaged ``.pnref`` files: header fields of wrong types/sizes, shapes, entries."""
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: np.asarray(data[k]) for k in data.files}
    header = json.loads(str(arrays["header"]))

    def pack(arrs: dict[str, np.ndarray], compress: bool = True) -> bytes:
        buf = io.BytesIO()
        (np.savez_compressed if compress else np.savez)(buf, **arrs)
        return buf.getvalue()

    def with_header(**changes: Any) -> bytes:
        h = dict(header)
        for k, v in changes.items():
            if v is _DROP:
                h.pop(k, None)
            else:
                h[k] = v
        return pack({**arrays, "header": np.array(json.dumps(h))})

    fields: list[tuple[str, Any]] = [
        ("trace_rate_hz", 0),
        ("trace_rate_hz", -100.0),
        ("trace_rate_hz", "fast"),
        ("trace_rate_hz", None),
        ("trace_rate_hz", 1e300),
        ("n_cycles", 10**12),
        ("n_cycles", -1),
        ("n_cycles", "12"),
        ("n_steps", 0),
        ("n_steps", 10**9),
        ("channels", 5),
        ("channels", ["P_In"]),
        ("units", ["furlong"] * len(header["units"])),
        ("feature_names", []),
        ("settings", "strict"),
        ("settings", {"alpha": "x"}),
        ("localisation", [1, 2]),
        ("machine_description", 3),
        ("machine_description", {"actuator": 1}),
        ("machine", None),
        ("sequence", [1, 2]),
        ("sequence", [{"valves": 3}]),
        ("sources", 4),
        ("supply_pressure", "high"),
        ("signature_locations", ["supply"]),
        ("version", 99),
        ("format", "something-else"),
    ]
    for key, value in fields:
        yield f"header_{key}_{str(value)[:12]}", with_header(**{key: value}), (key,)
    for key in ("channels", "n_steps", "trace_rate_hz", "settings"):
        yield f"header_without_{key}", with_header(**{key: _DROP}), (key,)
    yield "header_not_json", pack({**arrays, "header": np.array("{not json")}), ("header",)
    yield (
        "header_deeply_nested",
        pack({**arrays, "header": np.array("[" * 100_000 + "]" * 100_000)}),
        ("header",),
    )
    yield (
        "features_nan",
        pack({**arrays, "features": np.full_like(arrays["features"], np.nan)}),
        ("features",),
    )
    yield (
        "features_wrong_shape",
        pack({**arrays, "features": arrays["features"][:, :3]}),
        ("features",),
    )
    yield (
        "features_int",
        pack({**arrays, "features": arrays["features"].astype(np.int64)}),
        ("features",),
    )
    yield "features_object", _object_entry(pack, arrays), ("features",)
    without = {k: v for k, v in arrays.items() if k != "features"}
    yield "features_missing", pack(without), ("features",)
    if "band_mean" in arrays:
        yield "band_std_negative", pack({**arrays, "band_std": -arrays["band_std"]}), ("band_std",)
        yield (
            "trace_offsets_decreasing",
            pack({**arrays, "trace_offsets": arrays["trace_offsets"][::-1].copy()}),
            ("trace_offsets",),
        )
    yield "huge_shape", _huge_shape(pack({**arrays}, compress=False)), ("features", "shape")
    yield "damaged_deflate", _damage_deflate(pack(arrays)), ("ref",)
    yield "zip_of_nothing", _zip_of({"readme.txt": b"hello"}), ("header",)
    yield "pickle_entry", _zip_of({"header.npy": _pickle_npy()}), ("header",)


class _Drop:
    pass


_DROP = _Drop()


def _object_entry(pack: Callable[..., bytes], arrays: dict[str, np.ndarray]) -> bytes:
    data = pack(arrays)
    # an entry saved with dtype object needs pickle to load: must be refused unread
    return _replace_member(data, "features.npy", _pickle_npy())


def _pickle_npy() -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    return buf.getvalue()


def _zip_of(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, content in members.items():
            z.writestr(name, content)
    return buf.getvalue()


def _replace_member(data: bytes, name: str, content: bytes) -> bytes:
    src = zipfile.ZipFile(io.BytesIO(data))
    members = {n: src.read(n) for n in src.namelist()}
    members[name] = content
    return _zip_of(members)


def _huge_shape(data: bytes) -> bytes:
    """features.npy whose header asks for 74.5 GiB (10^5 x 10^5 float64)."""
    src = zipfile.ZipFile(io.BytesIO(data))
    members = {n: src.read(n) for n in src.namelist()}
    raw = members["features.npy"]
    header = np.lib.format.header_data_from_array_1_0(np.zeros((1, 1)))
    header["shape"] = (100_000, 100_000)
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    members["features.npy"] = buf.getvalue() + raw[128:]
    return _zip_of(members)


def _damage_deflate(data: bytes) -> bytes:
    """Flip bytes inside the compressed stream of the largest member (zlib.error)."""
    src = zipfile.ZipFile(io.BytesIO(data))
    info = max(src.infolist(), key=lambda i: i.compress_size)
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    buf = bytearray(data)
    for k in range(start + 16, start + min(info.compress_size, 4096), 97):
        buf[k] ^= 0x5A
    return bytes(buf)


def toml_mutations(text: str) -> Iterator[tuple[str, bytes, tuple[str, ...]]]:
    """Malformed machine files: encoding, depth, syntax, types and values."""
    yield "latin1", text.replace("#", "# \u00e9\u00e8 ", 1).encode("latin-1", "replace"), ("UTF-8",)
    yield "binary_garbage", bytes(range(256)) * 4, ("UTF-8", "TOML")
    yield "utf16", text.encode("utf-16"), ("UTF-8", "TOML")
    yield "empty", b"", ()
    yield (
        "nested_arrays_10000",
        ("x = " + "[" * 10_000 + "]" * 10_000 + "\n" + text).encode(),
        ("deep",),
    )
    yield (
        "nested_tables_300",
        ("".join(f"[{'.'.join(['t'] * k)}]\n" for k in range(1, 300)) + text).encode(),
        ("deep",),
    )
    yield (
        "nested_inline_5000",
        ("y = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n" + text).encode(),
        ("deep",),
    )
    yield "truncated", text[: len(text) // 2].encode(), ()
    yield "not_toml", b"<machine><actuator/></machine>", ("TOML",)
    for k, (old, new, why) in enumerate(
        (
            ("bore_mm = 25.0", 'bore_mm = "25"', "bore_mm"),
            ("bore_mm = 25.0", "bore_mm = -25.0", "bore_mm"),
            ("bore_mm = 25.0", "bore_mm = nan", "bore_mm"),
            ("bore_mm = 25.0", "bore_mm = inf", "bore_mm"),
            ("bore_mm = 25.0", "bore_mm = 1e308", "bore_mm"),
            ("house_psig = 108.0", "house_psig = -5.0", "house_psig"),
            ("house_psig = 108.0", "house_psig = 1e9", "house_psig"),
            ('set = "U_FEED_A"', "set = 7", "set"),
            ('set = "U_FEED_A"', 'set = "U_NOWHERE"', "U_NOWHERE"),
            ("[[step]]", "[[stepp]]", "step"),
            ("[[actuator]]", "[[actuatorz]]", "actuator"),
            ("scan_time_s = 0.005", "scan_time_s = -0.005", "scan_time_s"),
            ("scan_time_s = 0.005", "scan_time_s = 1e6", "scan_time_s"),
        )
    ):
        if old in text:
            yield f"value_{k:02d}_{why}", text.replace(old, new, 1).encode(), (why,)


# ------------------------------------------------------------ case builders

Builder = Callable[[dict[str, Path], Path, bool], list[Case]]


def _case_dir(root: Path, name: str) -> Path:
    folder = root / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _put(folder: Path, name: str, source: Path | bytes | Recording) -> str:
    target = folder / name
    if isinstance(source, Recording):
        source.write(target)
    elif isinstance(source, bytes):
        target.write_bytes(source)
    else:
        shutil.copy(source, target)
    return name


def _same_recording(path: Path, original: Recording) -> bool:
    """True if ``path`` reads back as ``original`` (a flipped bit in unchecked padding)."""
    try:
        back = Recording.read(path)
    except Exception:
        return False
    if back.channels != original.channels or back.metadata != original.metadata:
        return False
    return all(
        np.array_equal(back.info(n).values, original.info(n).values, equal_nan=True)
        for n in original.channels
    )


def _bad_recordings(
    base: dict[str, Path], root: Path, full: bool, source: str = "run"
) -> list[tuple[str, Path, tuple[str, ...], bool]]:
    """(name, file, mentions, structural) of every damaged ``source``: each written once.

    ``structural`` damage (truncated, flipped, foreign files) must be refused; a bit
    flip the format cannot see (it reads back identical) counts as no damage.
    """
    store = root / f"_recordings_{source}"
    store.mkdir(parents=True, exist_ok=True)
    items: list[tuple[str, Path, tuple[str, ...], bool]] = []
    data = base[source].read_bytes()
    rec = Recording.read(base[source])
    for name, content in truncations(data):
        path = store / f"{name}.parquet"
        path.write_bytes(content)
        items.append((name, path, ("run.parquet",), True))
    for name, content in bit_flips(data, 32 if full else 4, SEED):
        path = store / f"{name}.parquet"
        path.write_bytes(content)
        items.append((name, path, ("run.parquet",), not _same_recording(path, rec)))
    for name, content in parquet_mutations(base[source]):
        path = store / f"{name}.parquet"
        path.write_bytes(content)
        items.append((name, path, ("run.parquet",), True))
    for name, mutated, words in recording_mutations(rec):
        if not full and name not in QUICK_RECORDING_MUTATIONS:
            continue
        if mutated is None:
            continue
        path = store / f"{name}.parquet"
        if not path.exists():
            mutated.write(path)
        items.append((name, path, ("run.parquet", *words), False))
    csv = store / "export.csv"
    csv.write_text("t,P_In\n0,600000\n0.001,600100\n")
    items.append(("csv_file", csv, ("run.csv", "column"), True))
    tdms = store / "garbage.tdms"
    tdms.write_bytes(b"TDSm" + bytes(64))
    items.append(("tdms_garbage", tdms, ("run.tdms",), True))
    return items


QUICK_RECORDING_MUTATIONS = frozenset(
    {
        "nan_all_first_analog",
        "huge_1e308_flow",
        "empty_flow",
        "nan_bursts_1pct",
        "analog_t0_plus_1e9",
        "analog_at_1hz",
        "flow_labelled_pa",
        "missing_switch",
        "metadata_steps_are_ints",
        "metadata_step_without_set",
        "metadata_cycle_start_null",
    }
)

#: Data mutations a command may accept (exit 0/1): gaps repaired or skipped by the
#: documented rule, or content that is odd but not nonsense.
MAY_ACCEPT = frozenset(
    {
        "nan_bursts_1pct",
        "inf_bursts_1pct",
        "huge_1e308_spikes",
        "switch_stuck_on",
        "analog_rate_mislabelled_10x",
        "metadata_deeply_nested",
        "metadata_cycle_start_null",
        "metadata_machine_is_int",
        "metadata_machine_name_other",
        "missing_flow",
        "nan_half_of_flow",
        "truncated_half",
        "truncated_one_cycle",
    }
)


def _run_name(path: Path) -> str:
    return "run" + path.suffix


def build_steps(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = []
    for name, path, words, structural in _bad_recordings(base, root, full):
        folder = _case_dir(root, f"steps-{name}")
        run = _put(folder, _run_name(path), path)
        expect = {EXIT_INPUT} if structural else {EXIT_INPUT, EXIT_OK}
        cases.append(
            Case(
                f"steps/{name}",
                "steps",
                ["steps", run, "--json"],
                folder,
                [run],
                [],
                frozenset(expect),
                (run, *words),
            )
        )
    return cases


def build_features(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = []
    for name, path, words, structural in _bad_recordings(base, root, full):
        folder = _case_dir(root, f"features-{name}")
        run = _put(folder, _run_name(path), path)
        accept = name in MAY_ACCEPT or name.startswith("bitflip")
        expect = {EXIT_INPUT, EXIT_OK} if accept and not structural else {EXIT_INPUT}
        cases.append(
            Case(
                f"features/{name}",
                "features",
                ["features", run, "--out", "f.csv", "--group", "air", "--actuator", "PRESS"],
                folder,
                [run],
                ["f.csv"],
                frozenset(expect),
                (run, *words),
            )
        )
    # outputs pointing at inputs, folders, existing files
    folder = _case_dir(root, "features-out-is-input")
    run = _put(folder, "run.parquet", base["run"])
    cases.append(
        Case(
            "features/out_is_input_overwrite",
            "features",
            ["features", run, "--out", run, "--overwrite"],
            folder,
            [run],
            [],
            mentions=("--out",),
        )
    )
    folder = _case_dir(root, "features-out-is-dir")
    run = _put(folder, "run.parquet", base["run"])
    (folder / "d").mkdir(exist_ok=True)
    cases.append(
        Case(
            "features/out_is_folder",
            "features",
            ["features", run, "--out", "d", "--overwrite"],
            folder,
            [run],
            [],
            mentions=("--out",),
        )
    )
    folder = _case_dir(root, "features-bad-group")
    run = _put(folder, "run.parquet", base["run"])
    cases.append(
        Case(
            "features/bad_group",
            "features",
            ["features", run, "--out", "f.csv", "--group", "nonsense"],
            folder,
            [run],
            ["f.csv"],
            mentions=("--group",),
        )
    )
    cases.append(
        Case(
            "features/bad_wavelet",
            "features",
            ["features", run, "--out", "g.csv", "--group", "wavelet", "--wavelet", "nope"],
            folder,
            [run],
            ["g.csv"],
            mentions=("wavelet", "nope"),
        )
    )
    return cases


def build_reference(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = []
    for name, path, words, structural in _bad_recordings(base, root, full, "ref"):
        if (
            not full
            and not structural
            and name not in {"nan_all_first_analog", "analog_at_1hz", "flow_labelled_pa"}
        ):
            continue
        folder = _case_dir(root, f"reference-{name}")
        run = _put(folder, _run_name(path), path)
        # the damaged recording is the only one: it must make a usable reference or be refused
        accept = name in MAY_ACCEPT or (name.startswith("bitflip") and not structural)
        expect = {EXIT_INPUT, EXIT_OK} if accept and not structural else {EXIT_INPUT}
        cases.append(
            Case(
                f"reference build/{name}",
                "reference build",
                ["reference", "build", run, "--out", "r.pnref", "--no-signatures"],
                folder,
                [run],
                ["r.pnref"],
                frozenset(expect),
                (run, *words),
            )
        )
    text = base["toml"].read_text("utf-8")
    muts = list(toml_mutations(text))
    if not full:
        muts = [m for m in muts if m[0] in {"binary_garbage", "nested_inline_5000"}]
    for name, content, words in muts:
        folder = _case_dir(root, f"reference-toml-{name}")
        run = _put(folder, "run.parquet", base["ref"])
        toml = _put(folder, "m.toml", content)
        cases.append(
            Case(
                f"reference build/toml_{name}",
                "reference build",
                [
                    "reference",
                    "build",
                    run,
                    "--machine",
                    toml,
                    "--out",
                    "r.pnref",
                    "--no-signatures",
                ],
                folder,
                [run, toml],
                ["r.pnref"],
                frozenset({EXIT_INPUT}),
                ("m.toml", *words),
            )
        )
    folder = _case_dir(root, "reference-out-is-input")
    run = _put(folder, "run.parquet", base["ref"])
    cases.append(
        Case(
            "reference build/out_is_input_overwrite",
            "reference build",
            ["reference", "build", run, "--out", run, "--overwrite", "--no-signatures"],
            folder,
            [run],
            [],
            mentions=("--out",),
        )
    )
    toml = _put(folder, "m.toml", base["toml"])
    cases.append(
        Case(
            "reference build/out_is_machine_overwrite",
            "reference build",
            [
                "reference",
                "build",
                run,
                "--machine",
                toml,
                "--out",
                toml,
                "--overwrite",
                "--no-signatures",
            ],
            folder,
            [run, toml],
            [],
            mentions=("--out",),
        )
    )
    for opt, value, words in (
        ("--channels", "P_In,NOPE", ("NOPE",)),
        ("--channels", ",", ("--channels",)),
        ("--signature-cycles", "0", ("--signature-cycles",)),
        ("--signature-sizes", "5,3", ("--signature-sizes",)),
        ("--signature-sizes", "nan,inf", ("--signature-sizes",)),
        ("--signature-sizes", "-5,3", ("--signature-sizes",)),
        ("--uncertainty-plants", "-1", ("--uncertainty-plants",)),
        ("--machine", "no-such-machine", ("no-such-machine",)),
        ("--machine", "d", ("d",)),
    ):
        (folder / "d").mkdir(exist_ok=True)
        out = f"o{len(cases)}.pnref"
        cases.append(
            Case(
                f"reference build/{opt}={value}",
                "reference build",
                ["reference", "build", run, "--out", out, opt, value],
                folder,
                [run],
                [out],
                mentions=words,
            )
        )
    return cases


def build_diagnose(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = []
    for name, path, words, structural in _bad_recordings(base, root, full):
        folder = _case_dir(root, f"diagnose-{name}")
        run = _put(folder, _run_name(path), path)
        ref = _put(folder, "ref.pnref", base["pnref"])
        if structural:
            expect = {EXIT_INPUT}
        elif name in MAY_ACCEPT or name.startswith("bitflip"):
            expect = {EXIT_INPUT, EXIT_OK}  # leak-free data: never "leak found"
        else:
            expect = {EXIT_INPUT}
        cases.append(
            Case(
                f"diagnose/{name}",
                "diagnose",
                ["diagnose", run, "--reference", ref, "--json", "d.json"],
                folder,
                [run, ref],
                ["d.json"],
                frozenset(expect),
                (run, *words),
            )
        )
    # damaged references
    ref_items: list[tuple[str, bytes, tuple[str, ...]]] = []
    data = base["pnref"].read_bytes()
    ref_items += [(n, c, ()) for n, c in truncations(data)]
    ref_items += [(n, c, ()) for n, c in bit_flips(data, 16 if full else 3, SEED + 7)]
    muts = list(pnref_mutations(base["pnref"]))
    ref_items += muts if full else [m for m in muts if m[0] in QUICK_PNREF]
    for name, content, words in ref_items:
        folder = _case_dir(root, f"diagnose-ref-{name}")
        run = _put(folder, "run.parquet", base["run"])
        ref = _put(folder, "ref.pnref", content)
        cases.append(
            Case(
                f"diagnose/ref_{name}",
                "diagnose",
                ["diagnose", run, "--reference", ref, "--report", "r.html"],
                folder,
                [run, ref],
                ["r.html"],
                frozenset({EXIT_INPUT}),
                ("ref.pnref", *words),
            )
        )
    # a file name that looks like console markup is printed as written
    folder = _case_dir(root, "diagnose-markup-name")
    run = _put(folder, "run[bold].parquet", base["run"])
    ref = _put(folder, "ref.pnref", base["pnref"])
    cases.append(
        Case(
            "diagnose/markup_in_file_name",
            "diagnose",
            ["diagnose", run, "--reference", ref, "--json", "[red]d.json"],
            folder,
            [run, ref],
            ["[red]d.json"],
            frozenset({EXIT_OK}),
        )
    )
    # outputs pointing at inputs or at each other
    folder = _case_dir(root, "diagnose-outputs")
    run = _put(folder, "run.parquet", base["run"])
    ref = _put(folder, "ref.pnref", base["pnref"])
    (folder / "d").mkdir(exist_ok=True)
    for label, extra, words in (
        ("json_is_run", ["--json", run], ("--json",)),
        ("json_is_run_overwrite", ["--json", run, "--overwrite"], ("--json",)),
        ("report_is_reference", ["--report", ref], ("--report",)),
        ("report_is_reference_overwrite", ["--report", ref, "--overwrite"], ("--report",)),
        ("json_and_report_same", ["--json", "x.out", "--report", "x.out"], ("--report",)),
        ("json_is_folder", ["--json", "d"], ("--json",)),
        ("json_under_a_file", ["--json", f"{run}/x.json"], ("--json",)),
        ("json_via_dotdot", ["--json", f"d/../{run}", "--overwrite"], ("--json",)),
        ("max_leaks_33", ["--max-leaks", "33"], ("--max-leaks",)),
        ("max_leaks_0", ["--max-leaks", "0"], ("--max-leaks",)),
        ("hours_negative", ["--hours", "-1"], ("hours",)),
        ("hours_nan", ["--hours", "nan"], ("hours",)),
        ("price_inf", ["--price", "inf"], ("price",)),
        ("hours_text", ["--hours", "lots"], ("--hours",)),
        ("reference_missing", ["--reference", "nope.pnref"], ("nope.pnref",)),
        ("reference_is_folder", ["--reference", "d"], ("d",)),
        ("reference_is_run", ["--reference", run], ("run.parquet",)),
    ):
        argv = ["diagnose", run, "--reference", ref, *extra]
        outs = [x for x in ("x.out",) if "x.out" in extra]
        cases.append(
            Case(f"diagnose/{label}", "diagnose", argv, folder, [run, ref], outs, mentions=words)
        )
    return cases


QUICK_PNREF = frozenset(
    {
        "header_trace_rate_hz_0",
        "header_n_cycles_100000000000",
        "header_sequence_[1, 2]",
        "header_settings_strict",
        "huge_shape",
        "damaged_deflate",
        "header_deeply_nested",
        "features_object",
    }
)


def build_simulate(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = []
    text = base["toml"].read_text("utf-8")
    muts = list(toml_mutations(text))
    if not full:
        muts = [m for m in muts if m[0] in {"latin1", "nested_arrays_10000", "value_02_bore_mm"}]
    for name, content, words in muts:
        folder = _case_dir(root, f"simulate-{name}")
        toml = _put(folder, "m.toml", content)
        cases.append(
            Case(
                f"simulate/toml_{name}",
                "simulate",
                ["simulate", "--machine", toml, "--cycles", "1", "--out", "o.parquet"],
                folder,
                [toml],
                ["o.parquet"],
                frozenset({EXIT_INPUT}),
                ("m.toml", *words),
            )
        )
    folder = _case_dir(root, "simulate-options")
    toml = _put(folder, "m.toml", base["toml"])
    (folder / "d").mkdir(exist_ok=True)
    for label, extra, words in (
        ("out_is_machine_overwrite", ["--machine", toml, "--out", toml, "--overwrite"], ("--out",)),
        ("out_is_folder", ["--out", "d"], ("--out",)),
        ("cycles_20_digits", ["--cycles", "99999999999999999999999"], ("--cycles",)),
        ("cycles_1e6", ["--cycles", "1000000"], ("--cycles",)),
        ("cycles_0", ["--cycles", "0"], ("--cycles",)),
        ("cycles_negative", ["--cycles", "-3"], ("--cycles",)),
        ("seed_negative", ["--seed", "-1"], ("--seed",)),
        ("seed_huge", ["--seed", "99999999999999999999999999"], ("--seed",)),
        ("leak_unknown_location", ["--leak", "NOWHERE_A=3"], ("NOWHERE_A",)),
        ("leak_no_size", ["--leak", "supply="], ("--leak",)),
        ("leak_nan", ["--leak", "supply=nanslpm"], ("supply", "nan")),
        ("leak_huge", ["--leak", "supply=1e30slpm"], ("supply", "1e30")),
        ("leak_negative_turns", ["--leak", "supply=-2"], ("supply", "-2")),
        ("leak_twice", ["--leak", "supply=3", "--leak", "supply=4"], ("supply",)),
        ("leak_markup", ["--leak", "supply=[/bold]"], ("supply",)),
        ("machine_folder", ["--machine", "d"], ("d",)),
        ("machine_missing", ["--machine", "missing.toml"], ("missing.toml",)),
        ("max_cycle_s_nan", ["--max-cycle-s", "nan"], ("--max-cycle-s",)),
        ("max_cycle_s_zero", ["--max-cycle-s", "0"], ("--max-cycle-s",)),
        ("max_cycle_s_stall", ["--max-cycle-s", "0.2"], ("max_cycle_s",)),
        ("fault_unknown_kind", ["--fault", "supply=wobble:3"], ("wobble",)),
        ("fault_nan_size", ["--fault", "supply=regulator:nanbar"], ("regulator",)),
        ("fault_unknown_location", ["--fault", "NOWHERE=friction:10%"], ("NOWHERE",)),
        ("fault_growth_orphan", ["--fault-growth", "supply=regulator:1/h"], ("--fault-growth",)),
        ("ambient_500C", ["--ambient", "500C"], ("500",)),
        ("payload_unknown_actuator", ["--payload", "NOWHERE=1kg"], ("NOWHERE",)),
        (
            "header_dips_rate_1e9",
            ["--header-dips", "depth=0.3bar,duration=2s,rate=1e9/h"],
            ("header dip rate",),
        ),
    ):
        argv = ["simulate", "--machine", MACHINE, "--out", f"o{len(cases)}.parquet", *extra]
        # any seed >= 0 is a seed: a 26-digit one simulates like any other
        expect = {EXIT_INPUT, EXIT_OK} if label == "seed_huge" else {EXIT_INPUT}
        cases.append(
            Case(
                f"simulate/{label}",
                "simulate",
                argv,
                folder,
                [toml],
                [f"o{len(cases)}.parquet"],
                frozenset(expect),
                words,
            )
        )
    return cases


def build_machines(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "machines")
    return [
        Case("machines/list", "machines", ["machines"], folder, [], [], frozenset({EXIT_OK})),
        Case("machines/extra_arg", "machines", ["machines", "x"], folder, [], [], mentions=("x",)),
    ]


def build_faults(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "faults")
    return [
        Case("faults/list", "faults", ["faults"], folder, [], [], frozenset({EXIT_OK})),
        Case("faults/extra_arg", "faults", ["faults", "x"], folder, [], [], mentions=("x",)),
    ]


def build_standstill_plan(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "standstill-plan")
    blocker = _put(folder, "f.txt", b"a file")
    return [
        Case(
            f"standstill plan/{label}",
            "standstill plan",
            ["standstill", "plan", *extra],
            folder,
            [blocker],
            [],
            mentions=words,
        )
        for label, extra, words in (
            ("unknown_machine", ["--machine", "no-such-machine"], ("no-such-machine",)),
            ("mode_unknown", ["--machine", MACHINE, "--mode", "vacuum"], ("--mode",)),
            ("settle_zero", ["--machine", MACHINE, "--settle", "0"], ("--settle",)),
            ("window_nan", ["--machine", MACHINE, "--window", "nan"], ("--window",)),
            ("out_under_a_file", ["--machine", MACHINE, "--out", f"{blocker}/plan"], ("f.txt",)),
        )
    ]


def build_standstill_analyse(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "standstill-analyse")
    run = _put(folder, "run.parquet", base["run"])
    (folder / "plan").mkdir(exist_ok=True)
    garbage = _put(folder, "plan/plan.json", b'{"mode": "flow", "states": [[[[[')
    deep = _put(folder, "deep.json", ("[" * 100_000 + "]" * 100_000).encode())
    empty = _put(folder, "empty.json", b"{}")
    cases = []
    for label, extra, inputs, words in (
        # the plan (damaged here) is read first: either may be named
        (
            "recording_missing",
            ["missing.parquet", "--plan", "plan"],
            [garbage],
            ("missing.parquet", "plan.json"),
        ),
        ("plan_missing", [run, "--plan", "noplan"], [run], ("noplan", "--plan")),
        ("plan_not_json", [run, "--plan", "plan"], [run, garbage], ("plan.json", "--plan")),
        ("plan_nested", [run, "--plan", deep], [run, deep], ("deep.json", "--plan")),
        ("plan_empty", [run, "--plan", empty], [run, empty], ("empty.json", "--plan")),
    ):
        cases.append(
            Case(
                f"standstill analyse/{label}",
                "standstill analyse",
                ["standstill", "analyse", *extra],
                folder,
                inputs,
                [],
                mentions=words,
            )
        )
    return cases


def build_machine_vary(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = []
    text = base["toml"].read_text("utf-8")
    muts = list(toml_mutations(text))
    if not full:
        muts = [m for m in muts if m[0] in {"utf16", "nested_tables_300"}]
    for name, content, words in muts:
        folder = _case_dir(root, f"vary-{name}")
        toml = _put(folder, "m.toml", content)
        cases.append(
            Case(
                f"machine vary/toml_{name}",
                "machine vary",
                ["machine", "vary", toml, "--out", "p.toml"],
                folder,
                [toml],
                ["p.toml"],
                frozenset({EXIT_INPUT}),
                ("m.toml", *words),
            )
        )
    folder = _case_dir(root, "vary-options")
    toml = _put(folder, "m.toml", base["toml"])
    (folder / "d").mkdir(exist_ok=True)
    for label, extra, words in (
        ("out_is_input_overwrite", [toml, "--out", toml, "--overwrite"], ("--out",)),
        ("out_is_folder", [toml, "--out", "d"], ("--out",)),
        ("scale_nan", [toml, "--out", "a.toml", "--scale", "nan"], ("--scale",)),
        ("scale_huge", [toml, "--out", "a.toml", "--scale", "1e9"], ("--scale",)),
        ("seed_negative", [toml, "--out", "a.toml", "--seed", "-4"], ("--seed",)),
        ("unknown_machine", ["nope", "--out", "a.toml"], ("nope",)),
    ):
        cases.append(
            Case(
                f"machine vary/{label}",
                "machine vary",
                ["machine", "vary", *extra],
                folder,
                [toml],
                ["a.toml"],
                mentions=words,
            )
        )
    return cases


# ----------------------------------------------- commands of issues 10 and 12


def _plc_export(root: Path) -> tuple[Path, Path]:
    """A small PLC-tagged CSV export of the machine and the tag map that imports it (cached)."""
    from pneufdd.recording.plc_export import write_plc_csv

    store = root / "_plc"
    csv, tags = store / "plc.csv", store / "tags.toml"
    if not csv.exists():
        store.mkdir(parents=True, exist_ok=True)
        write_plc_csv(_simulate(3, SEED + 3), csv, tags)
    return csv, tags


def tag_map_mutations(text: str) -> Iterator[tuple[str, bytes, tuple[str, ...]]]:
    """Malformed tag maps: the TOML mutations, then map-specific nonsense."""
    # a comment, so that the Latin-1 mutation has a non-ASCII character to encode
    for name, content, words in toml_mutations("# tag map\n" + text):
        if not name.startswith("value_"):
            yield name, content, words
    lines = text.splitlines()
    valve = next(line for line in lines if '"U_' in line)
    pressure = next(line for line in lines if '"P_In"' in line)
    flow = next(line for line in lines if '"Q_In"' in line)
    time_line = next(line for line in lines if '"time"' in line)
    valve_role = valve.split('role = "')[1].split('"')[0]

    def swap(old: str, new: str) -> bytes:
        return text.replace(old, new, 1).encode()

    yield "unknown_role", swap(f'"{valve_role}"', '"VALVE_7"'), ("VALVE_7", "role")
    yield "duplicated_role", swap(f'"{valve_role}"', '"P_In"'), ("P_In",)
    yield (
        "unknown_unit",
        swap(pressure, pressure.split("unit")[0] + 'unit = "hectobar" }'),
        ("hectobar",),
    )
    flow_no_basis = flow.split("basis")[0].rstrip(", ") + " }"
    yield "lpm_without_basis", swap(flow, flow_no_basis), ("basis",)
    yield "basis_bogus", swap(flow, flow.replace("basis = ", 'basis = "MARS", x = ', 1)), ("x",)
    yield "missing_time_column", swap(time_line + "\n", ""), ("time",)
    yield "digital_with_unit", swap(valve, valve.replace(" }", ', unit = "bar" }')), ("unit",)
    yield "unknown_top_key", (text + "\n[colums]\nx = 1\n").encode(), ("colums",)
    yield "columns_is_string", b'columns = "all"\n', ("columns",)
    yield "rate_hz_zero", ("rate_hz = 0\n" + text).encode(), ("rate_hz",)
    yield "rate_hz_huge", ("rate_hz = 1e308\n" + text).encode(), ("rate_hz",)
    yield "no_valves", "\n".join(x for x in lines if '"U_' not in x).encode(), ("valve",)
    yield (
        "role_not_mapped_in_file",
        (text + '\n"NOPE" = { role = "S_EXTRA_A" }\n').encode(),
        ("NOPE",),
    )


QUICK_TAG_MAP = frozenset({"utf16", "unknown_role", "duplicated_role", "lpm_without_basis"})
QUICK_NEW_RECORDINGS = frozenset({"empty", "cut_50pct", "bitflip_0", "parquet_rate_zero"})


def _map_cases(
    command: str, argv: Callable[[str, str], list[str]], root: Path, full: bool, out: str
) -> list[Case]:
    """``command`` reading the PLC export through each damaged tag map."""
    csv, tags = _plc_export(root)
    text = tags.read_text("utf-8")
    cases = []
    for name, content, words in tag_map_mutations(text):
        if not full and name not in QUICK_TAG_MAP:
            continue
        folder = _case_dir(root, f"{command.replace(' ', '-')}-map-{name}")
        data = _put(folder, "plc.csv", csv)
        mapping = _put(folder, "tags.toml", content)
        cases.append(
            Case(
                f"{command}/map_{name}",
                command,
                argv(data, mapping),
                folder,
                [data, mapping],
                [out],
                frozenset({EXIT_INPUT}),
                ("tags.toml", *words),
            )
        )
    return cases


def _recording_cases(
    command: str,
    argv: Callable[[str], list[str]],
    base: dict[str, Path],
    root: Path,
    full: bool,
    outputs: list[str],
    data_mutations: bool = True,
) -> list[Case]:
    """``command`` on each damaged recording (structural damage must be refused)."""
    cases = []
    for name, path, words, structural in _bad_recordings(base, root, full):
        if not full and name not in QUICK_NEW_RECORDINGS:
            continue
        if not structural and not data_mutations:
            continue
        folder = _case_dir(root, f"{command.replace(' ', '-')}-{name}")
        run = _put(folder, _run_name(path), path)
        expect = {EXIT_INPUT} if structural else {EXIT_INPUT, EXIT_OK}
        cases.append(
            Case(
                f"{command}/{name}",
                command,
                argv(run),
                folder,
                [run],
                outputs,
                frozenset(expect),
                (run, *words),
            )
        )
    return cases


def build_import(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = _map_cases(
        "import",
        lambda data, mapping: ["import", data, "--map", mapping, "--out", "o.parquet"],
        root,
        full,
        "o.parquet",
    )
    csv, tags = _plc_export(root)
    store = root / "_plc_damaged"
    store.mkdir(parents=True, exist_ok=True)
    data = csv.read_bytes()
    damaged = list(truncations(data))
    lines = csv.read_text("utf-8").splitlines()
    damaged += [
        (
            "csv_text_in_number",
            "\n".join([*lines[:5], lines[5].replace(",", ",abc", 1), *lines[6:]]).encode(),
        ),
        ("csv_header_only", (lines[0] + "\n").encode()),
        ("csv_time_backwards", "\n".join([lines[0], *lines[1:][::-1]]).encode()),
        ("csv_binary", bytes(range(256)) * 8),
    ]
    if not full:
        damaged = [d for d in damaged if d[0] in {"empty", "cut_50pct", "csv_text_in_number"}]
    for name, content in damaged:
        # without its last newline the export is still a whole CSV file
        whole = name == "minus_1_byte" and data.endswith(b"\n")
        folder = _case_dir(root, f"import-csv-{name}")
        run = _put(folder, "plc.csv", content)
        mapping = _put(folder, "tags.toml", tags)
        cases.append(
            Case(
                f"import/csv_{name}",
                "import",
                ["import", run, "--map", mapping, "--out", "o.parquet"],
                folder,
                [run, mapping],
                ["o.parquet"],
                frozenset({EXIT_INPUT, EXIT_OK} if whole else {EXIT_INPUT}),
                ("plc.csv", "tags.toml"),
            )
        )
    folder = _case_dir(root, "import-options")
    run = _put(folder, "plc.csv", csv)
    mapping = _put(folder, "tags.toml", tags)
    (folder / "d").mkdir(exist_ok=True)
    for label, extra, words in (
        ("out_is_data", [run, "--map", mapping, "--out", run], ("--out",)),
        ("out_is_data_overwrite", [run, "--map", mapping, "--out", run, "--overwrite"], ("--out",)),
        (
            "out_is_map_overwrite",
            [run, "--map", mapping, "--out", mapping, "--overwrite"],
            ("--out",),
        ),
        ("out_is_folder", [run, "--map", mapping, "--out", "d"], ("--out",)),
        ("map_is_folder", [run, "--map", "d", "--out", "a.parquet"], ("d",)),
        ("map_missing", [run, "--map", "none.toml", "--out", "a.parquet"], ("none.toml",)),
        ("data_missing", ["none.csv", "--map", mapping, "--out", "a.parquet"], ("none.csv",)),
        ("data_is_folder", ["d", "--map", mapping, "--out", "a.parquet"], ("d",)),
        ("data_bad_suffix", [mapping, "--map", mapping, "--out", "a.parquet"], ("suffix",)),
    ):
        cases.append(
            Case(
                f"import/{label}",
                "import",
                ["import", *extra],
                folder,
                [run, mapping],
                ["a.parquet"],
                mentions=words,
            )
        )
    return cases


def build_machine_draft(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    cases = _recording_cases(
        "machine draft",
        lambda run: ["machine", "draft", run, "--out", "d.toml"],
        base,
        root,
        full,
        ["d.toml"],
    )
    cases += _map_cases(
        "machine draft",
        lambda data, mapping: ["machine", "draft", data, "--map", mapping, "--out", "d.toml"],
        root,
        full,
        "d.toml",
    )
    folder = _case_dir(root, "draft-options")
    run = _put(folder, "run.parquet", base["run"])
    (folder / "d").mkdir(exist_ok=True)
    for label, extra, words in (
        ("out_is_input", [run, "--out", run], ("--out",)),
        ("out_is_input_overwrite", [run, "--out", run, "--overwrite"], ("--out",)),
        ("out_is_folder", [run, "--out", "d"], ("--out",)),
        ("out_in_a_file", [run, "--out", f"{run}/x.toml"], ("--out",)),
        ("recording_missing", ["none.parquet", "--out", "a.toml"], ("none.parquet",)),
        ("recording_is_folder", ["d", "--out", "a.toml"], ("d",)),
        ("name_empty", [run, "--out", "a.toml", "--name", ""], ("--name", "name")),
        ("name_quote", [run, "--out", "a.toml", "--name", 'a"b\n[x]'], ("--name", "name")),
    ):
        cases.append(
            Case(
                f"machine draft/{label}",
                "machine draft",
                ["machine", "draft", *extra],
                folder,
                [run],
                ["a.toml"],
                mentions=words,
            )
        )
    return cases


def build_machine_calibrate(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    # only damage refused before the twin runs: a calibration takes minutes
    cases = _recording_cases(
        "machine calibrate",
        lambda run: ["machine", "calibrate", MACHINE, run, "--out", "c.toml"],
        base,
        root,
        full,
        ["c.toml"],
        data_mutations=False,
    )
    text = base["toml"].read_text("utf-8")
    for name, content, words in toml_mutations(text):
        if not full and name not in {"latin1", "value_01_bore_mm"}:
            continue
        folder = _case_dir(root, f"calibrate-toml-{name}")
        toml = _put(folder, "m.toml", content)
        run = _put(folder, "run.parquet", base["run"])
        cases.append(
            Case(
                f"machine calibrate/toml_{name}",
                "machine calibrate",
                ["machine", "calibrate", toml, run, "--out", "c.toml"],
                folder,
                [toml, run],
                ["c.toml"],
                frozenset({EXIT_INPUT}),
                ("m.toml", *words),
            )
        )
    cases += _map_cases(
        "machine calibrate",
        lambda data, mapping: [
            "machine",
            "calibrate",
            MACHINE,
            data,
            "--map",
            mapping,
            "--out",
            "c.toml",
        ],
        root,
        full,
        "c.toml",
    )
    folder = _case_dir(root, "calibrate-options")
    run = _put(folder, "run.parquet", base["run"])
    toml = _put(folder, "m.toml", base["toml"])
    (folder / "d").mkdir(exist_ok=True)
    for label, extra, words in (
        ("out_is_recording_overwrite", [MACHINE, run, "--out", run, "--overwrite"], ("--out",)),
        ("out_is_machine_overwrite", [toml, run, "--out", toml, "--overwrite"], ("--out",)),
        ("report_is_recording", [MACHINE, run, "--out", "a.toml", "--report", run], ("--report",)),
        ("report_is_out", [MACHINE, run, "--out", "a.toml", "--report", "a.toml"], ("--report",)),
        ("out_is_folder", [MACHINE, run, "--out", "d"], ("--out",)),
        ("report_is_folder", [MACHINE, run, "--out", "a.toml", "--report", "d"], ("--report",)),
        ("unknown_machine", ["nope", run, "--out", "a.toml"], ("nope",)),
        ("recording_missing", [MACHINE, "none.parquet", "--out", "a.toml"], ("none.parquet",)),
        (
            "max_evaluations_1",
            [MACHINE, run, "--out", "a.toml", "--max-evaluations", "1"],
            ("--max-evaluations",),
        ),
        (
            "max_evaluations_20_digits",
            [MACHINE, run, "--out", "a.toml", "--max-evaluations", "99999999999999999999999"],
            ("--max-evaluations",),
        ),
    ):
        cases.append(
            Case(
                f"machine calibrate/{label}",
                "machine calibrate",
                ["machine", "calibrate", *extra],
                folder,
                [run, toml],
                ["a.toml"],
                mentions=words,
            )
        )
    return cases


def build_evaluate(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "evaluate")
    (folder / "empty").mkdir(exist_ok=True)
    (folder / "bad").mkdir(exist_ok=True)
    (folder / "bad" / "manifest.json").write_text("{not json")
    (folder / "list").mkdir(exist_ok=True)
    (folder / "list" / "manifest.json").write_text("[1, 2]")
    (folder / "nomachines").mkdir(exist_ok=True)
    (folder / "nomachines" / "manifest.json").write_text('{"design": {}, "machines": 3}')
    run = _put(folder, "run.parquet", base["run"])
    cases = []
    for label, extra, words in (
        ("missing_folder", ["nowhere"], ("nowhere",)),
        ("empty_folder", ["empty"], ("empty", "manifest")),
        ("campaign_is_file", [run], ("run.parquet",)),
        ("manifest_not_json", ["bad"], ("manifest",)),
        ("manifest_is_list", ["list"], ("manifest",)),
        ("manifest_machines_int", ["nomachines"], ("manifest", "machines")),
        ("out_is_file", ["empty", "--out", run], ("--out", "run.parquet")),
        ("workers_0", ["empty", "--workers", "0"], ("--workers",)),
        ("workers_20_digits", ["empty", "--workers", "99999999999999999999"], ("--workers",)),
    ):
        cases.append(
            Case(
                f"evaluate/{label}",
                "evaluate",
                ["evaluate", *extra],
                folder,
                [run, "bad/manifest.json", "list/manifest.json", "nomachines/manifest.json"],
                ["empty/evaluation/evaluation.csv"],
                mentions=words,
            )
        )
    return cases


def build_vector_map(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "vector-map")
    run = _put(folder, "run.parquet", base["run"])
    toml = _put(folder, "m.toml", b"[machine\n")
    cases = []
    for label, extra, words in (
        ("out_is_file", ["--out", run], ("--out", "run.parquet")),
        ("unknown_machine", ["--out", "o", "--machine", "nope"], ("nope",)),
        ("machine_damaged", ["--out", "o", "--machine", toml], ("m.toml",)),
        ("unknown_actuator", ["--out", "o", "--actuator", "NOPE"], ("NOPE",)),
        ("sizes_words", ["--out", "o", "--sizes", "a,b"], ("--sizes", "a")),
        ("sizes_empty", ["--out", "o", "--sizes", ","], ("--sizes",)),
        ("sizes_nan", ["--out", "o", "--sizes", "nan"], ("--sizes", "nan")),
        ("sizes_huge", ["--out", "o", "--sizes", "1e308"], ("--sizes", "1e308")),
        ("sizes_negative", ["--out", "o", "--sizes", "-2,4"], ("--sizes", "-2")),
        ("cycles_1", ["--out", "o", "--cycles", "1"], ("--cycles",)),
        ("cycles_20_digits", ["--out", "o", "--cycles", "99999999999999999999"], ("--cycles",)),
        ("plant_scale_nan", ["--out", "o", "--plant-scale", "nan"], ("--plant-scale",)),
        ("plant_scale_huge", ["--out", "o", "--plant-scale", "1e9"], ("--plant-scale",)),
        ("seed_negative", ["--out", "o", "--seed", "-1"], ("--seed",)),
        # simulates (seconds): the press ram's air per stroke no sensor gives
        *(
            [("air_not_measured", ["--out", "o", "--cycles", "2", "--sizes", "2"], ("PRESS",))]
            if full
            else []
        ),
    ):
        cases.append(
            Case(
                f"vector-map/{label}",
                "vector-map",
                ["vector-map", "--machine", MACHINE, "--actuator", "PRESS", *extra],
                folder,
                [run, toml],
                ["o/vector_sum.txt"],
                mentions=words,
            )
        )
    return cases


def build_history(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "history")
    (folder / "d").mkdir(exist_ok=True)
    notdb = _put(folder, "notdb.db", b"garbage, not a database\n")
    cases = []
    for label, extra, inputs, words in (
        ("url_not_a_url", ["--history", "notaurl"], [], ("--history",)),
        ("url_is_folder", ["--history", "sqlite:///d"], [], ("--history",)),
        ("url_not_a_database", ["--history", f"sqlite:///{notdb}"], [notdb], ("--history",)),
        ("url_other_backend", ["--history", "mysql://u@h/db"], [], ("--history",)),
        ("url_missing_file", ["--history", "sqlite:///missing.db"], [], ("--history",)),
        ("since_not_a_date", ["--since", "notadate"], [], ("--since",)),
    ):
        cases.append(
            Case(
                f"history/{label}",
                "history",
                ["history", *extra],
                folder,
                inputs,
                [],
                mentions=words,
            )
        )
    return cases


def build_monitor(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "monitor")
    ref = _put(folder, "ref.pnref", base["pnref"]) if "pnref" in base else None
    bad = _put(folder, "bad.pnref", b"not a reference")
    run = _put(folder, "run.parquet", base["run"])
    cases = [
        Case(
            "monitor/reference_missing",
            "monitor",
            ["monitor", "--reference", "missing.pnref", "--source", "replay:x.parquet", "--once"],
            folder,
            [],
            [],
            mentions=("missing.pnref",),
        ),
        Case(
            "monitor/reference_damaged",
            "monitor",
            ["monitor", "--reference", bad, "--source", "replay:x.parquet", "--once"],
            folder,
            [bad],
            [],
            mentions=("bad.pnref",),
        ),
    ]
    if ref is not None:
        for label, source, words in (
            ("source_scheme", "ftp://host/x", ("--source", "ftp")),
            ("replay_missing", "replay:missing.parquet", ("missing.parquet",)),
            ("replay_speed", f"replay:{run}?speed=-3", ("speed", "--source")),
        ):
            cases.append(
                Case(
                    f"monitor/{label}",
                    "monitor",
                    [
                        "monitor",
                        "--reference",
                        ref,
                        "--source",
                        source,
                        "--once",
                        "--history",
                        "sqlite:///h.db",
                    ],
                    folder,
                    [ref, run],
                    [],
                    mentions=words,
                )
            )
    return cases


def build_build_twin(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "build-twin")
    blocker = _put(folder, "f.txt", b"a file where the folder should be")
    return [
        Case(
            f"build-twin/{label}",
            "build-twin",
            ["build-twin", *extra],
            folder,
            [blocker],
            [],
            mentions=words,
        )
        for label, extra, words in (
            ("dir_is_a_file", ["--dir", blocker], ("f.txt",)),
            ("dir_under_a_file", ["--dir", f"{blocker}/sub"], ("f.txt",)),
            ("force_with_value", ["--force", "yes"], ("yes",)),
            ("unknown_option", ["--fast"], ("--fast",)),
        )
    ]


BUILDERS: dict[str, Builder] = {
    "steps": build_steps,
    "features": build_features,
    "reference build": build_reference,
    "diagnose": build_diagnose,
    "simulate": build_simulate,
    "machines": build_machines,
    "faults": build_faults,
    "machine vary": build_machine_vary,
    "history": build_history,
    "monitor": build_monitor,
    "import": build_import,
    "machine draft": build_machine_draft,
    "standstill plan": build_standstill_plan,
    "standstill analyse": build_standstill_analyse,
    "machine calibrate": build_machine_calibrate,
    "evaluate": build_evaluate,
    "vector-map": build_vector_map,
    "build-twin": build_build_twin,
}
"""Case builders by command path; a command added to the CLI adds one here."""

NOT_FUZZED: dict[str, str] = {
    "demo": "no hand-written cases (minutes per run): the generators give it what it must refuse",
    "campaign": "no hand-written cases (hours per run): the bounds and the generators do",
}
"""Commands without hand-written cases, with the reason; every command, these too, has an
entry in :data:`fuzzing_generators.COMMANDS`."""


def discover_commands() -> list[str]:
    """Every command path of the ``pneufdd`` CLI (``"reference build"``...)."""
    import typer.main

    from pneufdd.cli.app import app

    group = typer.main.get_command(app)
    found: list[str] = []

    def walk(cmd: Any, prefix: str) -> None:
        for name, sub in sorted(getattr(cmd, "commands", {}).items()):
            path = f"{prefix} {name}".strip()
            if getattr(sub, "commands", None):
                walk(sub, path)
            else:
                found.append(path)

    walk(group, "")
    return found


PARTS = ("cases", "outputs", "files", "generated", "bounds")
"""The parts of the corpus: hand-written cases (:data:`BUILDERS`), the output policy
(:mod:`fuzzing_outputs`), hostile files (:mod:`fuzzing_files`), the seeded generators
(:mod:`fuzzing_generators`) and the resource bounds (:mod:`fuzzing_bounds`)."""


def build_corpus(
    base: dict[str, Path],
    root: Path,
    full: bool = True,
    commands: Iterable[str] | None = None,
    seed: int | None = None,
    per_command: int | None = None,
    parts: Iterable[str] = PARTS,
) -> list[Case]:
    """Every case of the corpus (``full``) or of its quick slice; ``seed`` and
    ``per_command``: the generators' seed and variants per command (their defaults
    :data:`fuzzing_generators.SEED` and :data:`fuzzing_generators.PER_COMMAND`);
    ``parts``: which of :data:`PARTS` to build."""
    import fuzzing_bounds
    import fuzzing_files
    import fuzzing_generators
    import fuzzing_outputs

    part = set(parts)
    cases: list[Case] = []
    chosen = list(commands or discover_commands())
    for command in chosen if "cases" in part else ():
        builder = BUILDERS.get(command)
        if builder is not None:
            cases.extend(builder(base, root, full))
    # resource bounds (issue 39): campaign's bounds fail at once, so they are fuzzed too
    wanted = chosen if commands is not None else [*chosen, "campaign"]
    if "outputs" in part:
        cases += fuzzing_outputs.build_outputs(base, root, full, chosen)
    if "files" in part:
        cases += fuzzing_files.build_files(base, root, full, chosen)
    every = chosen if commands is not None else discover_commands()  # campaign and demo too
    if "generated" in part:
        cases += fuzzing_generators.build_generated(
            base,
            root,
            full,
            every,
            fuzzing_generators.SEED if seed is None else seed,
            per_command,
        )
    if "bounds" in part:
        cases += fuzzing_bounds.build_bounds(base, root, full, wanted)
    return cases


# ------------------------------------------------------------------ running


def _digest(path: Path) -> tuple[str, int] | None:
    if not path.exists():
        return None
    if path.is_dir():
        return ("dir", 0)
    return hashlib.sha256(path.read_bytes()).hexdigest(), path.stat().st_mode


def run_case(case: Case, in_process: bool) -> Outcome:
    """Run one case and check it (see the module docstring)."""
    before = {name: _digest(case.folder / name) for name in case.inputs}
    outputs_before = {name: _digest(case.folder / name) for name in case.outputs}
    listing_before = set(os.listdir(case.folder))
    start = time.perf_counter()
    peak: int | None = None
    cpu: float | None = None
    if in_process:
        code, stderr, stdout = _in_process(case)
    else:
        code, stderr, stdout, peak, cpu = _subprocess(case)
    seconds = time.perf_counter() - start
    problems = check(case, code, stderr, before, outputs_before, listing_before)
    shown = [s for s in case.secrets if s in stderr or s in stdout]
    if shown:
        problems.append(f"printed a secret: {shown}")
    through = [n for n in case.absent if os.path.lexists(case.folder / n)]
    if through:
        problems.append(f"wrote outside its outputs, through a link: {through}")
    if code == EXIT_HANG and not case.live:
        used = "" if cpu is None else f"; {cpu:.1f} s of CPU"
        problems.append(f"hang (killed after {CASE_TIMEOUT_S:g} s{used})")
    if peak is not None and peak > RSS_LIMIT_BYTES:
        problems.append(f"resident set {peak / 2**30:.2f} GiB, over 2 GiB")
    return Outcome(case, code, stderr, seconds, problems, peak, cpu)


def _in_process(case: Case) -> tuple[int, str, str]:
    from pneufdd.cli.app import main

    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(case.folder)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main(list(case.argv))
    finally:
        os.chdir(cwd)
    return code, err.getvalue(), out.getvalue()


def _cap_memory() -> None:
    """In the child before exec: the address-space cap of :data:`MEMORY_CAP_BYTES`."""
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP_BYTES, MEMORY_CAP_BYTES))


def _subprocess(case: Case) -> tuple[int, str, str, int, float]:
    """Exit code (:data:`EXIT_HANG` when killed at the time limit), stderr, stdout, the
    peak resident set [bytes] and the CPU time used [s]."""
    import threading

    exe = Path(sys.executable).with_name("pneufdd")
    env = dict(os.environ, COLUMNS="200", NO_COLOR="1")
    proc = subprocess.Popen(
        [str(exe), *case.argv],
        cwd=case.folder,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=_cap_memory,
    )
    assert proc.stdout is not None
    assert proc.stderr is not None
    streams: dict[str, bytes] = {}
    readers = [
        threading.Thread(target=lambda n=n, s=s: streams.__setitem__(n, s.read()))
        for n, s in (("out", proc.stdout), ("err", proc.stderr))
    ]
    for reader in readers:
        reader.start()
    hung = threading.Event()

    def _kill() -> None:
        hung.set()
        proc.kill()

    timer = threading.Timer(LIVE_S if case.live else CASE_TIMEOUT_S, _kill)
    timer.start()
    peak = [0]
    ended = threading.Event()
    watcher = threading.Thread(target=_watch_peak, args=(proc.pid, ended, peak))
    watcher.start()
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    finally:
        ended.set()
        timer.cancel()
        watcher.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    for reader in readers:
        reader.join()
    proc.stdout.close()
    proc.stderr.close()
    stderr = streams.get("err", b"").decode("utf-8", "replace")
    stdout = streams.get("out", b"").decode("utf-8", "replace")
    code = EXIT_HANG if hung.is_set() else proc.returncode
    return code, stderr, stdout, peak[0], usage.ru_utime + usage.ru_stime


def _watch_peak(pid: int, ended: Any, peak: list[int], every_s: float = 0.05) -> None:
    """The command's own peak resident set [bytes] into ``peak[0]``: its ``VmHWM`` (the
    high-water mark of the program's memory, which starts afresh at ``exec``), read every
    ``every_s`` until it ends. Not ``wait4``'s ``ru_maxrss``: on Linux that also holds the
    resident set of the forked copy of this harness before ``exec`` (the harness holds
    the corpus: 2 GB, which every command then seemed to use). Growth in the last
    ``every_s`` before the command exits is not seen."""
    status = Path(f"/proc/{pid}/status")
    while not ended.is_set():
        try:
            text = status.read_text()
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:  # ended meanwhile (a zombie has no memory left to read)
            return
        if b"pneufdd" in cmdline and b"fuzzing.py" not in cmdline:  # after exec
            for line in text.splitlines():
                if line.startswith("VmHWM:"):
                    peak[0] = max(peak[0], int(line.split()[1]) * 1024)
        ended.wait(every_s)


def check(
    case: Case,
    code: int,
    stderr: str,
    before: dict[str, Any],
    outputs_before: dict[str, Any],
    listing_before: set[str],
) -> list[str]:
    """The problems of one invocation (empty: it behaved)."""
    problems = []
    if "Traceback" in stderr:
        problems.append("traceback")
    if code == EXIT_INTERNAL:
        problems.append("internal error (exit 3)")
    if code not in case.expect:
        problems.append(f"exit {code}, allowed {sorted(case.expect)}")
    for name, digest in before.items():
        if _digest(case.folder / name) != digest:
            problems.append(f"input {name} changed")
    # a temporary file of this case's outputs (cases sharing a folder run in parallel)
    leftovers = [
        n
        for n in set(os.listdir(case.folder)) - listing_before
        if n.endswith(".tmp") and any(n.startswith(f".{Path(o).name}.") for o in case.outputs)
    ]
    if leftovers:
        problems.append(f"temporary files left: {leftovers}")
    # a command that refused its input writes nothing at all, named or not (files that
    # other cases of the folder may write meanwhile, and their temporaries, excepted)
    if code == EXIT_INPUT:
        # (an output of another case may sit in a folder it creates: its first part)
        others = {Path(o).parts[0] for o in _FOLDER_OUTPUTS.get(case.folder, set())}
        written = sorted(
            n
            for n in set(os.listdir(case.folder)) - listing_before - set(case.outputs)
            if n not in others and not (n.endswith(".tmp") or n.endswith(("-wal", "-shm")))
        )
        if written:
            problems.append(f"wrote outside its outputs after exit 2: {written}")
    for name in case.outputs:
        now = _digest(case.folder / name)
        if code in (EXIT_OK, EXIT_LEAK):
            if now is None and name not in case.optional:
                problems.append(f"output {name} missing after exit {code}")
            elif now is not None and not _readable(case.folder / name):
                problems.append(f"output {name} unreadable")
        elif now != outputs_before[name] and not _journal(case, name, stderr):
            problems.append(f"partial output {name} after exit {code}")
    if code == EXIT_INPUT:
        text = " ".join(stderr.split())
        if "error" not in text.lower():
            problems.append("exit 2 without an error message")
        elif case.mentions and not any(w.lower() in text.lower() for w in case.mentions):
            problems.append(f"message names none of {list(case.mentions)}")
    return problems


JOURNALS = {"monitor": ("error: no cycle was judged", (".db",))}
"""Outputs that log what the input gave as it is read, kept after an exit 2 that comes
only at the end: a monitor's history keeps the cycles it recorded when it judged none
(docs/monitor.md, "A run that judged no cycle"). Command -> (the exit-2 message, the
suffixes of such outputs)."""


def _journal(case: Case, name: str, stderr: str) -> bool:
    """Whether output ``name`` of ``case`` is a journal that an exit 2 rightly keeps."""
    said, suffixes = JOURNALS.get(case.command, ("\x00", ()))
    return said in " ".join(stderr.split()) and name.endswith(suffixes)


def _readable(path: Path) -> bool:
    try:
        if path.suffix == ".json":
            json.loads(path.read_text("utf-8"))
        elif path.suffix == ".parquet":
            Recording.read(path)
        elif path.suffix == ".pnref":
            from pneufdd.diagnosis.reference.file import load_reference

            load_reference(path)
        elif path.suffix in (".csv", ".html", ".toml"):
            text = path.read_text("utf-8")
            if path.suffix == ".html" and "</html>" not in text:
                return False
            if path.suffix == ".toml":
                import tomllib

                tomllib.loads(text)
        return True
    except Exception:
        return False


_FOLDER_OUTPUTS: dict[Path, set[str]] = {}
"""Every output name of the cases sharing a folder (they may run at the same time)."""


def _record(outcome: Outcome) -> dict[str, Any]:
    """One outcome as JSON (``--json`` and its running ``.jsonl``)."""
    o = outcome
    return {
        "case": o.case.name,
        "command": o.case.command,
        "argv": o.case.argv,
        "exit": o.code,
        "problems": o.problems,
        "stderr": o.stderr[-2000:],
        "seconds": round(o.seconds, 2),
        "peak_rss_mib": None if o.peak_rss is None else round(o.peak_rss / 2**20, 1),
        "cpu_s": None if o.cpu_s is None else round(o.cpu_s, 2),
    }


def run_corpus(
    cases: list[Case],
    in_process: bool,
    workers: int = 1,
    log: Callable[[str], None] | None = None,
    running: Path | None = None,
) -> list[Outcome]:
    """Run ``cases`` (in ``workers`` threads when in subprocesses); ``running``: a JSON-lines
    file each outcome is appended to as it ends (a long run stopped early keeps them)."""
    sink = running.open("a", encoding="utf-8") if running is not None else None

    def ran(outcome: Outcome) -> Outcome:
        if sink is not None:
            sink.write(json.dumps(_record(outcome)) + "\n")
            sink.flush()
        return outcome

    try:
        return _run_all(cases, in_process, workers, log, ran)
    finally:
        if sink is not None:
            sink.close()


def _run_all(
    cases: list[Case],
    in_process: bool,
    workers: int,
    log: Callable[[str], None] | None,
    ran: Callable[[Outcome], Outcome],
) -> list[Outcome]:
    for case in cases:
        _FOLDER_OUTPUTS.setdefault(case.folder, set()).update(case.outputs)
    if in_process or workers <= 1:
        outcomes = []
        for k, case in enumerate(cases):
            outcomes.append(ran(run_case(case, in_process)))
            if log and outcomes[-1].problems:
                log(f"[{k + 1}/{len(cases)}] {case.name}: {outcomes[-1].problems}")
        return outcomes
    with ThreadPoolExecutor(workers) as pool:
        futures = {pool.submit(run_case, c, False): k for k, c in enumerate(cases)}
        done: dict[int, Outcome] = {}
        for future in as_completed(futures):  # each problem printed when it happens
            k = futures[future]
            done[k] = ran(future.result())
            if log and done[k].problems:
                log(f"[{len(done)}/{len(cases)}] {cases[k].name}: {done[k].problems}")
    return [done[k] for k in range(len(cases))]


def summary(outcomes: list[Outcome]) -> dict[str, Any]:
    """Counts for the report: invocations, tracebacks, changed inputs, partial outputs."""
    by_command: dict[str, dict[int, int]] = {}
    for o in outcomes:
        counts = by_command.setdefault(o.case.command, {})
        counts[o.code] = counts.get(o.code, 0) + 1
    flat = [p for o in outcomes for p in o.problems]
    return {
        "invocations": len(outcomes),
        "tracebacks": sum("Traceback" in o.stderr for o in outcomes),
        "internal_errors": sum(o.code == EXIT_INTERNAL for o in outcomes),
        "inputs_changed": sum(p.startswith("input ") for p in flat),
        "partial_outputs": sum(p.startswith(("partial output", "temporary")) for p in flat),
        "writes_outside_outputs": sum(p.startswith("wrote outside") for p in flat),
        "secrets_printed": sum(p.startswith("printed a secret") for p in flat),
        "cases_with_problems": sum(bool(o.problems) for o in outcomes),
        "hangs": sum(o.code == EXIT_HANG and not o.case.live for o in outcomes),
        "live_stopped": sum(o.code == EXIT_HANG and o.case.live for o in outcomes),
        "over_2_gib": sum(
            o.peak_rss is not None and o.peak_rss > RSS_LIMIT_BYTES for o in outcomes
        ),
        "largest_rss_mib": round(max((o.peak_rss or 0) for o in outcomes) / 2**20, 1)
        if outcomes
        else 0.0,
        "slowest_s": round(max((o.seconds for o in outcomes), default=0.0), 1),
        "slowest_case": max(outcomes, key=lambda o: o.seconds).case.name if outcomes else None,
        "most_cpu_s": round(max((o.cpu_s or 0.0) for o in outcomes), 1) if outcomes else 0.0,
        "largest_rss_case": max(outcomes, key=lambda o: o.peak_rss or 0).case.name
        if outcomes
        else None,
        "exit_codes_by_command": {
            c: dict(sorted(v.items())) for c, v in sorted(by_command.items())
        },
        "seconds": round(sum(o.seconds for o in outcomes), 1),
    }


def _release_memory() -> None:
    """Give back what building the corpus took (hostile files of 100 MB were made in
    memory) before thousands of commands are forked from this process."""
    import ctypes
    import gc

    gc.collect()
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6").malloc_trim(0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("build/fuzz"), help="work folder")
    parser.add_argument("--quick", action="store_true", help="only the quick slice")
    parser.add_argument("--in-process", action="store_true", help="call main() in-process")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--command",
        action="append",
        help="only this command (repeatable; e.g. --command 'reference build')",
    )
    parser.add_argument(
        "--seed", type=int, default=None, help="seed of the generators (default 97,000,100)"
    )
    parser.add_argument(
        "--per-command", type=int, default=None, help="generated variants per command (24)"
    )
    parser.add_argument("--json", type=Path, help="write every outcome here")
    parser.add_argument(
        "--part", action="append", choices=PARTS, help="only these parts (repeatable; all)"
    )
    parser.add_argument("--case", help="only the cases whose name contains this text")
    parser.add_argument(
        "--shuffle", action="store_true", help="run the cases in an order drawn with --seed"
    )
    args = parser.parse_args(argv)
    full = not args.quick
    base = make_base(args.out / "base", full=full)
    cases_root = args.out / "cases"
    if cases_root.exists():
        shutil.rmtree(cases_root)
    unknown = sorted(set(args.command or ()) - set(discover_commands()))
    if unknown:
        parser.error(f"unknown --command {unknown}; the commands: {discover_commands()}")
    cases = build_corpus(
        base, cases_root, full, args.command, args.seed, args.per_command, args.part or PARTS
    )
    if args.case:
        cases = [c for c in cases if args.case in c.name]
    if args.shuffle:  # any prefix of the run is then a sample of every command
        order = np.random.default_rng(args.seed or 0).permutation(len(cases))
        cases = [cases[int(k)] for k in order]
    _release_memory()
    import fuzzing_generators

    missing = fuzzing_generators.missing_entries(discover_commands())
    print(f"{len(cases)} invocations; commands without cases: {missing or 'none'}", flush=True)
    running = None if args.json is None else args.json.with_suffix(".running.jsonl")
    if running is not None:
        running.unlink(missing_ok=True)
    say = lambda s: print(s, flush=True)  # noqa: E731
    outcomes = run_corpus(cases, args.in_process, args.workers, say, running)
    result = summary(outcomes)
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps([_record(o) for o in outcomes], indent=1))
    return 1 if result["cases_with_problems"] or missing else 0


if __name__ == "__main__":
    sys.exit(main())
