"""Seeded generators of hostile values for every command of ``pneufdd --help`` (issue 39).

Table-driven: :data:`COMMANDS` holds one :class:`Entry` per command, a working
invocation built from the base inputs and the exit codes it gives. The generators vary
that invocation one thing at a time, with values a seeded random generator draws
(:data:`SEED`), so a rerun is the same corpus:

* sizes: every numeric option, found on the command itself (a new option is fuzzed
  without an edit), gets NaN, +-inf, -1, 0, 1e308, 1e-300, 2^31, a 30-digit integer,
  and the ends of its range and just past them;
* texts: every text option gets a name from :data:`fuzzing_files.NAMES` (traversal,
  NUL and control characters, markup, mathtext, format strings, HTML, a right-to-left
  override, 10,000 characters) or a malformed number list;
* nesting: every TOML input nested 13, 65, 1,000 or 100,000 levels deep, every
  recording's and reference's JSON metadata nested likewise;
* links: every input replaced by a symbolic link, a dangling link, a link loop, a
  named pipe or a folder; every output behind a dangling link (whose target must not
  appear), on a symbolic or hard link to an input, in a missing folder, under a file,
  on a link loop;
* names: the machine's name, a recording's channel name, a leak location;
* a stray argument.

An accepted value may give the command's own exit codes or 2; a value that can never
be right (NaN, an input that is a pipe) must give 2; none may give 3, hang, grow past
2 GiB, change an input or write outside the outputs. A command with ``expensive`` (a
campaign, the demo, compiling the twin: minutes when accepted) gets only the values
that must be refused. ``test_every_command_has_a_generator_entry`` fails for a command
without an entry: a new command adds one line to :data:`COMMANDS`.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import fuzzing
import fuzzing_bounds
from fuzzing import EXIT_INPUT, EXIT_LEAK, EXIT_OK, MACHINE, Case, _case_dir
from fuzzing_files import NAMES, hostile_names

__all__ = ["COMMANDS", "SEED", "Entry", "build_generated"]

SEED = 97_000_100
"""Seed of the generators (issue 39's third round: 97,000,000 and above)."""

PER_COMMAND = 24
"""Variants drawn per command in the full corpus (all of them when fewer)."""

TWO = frozenset({EXIT_INPUT})

# ------------------------------------------------------------------ the kit


@dataclass
class Kit:
    """Places a command's inputs in its folder under unique names and records them.

    ``inputs``: name -> kind (``recording``, ``reference``, ``machine``, ``map``,
    ``csv``, ``campaign``, ``history``); ``outputs``: option -> name.
    """

    base: dict[str, Path]
    root: Path
    folder: Path
    inputs: dict[str, str] = field(default_factory=dict)
    outputs: dict[str, str] = field(default_factory=dict)
    optional: set[str] = field(default_factory=set)
    _count: int = 0

    def _name(self, stem: str, suffix: str) -> str:
        self._count += 1
        return f"{stem}{self._count}{suffix}"

    def put(self, source: Path | bytes, kind: str, suffix: str) -> str:
        name = self._name(kind[:3], suffix)
        target = self.folder / name
        if isinstance(source, bytes):
            target.write_bytes(source)
        elif source.is_dir():
            shutil.copytree(source, target)
        else:
            shutil.copy(source, target)
        self.inputs[name] = kind
        return name

    def run(self) -> str:
        return self.put(self.base["run"], "recording", ".parquet")

    def ref_run(self) -> str:
        return self.put(self.base["ref"], "recording", ".parquet")

    def pnref(self) -> str:
        return self.put(self.base["pnref"], "reference", ".pnref")

    def machine(self) -> str:
        return self.put(self.base["toml"], "machine", ".toml")

    def plc(self) -> tuple[str, str]:
        csv, tags = fuzzing._plc_export(self.root)
        return self.put(csv, "csv", ".csv"), self.put(tags, "map", ".toml")

    def campaign(self) -> str:
        return self.put(_campaign(self.root), "campaign", "")

    def history(self) -> str:
        return self.put(_history(self.base, self.root), "history", ".db")

    def out(self, option: str, suffix: str, optional: bool = False) -> str:
        """A new output's name; ``optional``: a success may leave it unwritten."""
        name = self._name("out", suffix)
        self.outputs[option] = name
        if optional:
            self.optional.add(name)
        return name


def _quietly(argv: list[str], cwd: Path) -> int:
    from pneufdd.cli.app import main

    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            return main(argv)
    finally:
        os.chdir(here)


def _campaign(root: Path) -> Path:
    """The smallest campaign (35 s, cached): one plant, one leak-free run, no pairs."""
    store = root / "_campaign"
    if not (store / "camp" / "manifest.json").exists():
        store.mkdir(parents=True, exist_ok=True)
        code = _quietly(["campaign", *CAMPAIGN_ARGS, "--out", "camp"], store)
        if code != 0:
            raise RuntimeError(f"the base campaign failed with exit {code}")
    return store / "camp"


def _standstill(root: Path) -> tuple[Path, Path]:
    """A standstill plan of the base machine and a recording of its test on the twin with
    a leak (cached): the working inputs of ``standstill analyse``."""
    store = root / "_standstill"
    plan_json, run = store / "plan" / "plan.json", store / "test.parquet"
    if not run.exists():
        from pneufdd.sim import load_machine
        from pneufdd.standstill.plan import plan_standstill
        from pneufdd.standstill.twin import simulate_standstill

        store.mkdir(parents=True, exist_ok=True)
        code = _quietly(["standstill", "plan", "--machine", MACHINE, "--out", "plan"], store)
        if code != 0:
            raise RuntimeError(f"the base standstill plan failed with exit {code}")
        machine = load_machine(MACHINE)
        (rec,) = simulate_standstill(machine, plan_standstill(machine), {"EJECT_B": "60slpm"})
        rec.write(run)
    return plan_json, run


def _standstill_analyse(kit: Kit) -> list[str]:
    plan_json, run = _standstill(kit.root)
    return ["standstill", "analyse", kit.put(run, "recording", ".parquet"),
            "--plan", kit.put(plan_json, "plan", ".json"),
            "--json", kit.out("--json", ".json")]  # fmt: skip


def _commission(root: Path) -> tuple[Path, Path, Path]:
    """A reference with signatures of the base machine, its commissioning plan (EJECT_B)
    and a run with the 1.0 mm test orifice there (cached): the working inputs of
    ``commission plan`` and ``commission apply``."""
    store = root / "_commission"
    ref, plan_json, run = store / "ref.pnref", store / "plan" / "plan.json", store / "run.parquet"
    if not run.exists():
        from pneufdd.sim import load_machine, simulate

        store.mkdir(parents=True, exist_ok=True)
        machine = load_machine(MACHINE)
        simulate(machine, cycles=11, seed=fuzzing.SEED + 30).write(store / "free.parquet")
        code = _quietly(
            ["reference", "build", "free.parquet", "--out", "ref.pnref", "--signature-cycles",
             "1", "--signature-sizes", "10,40,120", "--uncertainty-plants", "0"], store,
        )  # fmt: skip
        code = code or _quietly(
            ["commission", "plan", "--reference", "ref.pnref", "--ports", "EJECT_B",
             "--cycles", "4", "--out", "plan"], store,
        )  # fmt: skip
        if code != 0:
            raise RuntimeError(f"the base commissioning plan failed with exit {code}")
        simulate(machine, cycles=6, leaks={"EJECT_B": "1.0mm"}, seed=fuzzing.SEED + 31).write(run)
    return ref, plan_json, run


def _commission_apply(kit: Kit) -> list[str]:
    ref, plan_json, run = _commission(kit.root)
    return ["commission", "apply", "--reference", kit.put(ref, "reference", ".pnref"),
            "--plan", kit.put(plan_json, "plan", ".json"),
            "--run", "EJECT_B=./" + kit.put(run, "recording", ".parquet"),
            "--out", kit.out("--out", ".pnref"), "--json", kit.out("--json", ".json")]  # fmt: skip


def _history(base: dict[str, Path], root: Path) -> Path:
    """A history database with the base run's cycles in it (cached)."""
    store = root / "_history"
    if not (store / "h.db").exists():
        store.mkdir(parents=True, exist_ok=True)
        shutil.copy(base["run"], store / "run.parquet")
        code = _quietly(
            ["monitor", "--reference", str(base["pnref"]), "--source",
             "replay:run.parquet?speed=max", "--once", "--history", "sqlite:///h.db"], store,
        )  # fmt: skip
        if code not in (EXIT_OK, EXIT_LEAK):
            raise RuntimeError(f"the base history failed with exit {code}")
    return store / "h.db"


CAMPAIGN_ARGS = [
    "--machine", MACHINE, "--plants", "1", "--reps", "1", "--sizes", "1", "--leak-free-runs", "1",
    "--pairs", "0", "--run-cycles", "2", "--reference-cycles", "10", "--reference-recordings", "1",
    "--uncertainty-plants", "0", "--workers", "1",
]  # fmt: skip
"""A campaign of one plant and one leak-free run (35 s)."""

# ------------------------------------------------------------------ the table


@dataclass(frozen=True)
class Entry:
    """How to fuzz one command: its working invocation and what may vary in it.

    ``argv(kit)`` builds the invocation, placing its inputs and naming its outputs
    through the kit; ``ok`` its exit codes; ``expensive``: accepted values may run for
    minutes, so only those that must be refused are drawn; ``fixed``: options left as
    they are (with the reason in a comment at the entry).
    """

    argv: Callable[[Kit], list[str]]
    ok: frozenset[int] = frozenset({EXIT_OK})
    expensive: bool = False
    fixed: tuple[str, ...] = ()
    quick: bool = True
    """In ``make test``'s quick slice (its inputs take seconds to make, not a campaign)."""


def _monitor(kit: Kit) -> list[str]:
    run = kit.run()
    return ["monitor", "--reference", kit.pnref(), "--source", f"replay:{run}?speed=max",
            "--once", "--history", f"sqlite:///{kit.out('--history', '.db')}",
            "--alarm-log", kit.out("--alarm-log", ".jsonl", optional=True)]  # fmt: skip


def _import(kit: Kit) -> list[str]:
    csv, tags = kit.plc()
    return ["import", csv, "--map", tags, "--out", kit.out("--out", ".parquet")]


# fmt: off
COMMANDS: dict[str, Entry] = {
    "build-twin": Entry(lambda k: ["build-twin", "--dir", k.out("--dir", "")], expensive=True),
    "campaign": Entry(
        lambda k: ["campaign", *CAMPAIGN_ARGS, "--out", k.out("--out", "")],
        expensive=True,
        fixed=("--scheduler",),
    ),
    # commission: in the full corpus only; the quick slice runs the commands of
    # fuzzing.BUILDERS (test_quick_slice_of_the_fuzz_corpus)
    "commission apply": Entry(
        _commission_apply, ok=frozenset({EXIT_OK, EXIT_LEAK}), quick=False
    ),
    "commission plan": Entry(
        lambda k: ["commission", "plan", "--reference",
                   k.put(_commission(k.root)[0], "reference", ".pnref"),
                   "--out", k.out("--out", "")],
        quick=False,
    ),
    "demo": Entry(
        lambda k: ["demo", "--reference-cycles", "10", "--out", k.out("--out", "")], expensive=True
    ),
    "diagnose": Entry(
        lambda k: [
            "diagnose",
            k.run(),
            "--reference",
            k.pnref(),
            "--no-simulate",
            "--json",
            k.out("--json", ".json"),
            "--report",
            k.out("--report", ".html"),
        ],
        ok=frozenset({EXIT_OK, EXIT_LEAK}),
        fixed=("--scheduler",),
    ),  # --scheduler: a Dask address
    "evaluate": Entry(
        lambda k: ["evaluate", k.campaign(), "--workers", "1", "--out", k.out("--out", "")],
        quick=False,
    ),
    "features": Entry(
        lambda k: ["features", k.run(), "--group", "air", "--actuator", "PRESS",
                   "--out", k.out("--out", ".csv")]
    ),
    "energy": Entry(
        lambda k: ["energy", k.run(), "--reference", k.pnref(), "--twin-cycles", "2",
                   "--json", k.out("--json", ".json")],
        ok=frozenset({EXIT_OK, EXIT_LEAK}),
        quick=False,  # seconds per run: the twin runs each what-if
    ),
    "faults": Entry(lambda k: ["faults"]),  # no options: only a stray argument varies
    "history": Entry(
        lambda k: [
            "history",
            "--history",
            f"sqlite:///{k.history()}",
            "--figure",
            k.out("--figure", ".png"),
        ],
        quick=False,
    ),
    "import": Entry(_import),
    "machine calibrate": Entry(
        lambda k: [
            "machine",
            "calibrate",
            k.machine(),
            k.ref_run(),
            "--max-evaluations",
            "2",
            "--out",
            k.out("--out", ".toml"),
        ],
        ok=frozenset({EXIT_OK}),
    ),
    "machine draft": Entry(
        lambda k: ["machine", "draft", k.ref_run(), "--out", k.out("--out", ".toml")]
    ),
    "machine vary": Entry(
        lambda k: ["machine", "vary", k.machine(), "--seed", "3", "--out", k.out("--out", ".toml")]
    ),
    "machines": Entry(lambda k: ["machines"]),
    "monitor": Entry(_monitor, ok=frozenset({EXIT_OK, EXIT_LEAK})),
    "reference build": Entry(
        lambda k: [
            "reference",
            "build",
            k.ref_run(),
            "--no-signatures",
            "--out",
            k.out("--out", ".pnref"),
        ]
    ),
    # serve runs until stopped when it accepts: only values that must be refused; the
    # port stays fixed (any port in range is accepted and would serve for good).
    "serve": Entry(
        lambda k: ["serve", "--history", f"sqlite:///{k.history()}", "--port", "8765"],
        expensive=True,
        fixed=("--port",),
        quick=False,
    ),
    "simulate": Entry(
        lambda k: [
            "simulate",
            "--machine",
            k.machine(),
            "--cycles",
            "2",
            "--out",
            k.out("--out", ".parquet"),
        ]
    ),
    "standstill analyse": Entry(_standstill_analyse, ok=frozenset({EXIT_OK, EXIT_LEAK})),
    "standstill plan": Entry(
        lambda k: ["standstill", "plan", "--machine", k.machine(), "--out", k.out("--out", "")]
    ),
    "steps": Entry(lambda k: ["steps", k.run()]),
    # users add reads its password from standard input, which the corpus closes: the
    # working invocation is refused (a password of 0 characters) and no variant may
    # write the users file or exit 3.
    "users add": Entry(
        lambda k: ["users", "add", "--file", k.out("--file", ".toml"), "--name", "ann",
                   "--role", "viewer", "--password-stdin"],
        ok=TWO,
        quick=False,
    ),
    "vector-map": Entry(  # festo-dsd's DNC (the default): its air is measured
        lambda k: ["vector-map", "--cycles", "2", "--sizes", "2", "--out", k.out("--out", "")]
    ),
}
# fmt: on
"""One entry per command of ``pneufdd --help`` (a new command adds one)."""

# ------------------------------------------------------------- introspection


def _click(command: str) -> Any:
    import typer.main

    from pneufdd.cli.app import app

    cmd = typer.main.get_command(app)
    for part in command.split():
        cmd = cmd.commands[part]  # type: ignore[attr-defined]
    return cmd


def _options(command: str) -> Iterator[tuple[str, str, Any]]:
    """``(option, kind, click type)`` of each option: kind ``int``, ``float``, ``text``
    (by the type's class names: typer carries its own copy of click)."""
    for param in _click(command).params:
        if param.param_type_name != "option" or param.is_flag:
            continue
        names = {cls.__name__ for cls in type(param.type).__mro__}
        if "IntParamType" in names:
            yield param.opts[0], "int", param.type
        elif "FloatParamType" in names:
            yield param.opts[0], "float", param.type
        elif "StringParamType" in names:
            yield param.opts[0], "text", param.type


# --------------------------------------------------------------- generators

Variant = tuple[str, list[str], frozenset[int], tuple[str, ...], tuple[str, ...]]
"""``(label, argv, allowed exit codes, words an exit 2 names, files that must not appear)``."""

FLOATS_REFUSED = ("nan", "-nan", "NaN")
FLOATS_MAYBE = ("inf", "-inf", "-1", "0", "1e308", "-1e308", "1e-300", "2147483648")
INTS_REFUSED = ("nan", "1.5", "1e3", "0x10", "")
INTS_MAYBE = ("-1", "0", "2147483648", "9" * 30, "-" + "9" * 30)
TEXTS = ("nan", "1e308", "-1", "1,2,nan", "1,,2", "=", " ", "", "a=b=c", "1e-300,1e308")


def _said(option: str, value: str = "") -> tuple[str, ...]:
    """What an exit 2 about ``option`` may name: the option in any spelling, or the value."""
    bare = option.lstrip("-")
    words = (option, bare, bare.replace("-", "_"))
    return (*words, value) if len(value.strip()) > 1 else words


def _numbers(command: str, argv: list[str], ok: frozenset[int], expensive: bool,
             fixed: tuple[str, ...]) -> Iterator[Variant]:  # fmt: skip
    for option, kind, ctype in _options(command):
        if option in fixed:
            continue
        refused = FLOATS_REFUSED if kind == "float" else INTS_REFUSED if kind == "int" else ()
        maybe = FLOATS_MAYBE if kind == "float" else INTS_MAYBE if kind == "int" else ()
        low, high = getattr(ctype, "min", None), getattr(ctype, "max", None)
        edges = [str(v) for v in (low, high) if v is not None]
        past = [str(low - 1)] if isinstance(low, int) else []
        past += [str(high + 1)] if isinstance(high, int) else []
        for value in (*refused, *past):
            yield f"{option}={value!r}", [*argv, option, value], TWO, _said(option, value), ()
        if not expensive:  # accepted, or refused by whatever it breaks: no word required
            for value in (*maybe, *edges):
                yield f"{option}={value!r}", [*argv, option, value], ok | TWO, (), ()


RANDOM_NAMES = 8
"""Random traversal and markup names (:func:`fuzzing_files.hostile_names`) drawn per
text option, per input's name and per leak location, beside the fixed :data:`NAMES`."""


def _texts(command: str, argv: list[str], ok: frozenset[int], expensive: bool,
           fixed: tuple[str, ...], rng: np.random.Generator) -> Iterator[Variant]:  # fmt: skip
    if expensive:
        return
    for option, kind, _ in _options(command):
        if kind != "text" or option in fixed:
            continue
        for k, value in enumerate((*NAMES, *TEXTS, *hostile_names(rng, RANDOM_NAMES))):
            if "\x00" in value:
                continue  # no process argument holds a NUL
            yield f"{option}=text{k}", [*argv, option, value], ok | TWO, (), ()


def _swap(argv: list[str], old: str, new: str) -> list[str]:
    """``argv`` with the file ``old`` named ``new`` (also inside ``replay:`` and URLs)."""
    return [new if a == old else a.replace(f":{old}", f":{new}").replace(f"/{old}", f"/{new}")
            for a in argv]  # fmt: skip


def _links(kit: Kit, argv: list[str], ok: frozenset[int], expensive: bool) -> Iterator[Variant]:
    folder = kit.folder
    for name in list(kit.inputs):
        for how in ("symlink", "dangling", "loop", "fifo", "folder"):
            if how == "symlink" and expensive:
                continue
            new = f"{how}-{name}"
            path = folder / new
            if not os.path.lexists(path):
                if how == "symlink":
                    os.symlink(name, path)
                elif how == "dangling":
                    os.symlink(f"gone-{name}", path)
                elif how == "loop":
                    os.symlink(new, path)
                elif how == "fifo":
                    os.mkfifo(path)
                else:
                    path.mkdir()
            allowed = ok | TWO if how == "symlink" else TWO
            if kit.inputs[name] == "campaign" and how == "symlink":
                allowed = ok
            words = () if how in ("symlink", "folder") else (new,)  # a folder may be a batch
            yield f"input_{how}_{name}", _swap(argv, name, new), allowed, words, ()
    for option, name in kit.outputs.items():
        source = next(iter(kit.inputs), None)
        variants: list[tuple[str, Callable[[Path], None] | None, frozenset[int], bool]] = [
            ("dangling", lambda p: os.symlink(f"target-{p.name}", p), ok | TWO, True),
            ("loop", lambda p: os.symlink(p.name, p), TWO, False),
            ("under_a_file", None, TWO, False),
            ("missing_folder", None, ok | TWO, False),
        ]
        if source is not None and kit.inputs[source] not in ("campaign", "history"):
            variants += [
                ("symlink_to_input", lambda p, s=source: os.symlink(s, p), TWO, False),
                ("hardlink_to_input", lambda p, s=source: os.link(folder / s, p), TWO, False),
            ]
        for how, make, allowed, watch in variants:
            if expensive and allowed != TWO:
                continue
            new = f"{how}-{name}"
            if how == "under_a_file":
                (folder / f"file-{name}").write_bytes(b"a file")
                new = f"file-{name}/{name}"
            elif how == "missing_folder":
                new = f"new-{name}/sub/{name}"
            elif make is not None and not os.path.lexists(folder / new):
                make(folder / new)
            absent = (f"target-{new}",) if watch else ()
            yield f"output_{how}_{option}", _swap(argv, name, new), allowed, (option, new), absent


def _nested_toml(text: str, depth: int) -> bytes:
    return ("x = " + "[" * depth + "]" * depth + "\n" + text).encode()


def _nested_pnref(path: Path, depth: int) -> bytes:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: np.asarray(data[k]) for k in data.files}
    header = str(arrays["header"])
    arrays["header"] = np.array(header[:-1] + ', "x": ' + "[" * depth + "]" * depth + "}")
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def _nesting(kit: Kit, argv: list[str], ok: frozenset[int], rng: np.random.Generator,
             expensive: bool) -> Iterator[Variant]:  # fmt: skip
    for name, kind in list(kit.inputs.items()):
        depth = int(rng.choice([13, 65, 1_000, 100_000]))
        path = kit.folder / name
        if kind in ("machine", "map"):
            content = _nested_toml(path.read_text("utf-8"), depth)
        elif kind == "recording":
            content = fuzzing_bounds._nested_metadata(path, depth)
        elif kind == "reference":
            content = _nested_pnref(path, depth)
        else:
            continue
        deep = depth > 64
        if expensive and not deep:
            continue
        new = f"deep{depth}-{name}"
        (kit.folder / new).write_bytes(content)
        allowed = TWO if deep else ok | TWO
        yield f"nested_{depth}_{name}", _swap(argv, name, new), allowed, (new,), ()


