"""Resource limits: every count, size and rate a user can give, checked before work.

One place for the bounds of issue 39 ("no small input takes the machine down"): a
count, size or rate read from an option, a TOML file, a tag map, a ``.pnref`` header
or Parquet metadata is compared with its limit here, and with the memory it implies,
*before* anything is allocated. A value past a limit is bad input
(:class:`~pneufdd.errors.InputError`, exit 2) whose message names the option, file or
field, the limit and, for memory, the estimate. The limits are documented in
``docs/limits.md``; change them there and here together.

Examples
--------
>>> check_count("--uncertainty-plants", 12, MAX_UNCERTAINTY_PLANTS)
12
>>> check_count("--uncertainty-plants", 10**9, MAX_UNCERTAINTY_PLANTS)  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
pneufdd.errors.InputError: --uncertainty-plants: received 1000000000; allowed: ... to 1,000 ...
"""

from __future__ import annotations

import math
import os
import stat
from pathlib import Path

from pneufdd.errors import FileFormatError, InputError, MissingFileError, describe

__all__ = [
    "MAX_ACTUATORS",
    "MAX_ARL0",
    "MAX_CAMPAIGN_COUNT",
    "MAX_CHANNELS",
    "MAX_CSV_BYTES",
    "MAX_CSV_COLUMNS",
    "MAX_CSV_LINE_BYTES",
    "MAX_CYCLES",
    "MAX_HOURS_PER_YEAR",
    "MAX_JSON_DEPTH",
    "MAX_LEAKS",
    "MAX_MESSAGE_CHARS",
    "MAX_PAYLOAD_BYTES",
    "MAX_RATE_HZ",
    "MAX_REFERENCE_CYCLES",
    "MAX_REPLAY_CHUNK_S",
    "MAX_REPLAY_SPEED",
    "MAX_RUN_CYCLES",
    "MAX_SIGNATURE_CYCLES",
    "MAX_STEPS",
    "MAX_TDMS_LISTED_OBJECTS",
    "MAX_TDMS_OBJECTS",
    "MAX_TDMS_SEGMENTS",
    "MAX_TEXT_FILE_BYTES",
    "MAX_UNCERTAINTY_PLANTS",
    "MAX_WORKERS",
    "MEMORY_BUDGET_BYTES",
    "MIN_REPLAY_CHUNK_S",
    "MIN_REPLAY_SPEED",
    "check_count",
    "check_json_depth",
    "check_memory",
    "clip_message",
    "read_text_capped",
]

MEMORY_BUDGET_BYTES = 3 << 29
"""Largest working memory one command may plan for [bytes] (1.5 GiB: with the ~0.3 GB
that Python, NumPy and numba take, a command stays under 2 GB)."""

MAX_CYCLES = 100_000
"""Most cycles one simulated run may ask for; the memory they imply is checked too
(:data:`MEMORY_BUDGET_BYTES`: about 2,000 press-fit-cell cycles)."""

MAX_RUN_CYCLES = 10_000
"""Most cycles judged per run of a campaign (``campaign --run-cycles``)."""

MAX_SIGNATURE_CYCLES = 100
"""Most simulated cycles per leak-signature point (``--signature-cycles``; default 2)."""

MAX_UNCERTAINTY_PLANTS = 1_000
"""Most plausible plants drawn to measure model uncertainty (``--uncertainty-plants``)."""

MAX_CAMPAIGN_COUNT = 10_000
"""Most plants, repetitions, leak-free runs or leak pairs of a campaign (each)."""

MAX_REFERENCE_CYCLES = 1_000_000
"""Most reference cycles a ``.pnref`` file may declare (``n_cycles``)."""

MAX_WORKERS = 1_024
"""Most processes or threads one command may start (``--workers``, ``--threads``)."""

MAX_CHANNELS = 10_000
"""Most channels a recording file may hold (a machine of 64 actuators has about 400)."""

