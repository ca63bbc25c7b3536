"""Hostile files of the fuzz corpus: issue 39's third adversarial round (seeds 97,000,000+).

What an attacker or a careless user feeds the readers, beyond the corpus of
:mod:`fuzzing` and :mod:`fuzzing_bounds`:

* TDMS files whose headers declare what the file does not hold: a 4 GiB name, 4 x 10^9
  properties or objects, 2^40 samples, DAQmx widths of 16 GiB, 10^5 segments, 20,000
  objects repeated over segments, string and time channels, timing properties that
  are text, NaN or 1e-300, and seeded random damage of every header field
  (``import`` and ``steps`` through a tag map);
* CSV exports in every ``--format`` layout (and the plain one) with a byte-order mark,
  mixed line endings, a 100 MB line, time that goes backwards or repeats, 10^6
  columns, thousands separators, a preamble that never ends, an unclosed quote;
* tag maps whose names are traversal, markup or 10,000 characters;
* ``monitor --source`` URLs with hostile queries, ports, hosts and credentials (a
  password is never printed);
* ``.pnref`` zips: an inflate bomb, 10^5 members, traversal and duplicate names,
  encrypted and unknown-method members;
* Parquet recordings of odd schemas: nested and dictionary-encoded columns, zero rows,
  10^4 row groups;
* machine descriptions at every physical bound of ``docs/machine-format.md`` and just
  past it (read from ``sim/description.py``, so a new bound joins by itself).

:func:`build_files` is called by :func:`fuzzing.build_corpus`.
"""

from __future__ import annotations

import ast
import io
import json
import math
import re
import struct
import warnings
import zipfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

import fuzzing
from fuzzing import EXIT_INPUT, EXIT_LEAK, EXIT_OK, Case, _case_dir, _put

__all__ = ["SECRET", "SEED", "build_files"]

SEED = 97_000_000
"""Seed of this round's random damage (issue 39's third round: 97,000,000 and above)."""

SECRET = "hunter2-S3CRET"
"""A password put in hostile source URLs: no output may ever show it."""

ACCEPT = frozenset({EXIT_OK, EXIT_INPUT})
"""Exit codes of a hostile input that may be whole (0) or refused (2), never 3."""

# ---------------------------------------------------------------------- TDMS

TOC_METADATA, TOC_NEW_LIST, TOC_RAW, TOC_DAQMX = 1 << 1, 1 << 2, 1 << 3, 1 << 7
"""Table-of-contents bits of a TDMS segment lead-in (NI's file format description)."""
TDMS_DOUBLE, TDMS_UINT8, TDMS_STRING, TDMS_TIME = 10, 5, 0x20, 0x44
"""TDMS data type codes."""


def tdms_string(text: str | bytes) -> bytes:
    """A TDMS string: its length (uint32) and its UTF-8 bytes."""
    data = text.encode("utf-8") if isinstance(text, str) else text
    return struct.pack("<L", len(data)) + data


def tdms_property(name: str, code: int, raw: bytes) -> bytes:
    """One property: name, type code, value bytes."""
    return tdms_string(name) + struct.pack("<L", code) + raw


def tdms_double(name: str, value: float) -> bytes:
    return tdms_property(name, TDMS_DOUBLE, struct.pack("<d", value))


def tdms_text(name: str, value: str) -> bytes:
    return tdms_property(name, TDMS_STRING, tdms_string(value))


def tdms_index(code: int, count: int) -> bytes:
    """A channel's raw data index: 20 bytes, data type, dimension 1, number of values."""
    return struct.pack("<LLLQ", 20, code, 1, count)


NO_DATA = b"\xff\xff\xff\xff"
"""Raw data index header of an object without data."""


def tdms_object(
    path: str | bytes, index: bytes = NO_DATA, properties: Iterable[bytes] = ()
) -> bytes:
    props = list(properties)
    return tdms_string(path) + index + struct.pack("<L", len(props)) + b"".join(props)


def tdms_segment(toc: int, objects: list[bytes], data: bytes = b"") -> bytes:
    """A segment: lead-in (offsets computed), metadata (if ``toc`` says so), data."""
    meta = struct.pack("<L", len(objects)) + b"".join(objects) if toc & TOC_METADATA else b""
    lead = b"TDSm" + struct.pack("<llQQ", toc, 4713, len(meta) + len(data), len(meta))
    return lead + meta + data


def tdms_channel_path(group: str, name: str) -> str:
    return "/'{}'/'{}'".format(group.replace("'", "''"), name.replace("'", "''"))