def _renamed_channel(path: Path, name: str) -> bytes:
    """``path``'s recording with its last channel renamed ``name`` (CRC kept valid)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    names = table.column("name").to_pylist()
    names[-1] = name
    table = table.set_column(table.schema.get_field_index("name"), "name", pa.array(names))
    buf = io.BytesIO()
    pq.write_table(table, buf)
    return buf.getvalue()


def _names(kit: Kit, argv: list[str], ok: frozenset[int], rng: np.random.Generator,
           command: str, expensive: bool) -> Iterator[Variant]:  # fmt: skip
    if expensive:
        return
    pool = [*NAMES, *hostile_names(rng, RANDOM_NAMES)]
    for name, kind in list(kit.inputs.items()):
        label = pool[int(rng.integers(len(pool)))]
        path = kit.folder / name
        if kind == "machine":
            text = path.read_text("utf-8")
            data = text.replace(f'name = "{MACHINE}"', f"name = {json.dumps(label)}", 1).encode()
        elif kind == "recording":
            data = _renamed_channel(path, label)
        else:
            continue
        new = f"named-{name}"
        (kit.folder / new).write_bytes(data)
        yield f"name_{kind}_{name}", _swap(argv, name, new), ok | TWO, (new,), ()
    if command == "simulate":
        for k, label in enumerate(pool):
            if "\x00" not in label:
                yield f"leak_location_{k}", [*argv, "--leak", f"{label}=40slpm"], TWO, (
                    "--leak",), ()  # fmt: skip


def variants(
    command: str, kit: Kit, rng: np.random.Generator, only_stray: bool = False
) -> list[Variant]:
    """Every variant of ``command`` the generators make (its inputs placed in ``kit``);
    ``only_stray``: just the stray option (the quick slice)."""
    entry = COMMANDS[command]
    argv = entry.argv(kit)
    ok, expensive = entry.ok, entry.expensive
    found: list[Variant] = [
        ("stray_argument", [*argv, "--stray-option-x"], TWO, ("--stray-option-x",), ())
    ]
    if only_stray:
        return found
    found += _numbers(command, argv, ok, expensive, entry.fixed)
    found += _texts(command, argv, ok, expensive, entry.fixed, rng)
    found += _links(kit, argv, ok, expensive)
    found += _nesting(kit, argv, ok, rng, expensive)
    found += _names(kit, argv, ok, rng, command, expensive)
    return found


def _outputs(argv: list[str], names: Iterable[str]) -> list[str]:
    """The output files of a variant: each named output, or the path that replaced it."""
    found = []
    for name in names:
        for arg in argv:
            path = arg.removeprefix("sqlite:///")
            if path.endswith(("-" + name, "/" + name)) or path == name:
                found.append(path)
                break
    return found


def build_generated(
    base: dict[str, Path],
    root: Path,
    full: bool,
    wanted: Iterable[str],
    seed: int = SEED,
    per_command: int | None = None,
) -> list[Case]:
    """``per_command`` (:data:`PER_COMMAND`) variants of each command in ``wanted`` drawn
    with ``seed``; the quick slice: each quick command with a stray option (in-process, so
    never a pipe)."""
    per_command = PER_COMMAND if per_command is None else per_command
    cases = []
    for k, command in enumerate(sorted(set(wanted) & set(COMMANDS))):
        entry = COMMANDS[command]
        if not full and (entry.expensive or not entry.quick):
            continue
        rng = np.random.default_rng(seed + k)
        folder = _case_dir(root, f"gen-{command.replace(' ', '-')}")
        kit = Kit(base, root, folder)
        found = variants(command, kit, rng, only_stray=not full)
        pick = sorted(int(j) for j in rng.permutation(len(found))[:per_command]) if full else [0]
        for i in pick:
            label, argv, allowed, words, absent = found[i]
            for name in kit.outputs.values():  # each variant its own outputs
                argv = _swap(argv, name, f"v{i}-{name}")
                words = tuple(w.replace(f"/{name}", f"/v{i}-{name}") for w in words)
            outputs = _outputs(argv, kit.outputs.values())
            # an output whose option the variant sets otherwise may rightly not appear
            moved = any(label.startswith(f"{option}=") for option in kit.outputs)
            optional = [o for o in outputs if moved or any(o.endswith(n) for n in kit.optional)]
            cases.append(
                Case(f"{command}/gen_{label}", command, argv, folder, list(kit.inputs),
                     outputs, allowed, words, absent=absent, optional=tuple(optional))
            )  # fmt: skip
    return cases


def missing_entries(commands: Iterable[str]) -> list[str]:
    """Commands without a generator entry (``test_every_command_has_a_generator_entry``)."""
    return sorted(set(commands) - set(COMMANDS))