MAX_ACTUATORS = 64
"""Most actuators a machine description may have (the largest built-in has 9)."""

MAX_STEPS = 1_000
"""Most steps a machine description's sequence may have."""

MAX_CSV_BYTES = 1 << 30
"""Largest CSV export read [bytes] (1 GiB; the memory its rows imply is checked too)."""

MAX_CSV_LINE_BYTES = 16 << 20
"""Longest line of a CSV export [bytes] (16 MiB: a million columns; real rows are a few
kB, a 100,000-column export's about 200 kB)."""

MAX_CSV_COLUMNS = 200_000
"""Most columns a CSV export's header may have (twice the widest export measured, 100,000
ignored columns, about 4 s to import)."""

MAX_TDMS_SEGMENTS = 100_000
"""Most segments a TDMS file may have. LabVIEW writes one per write call; npTDMS spends
about 60 us and 230 bytes on each, and NI's TDMS tools defragment a file into one."""

MAX_TDMS_OBJECTS = 20_000
"""Most objects (channels, their groups, the root) one TDMS segment may list."""

MAX_TDMS_LISTED_OBJECTS = 2_000_000
"""Most objects listed over all segments of a TDMS file (each segment's list, summed):
npTDMS visits every one, about 8 us each (a 0.5 MB file of 20,000 objects repeated in
2,000 segments took 328 s and 334 MB)."""

MAX_LEAKS = 32
"""Most simultaneous leaks one diagnosis explains a run with (``--max-leaks``;
``LocalisationSettings.max_leaks``): every location of a machine of up to 15
actuators (the largest built-in has 19 locations). The forward search costs a few set
fits per leak found and the check by simulation ``k + 4`` simulations per explanation
of ``k`` leaks, so the limit bounds a diagnosis's time, not its memory."""

MAX_RATE_HZ = 10e6
"""Fastest plausible sample rate of any channel [Hz]; ``import`` refuses faster too."""

MIN_REPLAY_CHUNK_S = 1e-3
"""Shortest block a replayed source delivers (``replay:...?chunk=``) [s]."""

MAX_REPLAY_CHUNK_S = 3600.0
"""Longest block a replayed source delivers [s]."""

MIN_REPLAY_SPEED = 0.1
"""Slowest replay (``replay:...?speed=``): a tenth of real time [-]."""

MAX_REPLAY_SPEED = 1e6
"""Fastest replay given as a number (``speed=max`` reads as fast as it can) [-]."""

MAX_ARL0 = 1e9
"""Largest in-control average run length of the monitor's alarm (``--arl0``) [cycles]."""

MAX_HOURS_PER_YEAR = 8784.0
"""Most operating hours in a year (a leap year, around the clock) [h]."""

MAX_TEXT_FILE_BYTES = 4 << 20
"""Largest tag map or settings file read [bytes] (4 MiB, as machine files; real ones
are a few kB, one ignoring 100,000 columns about 1.1 MB)."""

MAX_PAYLOAD_BYTES = 64 << 20
"""Largest MQTT payload a live monitor parses [bytes] (64 MiB: minutes of every channel)."""

MAX_JSON_DEPTH = 64
"""Deepest nesting of objects and arrays in JSON read from a file (Parquet metadata,
``.pnref`` headers, tag maps); pneufdd writes at most 8."""

MAX_MESSAGE_CHARS = 2_000
"""Longest error message printed; a longer one is cut in the middle."""


def check_count(what: str, value: int, limit: int, low: int = 0) -> int:
    """Return ``value`` if ``low <= value <= limit``, else raise :class:`InputError`.

    Parameters
    ----------
    what : str
        The option, file field or setting, named in the message.
    value : int
        The count received.
    limit : int
        The largest count allowed (one of this module's constants).
    low : int
        The smallest count allowed.
    """
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= limit:
        raise InputError(
            describe(what, value, f"an integer from {low:,} to {limit:,} (docs/limits.md)")
        )
    return value