def tdms_of(rec: Any, names: dict[str, str] | None = None) -> tuple[bytes, str]:
    """``rec`` as one TDMS segment (analog in group AI, digital in DI; SI units) and the
    tag map that reads it back (``names``: channel -> TDMS channel name)."""
    names = names or {}
    objects, data, lines = [tdms_object("/"), tdms_object("/'AI'"), tdms_object("/'DI'")], [], []
    for channel in rec.channels:
        info = rec.info(channel)
        digital = info.kind == "digital"
        group, name = ("DI" if digital else "AI"), names.get(channel, channel)
        values = np.ascontiguousarray(info.values, dtype=np.uint8 if digital else np.float64)
        props = [tdms_double("wf_increment", 1.0 / info.rate_hz),
                 tdms_double("wf_start_offset", info.t0)]  # fmt: skip
        if not digital:
            props.append(tdms_text("unit_string", info.unit))
        code = TDMS_UINT8 if digital else TDMS_DOUBLE
        objects.append(tdms_object(tdms_channel_path(group, name), tdms_index(code, values.size),
                                   props))  # fmt: skip
        data.append(values.tobytes())
        key = json.dumps(f"{group}/{name}")
        unit = "" if digital else f', unit = "{info.unit}"'
        lines.append(f'{key} = {{ role = "{channel}"{unit} }}')
    segment = tdms_segment(TOC_METADATA | TOC_NEW_LIST | TOC_RAW, objects, b"".join(data))
    return segment, "[columns]\n" + "\n".join(lines) + "\n"


def _extra_channel(index: bytes, props: Iterable[bytes] = (), data: bytes = b"") -> bytes:
    """A second segment holding only channel AI/extra (appended to a whole file)."""
    obj = tdms_object(tdms_channel_path("AI", "extra"), index, props)
    return tdms_segment(TOC_METADATA | TOC_NEW_LIST | TOC_RAW, [obj], data)


def _field_words(data: bytes) -> list[tuple[int, int]]:
    """Offsets and sizes of the metadata's integer fields (counts, lengths, codes)."""
    (meta_len,) = struct.unpack("<Q", data[20:28])
    return [(offset, 4) for offset in range(28, 28 + meta_len - 3, 4)]


def hostile_tdms(valid: bytes) -> Iterator[tuple[str, bytes, tuple[str, ...]]]:
    """TDMS files that declare sizes they do not hold, and damaged timing properties."""
    inc = tdms_double("wf_increment", 1e-3)
    big = 0xFFFF_FFF0
    yield "name_4gib", valid + tdms_segment(TOC_METADATA, [struct.pack("<L", big) + b"/'x'"]), (
        "bytes left",)  # fmt: skip
    yield (
        "properties_4e9",
        valid
        + tdms_segment(TOC_METADATA, [tdms_string("/'AI'") + NO_DATA + struct.pack("<L", big)]),
        ("tdms",),
    )
    yield "objects_4e9", valid + tdms_segment(TOC_METADATA, [])[:28] + struct.pack("<L", big), (
        "objects listed",)  # fmt: skip
    yield "samples_2e40", valid + _extra_channel(tdms_index(TDMS_DOUBLE, 1 << 40), [inc],
                                                 bytes(800)), ("tdms",)  # fmt: skip
    # a DAQmx raw data index: format-changing scaler, one Int16 scaler, 2^32 - 16 widths
    daqmx = (struct.pack("<LLLQL", 0x1269, 0xFFFF_FFFF, 1, 100, 1)
             + struct.pack("<5L", 3, 0, 0, 0, 0) + struct.pack("<L", big))  # fmt: skip
    daqmx_obj = tdms_string(tdms_channel_path("AI", "extra")) + daqmx + struct.pack("<L", 0)
    yield "daqmx_widths_4e9", valid + tdms_segment(
        TOC_METADATA | TOC_RAW | TOC_DAQMX, [daqmx_obj], bytes(800)), ("tdms",)  # fmt: skip
    yield "segments_100001", valid + tdms_segment(TOC_RAW, []) * 100_001, ("segments",)
    many = [tdms_object(f"/'g'/'c{i}'") for i in range(20_000)]
    yield "objects_x_segments", valid + tdms_segment(TOC_METADATA, many) + tdms_segment(
        TOC_METADATA, []) * 120, ("objects listed",)  # fmt: skip
    string_index = struct.pack("<LLLQQ", 28, TDMS_STRING, 1, 1 << 60, 8)
    yield "string_channel_2e60", valid + _extra_channel(string_index, [inc], bytes(8)), ("extra",)
    yield "time_channel", valid + _extra_channel(tdms_index(TDMS_TIME, 4), [inc], bytes(64)), (
        "extra",)  # fmt: skip
    p_in = tdms_channel_path("AI", "P_In")
    for label, props in (
        ("increment_text", [tdms_text("wf_increment", "fast")]),
        ("increment_nan", [tdms_double("wf_increment", math.nan)]),
        ("increment_zero", [tdms_double("wf_increment", 0.0)]),
        ("increment_1e-300", [tdms_double("wf_increment", 1e-300)]),
        ("increment_-1", [tdms_double("wf_increment", -1.0)]),
        ("offset_nan", [tdms_double("wf_start_offset", math.nan)]),
        ("offset_1e308", [tdms_double("wf_start_offset", 1e308)]),
        ("offset_text", [tdms_text("wf_start_offset", "soon")]),
        ("time_max", [tdms_property("wf_start_time", TDMS_TIME, struct.pack("<Qq", 0, 2**62))]),
        ("time_min", [tdms_property("wf_start_time", TDMS_TIME, struct.pack("<Qq", 0, -(2**62)))]),
        ("unit_markup", [tdms_text("unit_string", "[bold]bar[/")]),
    ):  # a later segment changes P_In's properties, as LabVIEW writes a property change
        change = tdms_segment(TOC_METADATA, [tdms_object(p_in, NO_DATA, props)])
        yield f"p_in_{label}", valid + change, ("P_In", "wf_", "unit")
    yield "big_endian_flag", valid[:4] + struct.pack("<l", struct.unpack("<l", valid[4:8])[0]
                                                     | (1 << 6)) + valid[8:], ("tdms",)  # fmt: skip
    for name, content in fuzzing.truncations(valid):
        yield f"cut_{name}", content, ("tdms",)
    rng = np.random.default_rng(SEED + 1)
    words = _field_words(valid)
    for k in range(24):
        buf = bytearray(valid)
        offset, size = words[int(rng.integers(len(words)))]
        value = int(rng.choice([0, 1, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF, 0x0010_0000, 20, 28]))
        buf[offset : offset + size] = struct.pack("<L", value)
        yield f"field_{k:02d}_at_{offset}_{value:x}", bytes(buf), ("tdms",)


TDMS_QUICK = frozenset({"name_4gib", "daqmx_widths_4e9"})
TDMS_EXTRA = frozenset({"samples_2e40", "string_channel_2e60", "time_channel"})
"""Cases whose channel AI/extra is read as P_In (the map points there)."""


def _tdms_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    from pneufdd import Recording

    folder = _case_dir(root, "files-tdms")
    rec = Recording.read(base["ref"])
    valid, tags = tdms_of(rec)
    mapping = _put(folder, "tdms.toml", tags.encode())
    extra = _put(folder, "extra.toml", tags.replace('"AI/P_In"', '"AI/extra"').encode())
    cases = [
        Case("import/tdms_whole", "import",
             ["import", _put(folder, "whole.tdms", valid), "--map", mapping, "--out", "w.parquet"],
             folder, ["whole.tdms", mapping], ["w.parquet"], frozenset({EXIT_OK}))
    ]  # fmt: skip
    for name, content, words in hostile_tdms(valid):
        if not full and name not in TDMS_QUICK:
            if len(cases) > len(TDMS_QUICK):
                break  # the rest is large to make
            continue
        data = _put(folder, f"{name}.tdms", content)
        whole = name.startswith(
            ("field_", "big_endian", "p_in_time", "p_in_unit", "p_in_offset_1e308")
        )
        expect = ACCEPT if whole else frozenset({EXIT_INPUT})
        tags_used = extra if name in TDMS_EXTRA else mapping
        cases.append(
            Case(f"import/tdms_{name}", "import",
                 ["import", data, "--map", tags_used, "--out", f"{name}.parquet"],
                 folder, [data, tags_used], [f"{name}.parquet"], expect, (data, *words))
        )  # fmt: skip
        if full and name in ("name_4gib", "objects_x_segments", "p_in_increment_1e-300"):
            cases.append(
                Case(f"steps/tdms_{name}", "steps", ["steps", data, "--map", tags_used],
                     folder, [data, tags_used], [], expect, (data, *words))
            )  # fmt: skip
    return cases


# ----------------------------------------------------------------------- CSV


def _exports(
    base: dict[str, Path], root: Path, layouts: Iterable[str] | None = None
) -> dict[str, tuple[Path, Path]]:
    """A small export in each ``--format`` layout (of ``layouts``: all), and the plain PLC
    one (cached)."""
    from pneufdd import Recording
    from pneufdd.recording.csv_layout import PRESETS
    from pneufdd.recording.field_export import write_field_export

    store = root / "_exports"
    store.mkdir(parents=True, exist_ok=True)
    found = {"plain": fuzzing._plc_export(root)}
    rec = None
    for preset in PRESETS if layouts is None else [p for p in PRESETS if p in layouts]:
        csv, tags = store / f"{preset}.csv", store / f"{preset}.toml"
        if not csv.exists():
            rec = rec or Recording.read(base["ref"]).select(["P_In", "Q_In", "U_PRESS_A",
                                                            "S_PRESS_B"])  # fmt: skip
            tags.write_text(write_field_export(rec, csv, preset))
        found[preset] = (csv, tags)
    return found


def _lines(data: bytes) -> tuple[list[bytes], bytes]:
    ending = b"\r\n" if b"\r\n" in data else b"\n"
    return data.split(ending), ending


def _header_index(lines: list[bytes], delimiter: bytes) -> int:
    """The header row: the last line before the first run of data rows (most fields)."""
    widths = [line.count(delimiter) for line in lines[: min(len(lines), 60)]]
    return max(range(len(widths)), key=lambda i: (widths[i], -i))