def check_memory(
    what: str,
    estimate_bytes: float,
    budget: int = MEMORY_BUDGET_BYTES,
    error: type[InputError] = InputError,
) -> None:
    """Refuse work whose estimated memory exceeds ``budget``, before allocating it.

    >>> check_memory("--cycles 10", 1e6)
    >>> check_memory("--cycles 100000", 3.4e10)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pneufdd.errors.InputError: --cycles 100000: needs about 34.0 GB ...; allowed: at most 1.6 GB ...
    """
    if not math.isfinite(estimate_bytes) or estimate_bytes > budget:
        shown = f"{estimate_bytes / 1e9:.1f} GB" if math.isfinite(estimate_bytes) else "unbounded"
        raise error(
            f"{what}: needs about {shown} of memory; allowed: at most "
            f"{budget / 1e9:.1f} GB (docs/limits.md)"
        )


def check_json_depth(text: str | bytes, what: str, limit: int = MAX_JSON_DEPTH) -> None:
    """Refuse JSON nested deeper than ``limit`` before :func:`json.loads` recurses into it.

    Counts brackets outside strings in one pass (no recursion).

    >>> check_json_depth('{"a": [1, {"b": "[[["}]}', "x")
    >>> check_json_depth("[" * 100 + "]" * 100, "x")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pneufdd.errors.FileFormatError: x: nesting of JSON ...: received '> 64 levels'; allowed: ...
    """
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text
    if data.count(b"[") + data.count(b"{") <= limit:
        return
    depth = 0
    in_string = escaped = False
    for byte in data:
        if in_string:
            if escaped:
                escaped = False
            elif byte == 0x5C:  # backslash
                escaped = True
            elif byte == 0x22:  # quote
                in_string = False
        elif byte == 0x22:
            in_string = True
        elif byte in (0x5B, 0x7B):
            depth += 1
            if depth > limit:
                raise FileFormatError(
                    describe(
                        f"{what}: nesting of JSON objects and arrays",
                        f"> {limit} levels",
                        f"at most {limit} levels (docs/limits.md)",
                    )
                )
        elif byte in (0x5D, 0x7D):
            depth -= 1


def read_text_capped(path: Path, what: str, limit: int = MAX_TEXT_FILE_BYTES) -> str:
    """The UTF-8 text of a small input file: a regular file of at most ``limit`` bytes.

    Devices, pipes and folders (``/dev/zero``, ``/dev/stdin``) are refused without
    reading; so is a file larger than ``limit``, from its size on disk, and one that
    grows past it while read.

    Raises
    ------
    MissingFileError
        If ``path`` does not exist.
    FileFormatError
        If it is not a regular file, is too large, or is not UTF-8.
    """
    label = f"{what} {str(path)!r}"
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise MissingFileError(f"{label} does not exist") from None
    except OSError as exc:
        raise FileFormatError(f"{label}: cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(info.st_mode):
        raise FileFormatError(
            describe(f"{label}: kind of file", "not a regular file", "a regular file")
        )
    if info.st_size > limit:
        raise FileFormatError(
            describe(f"{label}: size [bytes]", info.st_size, f"<= {limit:,} (docs/limits.md)")
        )
    with open(path, "rb") as handle:
        data = handle.read(limit + 1)
    if len(data) > limit:
        raise FileFormatError(
            describe(f"{label}: size [bytes]", f"> {limit:,}", f"<= {limit:,} (docs/limits.md)")
        )
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileFormatError(
            f"{label} is not UTF-8 text (byte {exc.start}); save it as UTF-8"
        ) from None


def clip_message(text: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` cut to at most ``limit`` characters, keeping its start and end.

    >>> clip_message("a" * 10, 6)
    'aa [...] aa'
    >>> len(clip_message("x" * 10**6)) < 2100
    True
    """
    if len(text) <= limit:
        return text
    half = max(limit // 2 - 1, 1)
    return f"{text[:half]} [...] {text[-half:]}"