def hostile_csv(data: bytes, delimiter: bytes) -> Iterator[tuple[str, bytes, frozenset[int]]]:
    """Damaged copies of one export: encoding, line ends, sizes, time, numbers, preamble."""
    lines, ending = _lines(data)
    head = _header_index(lines, delimiter)
    first = head + 1
    while first < len(lines) and not lines[first][:1].isdigit():
        first += 1  # TwinCAT's per-channel rows and blank row between header and data
    body = lines[first:]
    back = [*lines[:first], body[1], body[0], *body[2:]]
    yield "time_backwards", ending.join(back), frozenset({EXIT_INPUT})
    two = {EXIT_INPUT}
    yield "bom", b"\xef\xbb\xbf" + data, ACCEPT
    yield "utf16", data.decode("utf-8").encode("utf-16"), frozenset(two)
    mixed = b"".join(line + (b"\n", b"\r", b"\r\n")[k % 3] for k, line in enumerate(lines))
    yield "mixed_line_ends", mixed, ACCEPT
    yield "cr_only", data.replace(b"\r\n", b"\r").replace(b"\n", b"\r"), ACCEPT
    long = [*lines[: first + 2], b"7" * (17 << 20), *lines[first + 2 :]]
    yield "line_17mb", ending.join(long), frozenset(two)
    repeat = [*lines[: first + 3], lines[first + 2], *lines[first + 3 :]]
    yield "time_repeats", ending.join(repeat), frozenset(two)
    wide = lines[head] + delimiter + delimiter.join(b"c%d" % i for i in range(1_000_000))
    yield "columns_1e6", ending.join([*lines[:head], wide, *lines[head + 1 :]]), frozenset(two)
    thousands = [re.sub(rb"(\d)(\d{3})([.,]\d)", rb"\1,\2\3", line) if k >= first else line
                 for k, line in enumerate(lines)]  # fmt: skip
    yield "thousands_separators", ending.join(thousands), ACCEPT
    preamble = [b"note" + delimiter + b"x%d" % i for i in range(150_000)]
    yield "endless_preamble", ending.join(preamble), frozenset(two)
    yield "preamble_then_header", ending.join(preamble[:1000] + lines), ACCEPT
    quote = [*lines[: first + 5], b'"' + lines[first + 5], *lines[first + 6 :]]
    yield "unclosed_quote", ending.join(quote), frozenset(two)
    yield "nul_bytes", data.replace(delimiter, b"\x00" + delimiter, 40), ACCEPT
    yield "latin1_byte", data.replace(delimiter, b"\xe9" + delimiter, 1), ACCEPT
    trailing = [line + delimiter if line else line for line in lines]
    yield "trailing_delimiter", ending.join(trailing), ACCEPT
    yield "header_only", ending.join(lines[: head + 1]) + ending, frozenset(two)
    for label, cell in (("inf", b"inf"), ("nan", b"nan"), ("1e308", b"1e308"),
                        ("minus_1e308", b"-1e308"), ("markup", b"[bold]1[/")):  # fmt: skip
        cut = lines[first + 4].split(delimiter)
        cut[-2] = cell  # a value column (the last may be a bit)
        edited = [*lines[: first + 4], delimiter.join(cut), *lines[first + 5 :]]
        yield f"cell_{label}", ending.join(edited), ACCEPT
    cut = lines[first + 4].split(delimiter)
    cut[0] = b"1e300"
    late = [*lines[: first + 4], delimiter.join(cut), *lines[first + 5 :]]
    yield "time_1e300", ending.join(late), frozenset(two)


CSV_QUICK = frozenset({"time_backwards"})


def _csv_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    from pneufdd.recording.csv_layout import PRESETS

    cases = []
    for layout, (csv, tags) in _exports(base, root, None if full else ["csv-de"]).items():
        if not full and layout != "csv-de":
            continue
        folder = _case_dir(root, f"files-csv-{layout}")
        mapping = _put(folder, "tags.toml", tags)
        delimiter = PRESETS[layout].delimiter.encode() if layout in PRESETS else b","
        fmt = [] if layout == "plain" else ["--format", layout]
        for name, content, expect in hostile_csv(csv.read_bytes(), delimiter):
            if not full and name not in CSV_QUICK:
                if len(cases) == len(CSV_QUICK):
                    break  # the rest is large to make
                continue
            data = _put(folder, f"{name}.csv", content)
            cases.append(
                Case(f"import/csv_{layout}_{name}", "import",
                     ["import", data, "--map", mapping, *fmt, "--out", f"{name}.parquet"],
                     folder, [data, mapping], [f"{name}.parquet"], expect, (data, mapping))
            )  # fmt: skip
    if full:  # a single 100 MB line after the header, once
        folder = _case_dir(root, "files-csv-plain")
        header = fuzzing._plc_export(root)[0].read_bytes().split(b"\n", 1)[0]
        data = _put(folder, "line_100mb.csv", header + b"\n" + b"0," * (50 << 20) + b"\n")
        cases.append(
            Case("import/csv_plain_line_100mb", "import",
                 ["import", data, "--map", "tags.toml", "--out", "l.parquet"], folder,
                 [data, "tags.toml"], ["l.parquet"], frozenset({EXIT_INPUT}), (data,))
        )  # fmt: skip
    return cases


# ------------------------------------------------------------------ tag maps

NAMES = (
    "../../victim",
    "/etc/passwd",
    "..\\..\\win",
    "a\x00b",
    "bell\x07\x1b[31mred",
    "[/]",
    "[bold]x[/bold",
    "$\\undefinedcmd$",
    "%s%n%x",
    "{0}{}{__class__}",
    "<script>alert(1)</script>",
    "\u202eevil\u202c",
    "x" * 10_000,
)
"""Names an attacker puts wherever a file names something (machine, actuator, channel,
tag, column, location): traversal, NUL and control characters, rich markup, mathtext,
format strings, HTML, a right-to-left override, 10,000 characters."""

_DOTS = ("..", "..", "...", ".", "%2e%2e", "%2e.", ".%2e", "\uff0e\uff0e", "..%c0%af", "..\u2215")
_SEPARATORS = ("/", "/", "\\", "//", "/./", "\\\\", "%2f", "%5c", "\u2215", "/\u200b")
_ROOTS = ("", "", "./", "/", "//", "~/", "C:\\", "C:/", "\\\\host\\share\\", "file:///", "/dev/")
_TAILS = ("victim", "etc/passwd", "x.toml", "run.parquet", ".", "", "con", "aux.txt", "nul",
          "a" * 300, "dir/", " ", "x\u202eevil")  # fmt: skip


def traversal_name(rng: np.random.Generator) -> str:
    """A random name that tries to leave the folder it is joined to.

    A random root (none, ``/``, ``//``, ``~/``, a drive, a UNC share, ``file:///``), one to
    eight steps up each spelt at random (``..``, ``...``, percent-encoded or full-width
    dots, an overlong UTF-8 slash) with a random separator (``/``, ``\\``, doubled,
    ``/./``, percent-encoded, a division slash, a zero-width space after ``/``), and a
    random tail (a file, a device name, nothing, 300 characters). Never a NUL: the names
    reach processes through argv.

    >>> rng = np.random.default_rng(1)
    >>> names = [traversal_name(rng) for _ in range(200)]
    >>> sum(".." in n for n in names) > 100, all("\\x00" not in n for n in names)
    (True, True)
    """
    steps = int(rng.integers(1, 9))
    path = str(rng.choice(_ROOTS))
    for _ in range(steps):
        path += str(rng.choice(_DOTS)) + str(rng.choice(_SEPARATORS))
    return path + str(rng.choice(_TAILS))


_MARKUP = ("[", "]", "[/]", "[bold]", "[/bold]", "[/bold", "[red on blue]", "[b", "[i]x[/b]",
           "[link=file:///etc/passwd]", "[@click=app.quit]", "[/link]", ":smile:", "\\[", "[]",
           "[[", "]]", "[#ff0000]", "[blink]")  # fmt: skip
_MATHTEXT = ("$", "$", "$$", "\\frac{", "\\undefinedcmd", "\\", "^", "_", "{", "}", "^^",
             "\\mathrm{", "\\$", "\\sqrt[", "\\left(", "\\hspace{1e9}", "\\\\", "%", "\\begin{x}",
             "$\\undefinedcmd$")  # fmt: skip
_PLAIN = ("cell", "A", "PRESS", " ", "x", "%s", "{0}", "<b>", "&amp;", "\x1b[31m", "\x07", "\t",
          "\u202e", "\ud7ff", "é")  # fmt: skip


def markup_name(rng: np.random.Generator) -> str:
    """A random name of rich console markup and matplotlib mathtext pieces.

    Two to twelve tokens drawn from rich tags (balanced or not, closing without opening,
    links, click actions, emoji codes, escaped brackets), mathtext (``$`` in odd numbers,
    unknown commands, open braces, ``\\frac{``, ``^^``, a 10^9 em space) and plain text
    with format strings, HTML entities, ANSI escapes and a right-to-left override: a name
    printed through rich or drawn by matplotlib must come out as the same text.

    >>> rng = np.random.default_rng(2)
    >>> names = [markup_name(rng) for _ in range(200)]
    >>> sum("[" in n for n in names) > 50, sum("$" in n for n in names) > 50
    (True, True)
    """
    pools = (_MARKUP, _MATHTEXT, _PLAIN)
    tokens = [
        str(rng.choice(pools[int(rng.integers(len(pools)))])) for _ in range(rng.integers(2, 13))
    ]
    return "".join(tokens)


def hostile_names(rng: np.random.Generator, count: int) -> list[str]:
    """``count`` random names, traversal and markup alternately (see :func:`traversal_name`
    and :func:`markup_name`), for the generators beside the fixed list :data:`NAMES`."""
    return [traversal_name(rng) if k % 2 == 0 else markup_name(rng) for k in range(count)]


def _toml_key(text: str) -> str:
    return json.dumps(text)  # a TOML basic string is a JSON string (\\uXXXX escapes)


def _tag_map_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    """The plain export with a column renamed to each hostile name, in file and map."""
    csv, tags = fuzzing._plc_export(root)
    data, text = csv.read_bytes(), tags.read_text("utf-8")
    column = data.split(b"\n", 1)[0].decode().split(",")[1]  # the first pressure tag
    cases = []
    for k, name in enumerate(NAMES if full else NAMES[5:6]):
        folder = _case_dir(root, f"files-map-name-{k}")
        cell = '"' + name.replace('"', '""') + '"' if ("," in name or '"' in name) else name
        new = data.replace(f",{column},".encode(), f",{cell},".encode(), 1)
        run = _put(folder, "plc.csv", new)
        mapping = _put(folder, "tags.toml", text.replace(_toml_key(column), _toml_key(name), 1)
                       .encode())  # fmt: skip
        for command, argv, outputs in (
            ("import", ["import", run, "--map", mapping, "--out", "o.parquet"], ["o.parquet"]),
            *([("steps", ["steps", run, "--map", mapping], [])] if full else []),
        ):
            cases.append(
                Case(f"{command}/map_name_{k}", command, argv, folder, [run, mapping], outputs,
                     ACCEPT, (run, mapping))
            )  # fmt: skip
    return cases


# ------------------------------------------------------------ monitor URLs


def hostile_sources(run: str) -> list[tuple[str, str, frozenset[int]]]:
    """``--source`` values: replay queries, MQTT and OPC UA URLs with odd parts."""
    two = frozenset({EXIT_INPUT})
    replay = [
        (f"replay:{run}?speed=abc", two),
        (f"replay:{run}?speed=", two),
        (f"replay:{run}?speed=-1", two),
        (f"replay:{run}?speed=1e309", ACCEPT),
        (f"replay:{run}?chunk=0", two),
        (f"replay:{run}?chunk=-1", two),
        (f"replay:{run}?chunk=1e308", two),
        (f"replay:{run}?speed=max&speed=1", two),
        (f"replay:{run}?speed=max&unknown=1", two),
        (f"replay:{run}?sped=max", two),
        (f"replay:{run}?speed=max&" + "x" * 10_000 + "=1", two),
        (f"replay:{run}?speed=max#frag", two),
        (f"replay:{run}??speed=max", two),
        ("replay:", two),
        ("replay:?speed=max", two),
        ("replay:/dev/zero?speed=max", two),
        ("replay:.?speed=max", two),
        ("replay:%2e%2e/%2e%2e/etc/passwd?speed=max", two),
        ("replay:../../../../../../etc/passwd?speed=max", two),
        (f"REPLAY:{run}?speed=max", two),
        (f"file://{run}", two),
    ]
    live = frozenset({EXIT_INPUT, fuzzing.EXIT_HANG})  # a live source is retried until stopped
    broker = [
        (f"mqtt://user:{SECRET}@127.0.0.1:1/plant/line", live),
        (f"mqtt://user:{SECRET}@127.0.0.1:99999/t", two),
        (f"mqtt://user:{SECRET}@[::1/t", two),
        (f"mqtt://:{SECRET}@/t", two),
        (f"mqtt://user:{SECRET}@host.invalid:1883/t", live),
        ("mqtt://127.0.0.1:-1/t", two),
        ("mqtt://127.0.0.1:abc/t", two),
        ("mqtt://127.0.0.1:1883", two),
        (f"mqtts://user:{SECRET}@127.0.0.1:1/t?ca=/etc/shadow", two),
        (f"opcua://user:{SECRET}@127.0.0.1:1/", live),
        (f"opc.tcp://user:{SECRET}@127.0.0.1:1/", two),
        (f"opcua://user:{SECRET}@127.0.0.1:0/", live),
        (f"opcua://user:{SECRET}@host.invalid:4840/?accept_revised=2", two),
        ("opcua://127.0.0.1:4840/?ns=99999999999999999999", two),
        (f"http://user:{SECRET}@127.0.0.1:1/", two),
    ]
    return replay + broker


def _monitor_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "files-monitor")
    ref = _put(folder, "ref.pnref", base["pnref"])
    run = _put(folder, "run.parquet", base["run"])
    csv, tags = fuzzing._plc_export(root)
    plc, mapping = _put(folder, "plc.csv", csv), _put(folder, "tags.toml", tags)
    cases = []
    sources = hostile_sources(run)
    if not full:  # quick: refused at once (a live case needs a process to stop)
        sources = [s for s in sources if SECRET in s[0] and fuzzing.EXIT_HANG not in s[1]][:1]
    for k, (url, expect) in enumerate(sources):
        extra = ["--tags", mapping] if url.startswith(("mqtt", "opc")) else []
        live = fuzzing.EXIT_HANG in expect
        cases.append(
            Case(f"monitor/source_{k:02d}", "monitor",
                 ["monitor", "--reference", ref, "--source", url, "--once", *extra],
                 folder, [ref, run, plc, mapping], [],
                 frozenset({*expect, EXIT_LEAK}) if EXIT_OK in expect else expect,
                 ("--source", "--tags", "replay:", url.partition("?")[0][len("replay:"):] or "--"),
                 (SECRET,), live)
        )  # fmt: skip
    return cases


# ------------------------------------------------------------------- .pnref


def _zip(
    members: list[tuple[str | zipfile.ZipInfo, bytes]], method: int = zipfile.ZIP_DEFLATED
) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", method) as archive:
        for name, content in members:
            archive.writestr(name, content)
    return buf.getvalue()


def _members(pnref: Path) -> list[tuple[str, bytes]]:
    with zipfile.ZipFile(pnref) as archive:
        return [(n, archive.read(n)) for n in archive.namelist()]


def _bomb_zip(members: list[tuple[str, bytes]], name: str, gigabytes: float) -> bytes:
    """``members`` and an ``.npy`` of zeros ``name`` that inflates to ``gigabytes`` (its
    sizes declared honestly, zip64; a few MB deflated)."""
    n = int(gigabytes * 1e9) // 800
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (n, 100)}
    )
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for other, content in members:
            if other != name:
                archive.writestr(other, content)
        info = zipfile.ZipInfo(name)
        info.compress_type = zipfile.ZIP_DEFLATED
        with archive.open(info, "w", force_zip64=True) as member:
            member.write(header.getvalue())
            block, left = bytes(1 << 24), n * 800
            while left > 0:
                member.write(block[: min(left, len(block))])
                left -= len(block)
    return buf.getvalue()


def _encrypted(data: bytes, name: str) -> bytes:
    """``data`` with the entry ``name`` flagged encrypted in both of its headers."""
    info = zipfile.ZipFile(io.BytesIO(data)).getinfo(name)
    buf = bytearray(data)
    buf[info.header_offset + 6] |= 0x1  # local header flags
    central = data.index(b"PK\x01\x02")
    while data[central + 46 : central + 46 + len(name)] != name.encode():
        central = data.index(b"PK\x01\x02", central + 4)
    buf[central + 8] |= 0x1  # central directory flags
    return bytes(buf)


def hostile_pnrefs(pnref: Path, full: bool) -> Iterator[tuple[str, bytes, tuple[str, ...]]]:
    members = _members(pnref)
    names = [n for n, _ in members]
    features = dict(members)["features.npy"]
    if full:
        yield "bomb_5gb_extra_member", _bomb_zip(members, "extra.npy", 5.0), ("memory", "bytes")
        yield "bomb_5gb_features", _bomb_zip(members, "features.npy", 5.0), (
            "memory", "bytes", "features")  # fmt: skip
        yield "members_100k", _zip(members + [(f"m{i}.npy", b"") for i in range(100_000)],
                                   zipfile.ZIP_STORED), ("member",)  # fmt: skip
    yield "member_traversal", _zip([*members, ("../../evil.npy", features)]), ("entry name",)
    yield "member_absolute", _zip([*members, ("/etc/evil.npy", features)]), ("entry name",)
    yield "member_not_npy", _zip([*members, ("readme.txt", b"hello")]), ("entry name",)
    with warnings.catch_warnings():  # zipfile warns of the duplicate it writes
        warnings.simplefilter("ignore")
        twice = _zip([*members, ("features.npy", features)])
    yield "member_duplicate_features", twice, ("entry name", "features")
    yield "member_encrypted", _encrypted(_zip(members), "features.npy"), ("features", "encrypt")
    yield "members_bzip2", _zip(members, zipfile.ZIP_BZIP2), ("ref",)
    yield "members_lzma", _zip(members, zipfile.ZIP_LZMA), ("ref",)
    yield "comment_and_prefix", b"MZ" + bytes(4096) + _zip(members), ("ref",)
    yield "only_names", _zip([(n, b"") for n in names]), ("ref",)


def _pnref_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "files-pnref")
    run = _put(folder, "run.parquet", base["run"])
    cases = []
    for name, content, words in hostile_pnrefs(base["pnref"], full):
        if not full and name != "member_traversal":
            continue
        ref = _put(folder, f"{name}.pnref", content)
        whole = name in ("members_bzip2", "members_lzma", "comment_and_prefix")
        expect = ACCEPT | {EXIT_LEAK} if whole else frozenset({EXIT_INPUT})
        cases.append(
            Case(f"diagnose/pnref_{name}", "diagnose",
                 ["diagnose", run, "--reference", ref, "--no-simulate"], folder, [run, ref], [],
                 frozenset(expect), (ref, *words))
        )  # fmt: skip
    return cases


# ------------------------------------------------------------------ Parquet


def hostile_parquets(path: Path, full: bool) -> Iterator[tuple[str, Callable[[Path], None]]]:
    """Writers of pneufdd-labelled Parquet files of odd schemas (metadata kept valid)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = table.schema.metadata

    def keep(new: pa.Table) -> pa.Table:
        return new.replace_schema_metadata(meta)

    def writer(new: pa.Table, **options: Any) -> Callable[[Path], None]:
        return lambda target: pq.write_table(keep(new), target, **options)

    yield "dictionary_encoded", writer(table, use_dictionary=True)
    dict_names = table.set_column(0, "name", pa.compute.dictionary_encode(table.column("name")))
    yield "dictionary_type_names", writer(dict_names)
    yield "zero_rows", writer(table.slice(0, 0))
    nested = table.set_column(
        table.schema.get_field_index("values_float64"), "values_float64",
        pa.array([[[v] for v in (row or [])] if row is not None else None
                  for row in table.column("values_float64").to_pylist()]),
    )  # fmt: skip
    yield "nested_lists", writer(nested)
    struct_names = table.set_column(
        0, "name", pa.array([{"a": n} for n in table.column("name").to_pylist()])
    )
    yield "struct_names", writer(struct_names)
    yield "large_lists", writer(table.cast(pa.schema([
        pa.field(f.name, pa.large_list(f.type.value_type)) if pa.types.is_list(f.type) else f
        for f in table.schema]).with_metadata(meta)))  # fmt: skip
    yield "float_names", writer(table.set_column(0, "name", pa.array([1.5] * table.num_rows)))
    rows = table.num_rows
    yield "row_groups_1_row", writer(table, row_group_size=1)
    if full:
        many = pa.concat_tables([table.slice(0, 1)] * 10_000)
        yield "row_groups_10000", writer(many, row_group_size=1)
    doubled = pa.concat_tables([table, table])
    yield "channels_twice", writer(doubled)
    del rows


def _parquet_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    folder = _case_dir(root, "files-parquet")
    ref = _put(folder, "ref.pnref", base["pnref"])
    cases = []
    for name, write in hostile_parquets(base["run"], full):
        if not full and name != "nested_lists":
            if cases:
                break  # the rest is not in the quick slice
            continue
        target = folder / f"{name}.parquet"
        if not target.exists():
            write(target)
        for command, argv in (
            ("diagnose", ["diagnose", target.name, "--reference", ref, "--no-simulate"]),
            ("steps", ["steps", target.name]),
        ):
            if command == "steps" and not full:
                continue
            ok = (
                {EXIT_OK, EXIT_LEAK}
                if name in ("dictionary_encoded", "row_groups_1_row")
                else set()
            )
            cases.append(
                Case(f"{command}/parquet_{name}", command, argv, folder, [target.name, ref], [],
                     frozenset({EXIT_INPUT, *ok}), (target.name,))
            )  # fmt: skip
    return cases


# -------------------------------------------------------- machine physical bounds


def physical_bounds() -> list[tuple[str, float, float, bool]]:
    """``(key, low, high, low_open)`` of every ``number(...)`` of ``sim/description.py``."""
    import pneufdd.sim.description as description

    source = Path(description.__file__).read_text("utf-8")
    constants = {k: v for k, v in vars(description).items() if isinstance(v, int | float)}
    found = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "number" and node.args
                and isinstance(node.args[0], ast.Constant)):  # fmt: skip
            continue
        options = {k.arg: k.value for k in node.keywords}

        def value(expr: ast.expr | None, default: float) -> float:
            if expr is None:
                return default
            if isinstance(expr, ast.Name):
                return float(constants.get(expr.id, default))
            try:
                return float(ast.literal_eval(expr))
            except ValueError:
                return default

        low_open = isinstance(options.get("low_open"), ast.Constant) and bool(
            options["low_open"].value)  # type: ignore[union-attr]  # fmt: skip
        found.append((str(node.args[0].value), value(options.get("low"), -math.inf),
                      value(options.get("high"), math.inf), low_open))  # fmt: skip
    return found


def _set_key(text: str, key: str, value: float) -> str | None:
    line = re.compile(rf"^{re.escape(key)} = [^\n\[]*$", re.M)
    if not line.search(text):
        return None
    return line.sub(f"{key} = {value!r}", text, count=1)


def _bound_cases(base: dict[str, Path], root: Path, full: bool) -> list[Case]:
    text = base["toml"].read_text("utf-8")
    folder = _case_dir(root, "files-machine-bounds")
    cases = []
    seen: set[str] = set()
    for key, low, high, low_open in physical_bounds():
        if key in seen:
            continue
        seen.add(key)
        inside = [
            v for v in (low if not low_open else None, high) if v is not None and math.isfinite(v)
        ]
        below = low - max(abs(low) * 1e-3, 1e-9) if math.isfinite(low) else None
        above = high + max(abs(high) * 1e-3, 1e-9) if math.isfinite(high) else None
        values = [(v, ACCEPT) for v in inside] + [
            (v, frozenset({EXIT_INPUT})) for v in (below, above) if v is not None
        ]
        for value, expect in values if full else values[:1]:
            edited = _set_key(text, key, value)
            if edited is None:
                continue
            name = f"{key}_{value:g}"
            toml = _put(folder, f"{name}.toml", edited.encode())
            cases.append(
                Case(f"simulate/bound_{name}", "simulate",
                     ["simulate", "--machine", toml, "--cycles", "1", "--out", f"{name}.parquet"],
                     folder, [toml], [f"{name}.parquet"], expect,
                     (toml, key) if expect == {EXIT_INPUT} else ())
            )  # fmt: skip
        if not full and len(cases) >= 2:
            break
    return cases


# --------------------------------------------------------------------- entry

BUILDERS: dict[str, tuple[tuple[str, ...], Callable[[dict[str, Path], Path, bool], list[Case]]]] = {
    "tdms": (("import", "steps"), _tdms_cases),
    "csv": (("import",), _csv_cases),
    "tag maps": (("import", "steps"), _tag_map_cases),
    "monitor sources": (("monitor",), _monitor_cases),
    "pnref zips": (("diagnose",), _pnref_cases),
    "parquet schemas": (("diagnose", "steps"), _parquet_cases),
    "machine bounds": (("simulate",), _bound_cases),
}
"""The kinds of hostile file, the commands they are fed to, and their case builders."""


def build_files(base: dict[str, Path], root: Path, full: bool, wanted: Iterable[str]) -> list[Case]:
    """Every hostile-file case (``full``) or a quick few, for the commands in ``wanted``."""
    chosen = set(wanted)
    cases: list[Case] = []
    for commands, build in BUILDERS.values():
        if chosen & set(commands):
            cases += [c for c in build(base, root, full) if c.command in chosen]
    return cases
