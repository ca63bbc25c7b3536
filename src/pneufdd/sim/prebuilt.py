"""The twin's compiled code built ahead of time, so that short commands start at once.

numba compiles the twin's kernels (:func:`pneufdd.sim.kernel.run_cycle`, the sensor
lag :func:`pneufdd.sim.kernel.first_order_recursion_kernel`, the sensor reading
:func:`pneufdd.sim.kernel.sensor_reading_kernel`, the true-signal copy
:func:`pneufdd.sim.kernel.truth_rows_kernel`) on first use and keeps
them in its on-disk cache. Loading them from that cache still imports numba and
prepares its compiler (together about 0.6 s per process, most of a four-cycle
``pneufdd simulate``; ``benchmarks/bench_startup.py``). ``pneufdd build-twin`` (or
:func:`build_prebuilt_twin`) compiles the same Python functions once more with
numba's ahead-of-time compiler (:mod:`numba.pycc`) into an ordinary extension module;
a process that finds a current one uses it and never imports numba for the twin.

* **Same code, same numbers.** The module is compiled from the very functions the
  JIT compiles (their ``py_func``), for the same argument types, by the same LLVM
  without fast-math, for the generic CPU of the platform (no host-specific
  instructions, so a cache directory shared by different x86-64 machines works).
  Recordings are bit-for-bit those of the JIT (``tests/test_sim_prebuilt.py``).
* **Never stale.** The module's name holds a hash of every source file of
  :mod:`pneufdd.physics` and :mod:`pneufdd.sim`, and of the Python, NumPy, numba and
  llvmlite versions and the platform. After any edit or upgrade the name no longer
  matches, the module is ignored and the JIT runs, until ``pneufdd build-twin`` is
  run again.
* **Guarded.** numba's ahead-of-time wrappers trust their declared types; each call
  compares its arrays' layout with the one the module was typed for, and any other
  layout runs on the JIT (:class:`_Guarded`).
* **Threads.** numba's ahead-of-time wrappers keep the GIL by default; the build
  sets the same "release the GIL" flag as the JIT's ``nogil=True`` (numba's
  ``Flags.release_gil``), so the diagnosis's simulation checks still run in
  parallel on threads.
* **Where.** ``$PNEUFDD_PREBUILT_DIR``, else ``~/.cache/pneufdd/prebuilt``
  (``$XDG_CACHE_HOME`` respected): one place for ``make`` and a plain shell alike.
  numba's own cache directory (``$NUMBA_CACHE_DIR``, which the Makefile sets to
  ``.numba_cache``) plays no part, so a twin built by ``make demo`` is found by a
  ``pneufdd`` started from any shell. Checkouts of different sources may share the
  directory: each module's name holds its sources' hash. Building replaces
  the older builds in that directory; the new file is written aside and renamed, so
  a process never loads a half-written module. ``PNEUFDD_PREBUILT=0`` makes every
  process use the JIT.

Building needs a C compiler and Python's headers (numba links its runtime into the
module), and takes about 15 s. :mod:`numba.pycc` is marked "pending deprecation" by
numba: if a numba without it is installed, the build fails with a clear error and
everything runs on the JIT, with the same results.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.machinery
import importlib.util
import os
import platform
import shutil
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from pneufdd.errors import PneufddError

__all__ = [
    "CompiledTwin",
    "PrebuiltBuildError",
    "build_prebuilt_twin",
    "compiled_twin",
    "load_prebuilt_twin",
    "prebuilt_directory",
    "prebuilt_path",
]

DIRECTORY_ENV = "PNEUFDD_PREBUILT_DIR"
"""Environment variable naming the directory of the prebuilt twin."""
SWITCH_ENV = "PNEUFDD_PREBUILT"
"""Environment variable: ``0`` makes every process use numba's JIT."""
_PREFIX = "pneufdd_twin_"
_PACKAGE = Path(__file__).resolve().parent.parent


class PrebuiltBuildError(PneufddError):
    """The prebuilt twin could not be compiled (compiler, headers or numba missing)."""


class CompiledTwin(NamedTuple):
    """The twin's compiled functions a simulation calls, and where they come from."""

    run_cycle: Callable[..., tuple[int, int, int, int]]
    """:func:`pneufdd.sim.kernel.run_cycle`."""
    first_order_recursion: Callable[..., Any]
    """:func:`pneufdd.sim.kernel.first_order_recursion_kernel`."""
    sensor_reading: Callable[..., Any]
    """:func:`pneufdd.sim.kernel.sensor_reading_kernel`."""
    truth_rows: Callable[..., Any]
    """:func:`pneufdd.sim.kernel.truth_rows_kernel`."""
    origin: str
    """``"jit"`` or the path of the prebuilt module."""


def prebuilt_directory() -> Path:
    """The directory that holds the prebuilt twin (see the module's notes)."""
    if os.environ.get(DIRECTORY_ENV):
        return Path(os.environ[DIRECTORY_ENV])
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "pneufdd" / "prebuilt"


def _sources() -> list[Path]:
    """The files whose code the prebuilt module holds or whose arrays it is typed for."""
    return sorted([*(_PACKAGE / "physics").glob("*.py"), *(_PACKAGE / "sim").glob("*.py")])


def _version(package: str) -> str:
    """The installed version of ``package`` without importing it.

    The name of its ``.dist-info`` folder next to the package (``numba-0.61.2.dist-info``);
    :mod:`importlib.metadata` would do the same but costs 20-25 ms to import, 5 % of a
    short ``pneufdd simulate``. Without that folder: the size and time of the package's
    ``__init__.py``, which change when it is reinstalled.
    """
    spec = importlib.util.find_spec(package)
    if spec is None or spec.origin is None:
        return "absent"
    init = Path(spec.origin)
    infos = sorted(init.parent.parent.glob(f"{package}-*.dist-info"))
    if infos:
        return infos[-1].name
    stat = init.stat()
    return f"{init}:{stat.st_size}:{stat.st_mtime_ns}"


def build_key() -> str:
    """Hash of the sources, the compiler's and runtime's versions and the platform [hex]."""
    digest = hashlib.sha256()
    for part in (
        sys.implementation.cache_tag,
        sys.version,
        platform.machine(),
        np.__version__,
        _version("numba"),
        _version("llvmlite"),
    ):
        digest.update(part.encode() + b"\0")
    for path in _sources():
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def _module_name() -> str:
    return _PREFIX + build_key()[:24]


def prebuilt_path(directory: Path | None = None) -> Path:
    """Where the prebuilt twin of the installed sources is (or would be) [path]."""
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    return (directory or prebuilt_directory()) / (_module_name() + suffix)


def load_prebuilt_twin(directory: Path | None = None) -> ModuleType | None:
    """The prebuilt module of the installed sources, or None if there is none.

    Parameters
    ----------
    directory : Path, optional
        Where to look (default :func:`prebuilt_directory`).

    Returns
    -------
    module or None
        The extension module (functions ``run_cycle``, ``first_order_recursion``,
        ``sensor_reading`` and ``truth_rows``);
        None if it was not built for these sources, or does not load on this system.
    """
    path = prebuilt_path(directory)
    if not path.is_file():
        return None
    spec = importlib.util.spec_from_file_location(path.name.split(".")[0], path)
    if spec is None or spec.loader is None:  # pragma: no cover - an extension suffix always has one
        return None
    try:
        module = importlib.util.module_from_spec(spec)  # loads the shared library
        spec.loader.exec_module(module)
    except (ImportError, OSError):
        return None  # a module built on another system: the JIT gives the same results
    return module


_KERNELS = {
    "run_cycle": "run_cycle",
    "first_order_recursion": "first_order_recursion_kernel",
    "sensor_reading": "sensor_reading_kernel",
    "truth_rows": "truth_rows_kernel",
}
"""The twin's compiled functions: each a :class:`CompiledTwin` field and an export of the
prebuilt module, and its name in :mod:`pneufdd.sim.kernel`."""


def _jit_twin() -> CompiledTwin:
    from pneufdd.sim import kernel

    functions: dict[str, Any] = {name: getattr(kernel, k) for name, k in _KERNELS.items()}
    return CompiledTwin(**functions, origin="jit")


Layout = tuple[tuple[str, int, bool, bool], ...]


def argument_layout(arguments: Sequence[Any]) -> Layout:
    """Dtype, dimensions, C order and writability of every array in ``arguments``.

    Arguments are arrays, or records (tuples) of arrays; anything else is described
    by its type name, so it never matches an array's layout.
    """
    layout = []
    for argument in arguments:
        for array in argument if isinstance(argument, tuple) else (argument,):
            if isinstance(array, np.ndarray):
                flags = array.flags
                layout.append((array.dtype.str, array.ndim, flags.c_contiguous, flags.writeable))
            else:
                layout.append((type(array).__name__, -1, False, False))
    return tuple(layout)


class _Guarded:
    """A prebuilt function that runs only on the argument layout it was compiled for.

    Ahead-of-time wrappers trust their declared types: an array of another dtype or
    number of dimensions is read as if it had the declared ones (a wrong result or a
    crash). Any other layout goes to the JIT's function, which compiles for it.
    """

    def __init__(self, prebuilt: Callable[..., Any], layout: Layout, jit_name: str) -> None:
        self._prebuilt = prebuilt
        self._layout = layout
        self._jit_name = jit_name

    def __call__(self, *arguments: Any) -> Any:
        if argument_layout(arguments) == self._layout:
            return self._prebuilt(*arguments)
        return getattr(_jit_twin(), self._jit_name)(*arguments)


def _prebuilt_twin(module: ModuleType) -> CompiledTwin:
    """The module's functions, each guarded by the layout of the arguments it is typed for."""
    examples = _example_arguments()
    guarded: dict[str, Any] = {
        name: _Guarded(getattr(module, name), argument_layout(examples[name]), name)
        for name in _KERNELS
    }
    return CompiledTwin(**guarded, origin=str(module.__file__))


def _example_arguments() -> dict[str, tuple[Any, ...]]:
    """Arguments of the kind a simulation passes each compiled function.

    The prebuilt module is typed for them (:func:`_signatures`) and guards every call
    with their layout (:class:`_Guarded`): the kernel's records
    (:func:`pneufdd.sim.simulate.kernel_arguments`); a float64 vector and two floats
    for the recursion; two read-only float64 vectors (samples and noise draws), an int
    and six floats for the sensor reading (:func:`pneufdd.sim.sensors.apply_sensor`);
    the kernel's output buffers, the rows' sources and columns, the store and two ints
    for the true-signal copy.
    """
    from pneufdd.sim.simulate import kernel_arguments

    arguments = kernel_arguments()
    vector = arguments[2].jitter
    samples = vector.view()
    samples.flags.writeable = False
    outputs = arguments[4]
    index = np.zeros(1, dtype=np.int64)
    return {
        "run_cycle": tuple(arguments),
        "first_order_recursion": (vector, 0.5, 0.5),
        "sensor_reading": (samples, samples, 0, 1.0, 0.0, 0.0, 0.0, 10.0, 0.1),
        "truth_rows": (
            *(outputs.p, outputs.x, outputs.fch, outputs.fexh, outputs.fr),
            *(index, index, np.zeros((1, 1)), 0, 1),
        ),
    }


@functools.cache
def compiled_twin() -> CompiledTwin:
    """The prebuilt twin if one is current, else numba's JIT (identical results).

    Decided once per process; ``PNEUFDD_PREBUILT=0`` chooses the JIT.
    """
    if os.environ.get(SWITCH_ENV, "1") != "0":
        module = load_prebuilt_twin()
        if module is not None:
            return _prebuilt_twin(module)
    return _jit_twin()


@contextmanager
def _wrappers_release_gil() -> Iterator[None]:
    """Compile pycc's Python wrappers with numba's ``release_gil`` flag (``nogil=True``).

    numba.pycc builds every export with a default ``Flags()`` and offers no option for
    the GIL; the wrapper code that releases it is numba's own (the JIT's ``nogil``).
    """
    import numba.pycc.compiler as pycc_compiler
    from numba.core.compiler import Flags

    class _ReleasingFlags(Flags):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[no-untyped-call]
            setattr(self, "release_gil", True)  # noqa: B010 - numba's option descriptor

    setattr(pycc_compiler, "Flags", _ReleasingFlags)  # noqa: B010 - not exported by numba
    try:
        yield
    finally:
        setattr(pycc_compiler, "Flags", Flags)  # noqa: B010


def _signatures() -> dict[str, Any]:
    """The exported functions' numba signatures: the types a simulation passes them."""
    import numba
    from numba.core import types

    examples = _example_arguments()
    typeof: Any = numba.typeof
    unituple: Any = types.UniTuple
    vector = typeof(examples["first_order_recursion"][0])  # what the vector kernels return
    returns = {
        "run_cycle": unituple(types.int64, 4),
        "first_order_recursion": vector,
        "sensor_reading": vector,
        "truth_rows": types.none,
    }
    return {name: returns[name](*map(typeof, examples[name])) for name in _KERNELS}


def build_prebuilt_twin(directory: Path | None = None, force: bool = False) -> Path:
    """Compile the twin ahead of time for the installed sources (about 15 s).

    Parameters
    ----------
    directory : Path, optional
        Where to write it (default :func:`prebuilt_directory`); created if missing.
    force : bool
        Compile even if a current module exists.

    Returns
    -------
    Path
        The module's path.

    Raises
    ------
    PrebuiltBuildError
        If numba's ahead-of-time compiler, a C compiler or Python's headers are missing.
    """
    directory = directory or prebuilt_directory()
    target = prebuilt_path(directory)
    if not force and load_prebuilt_twin(directory) is not None:
        return target
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise PrebuiltBuildError(
            f"cannot make the prebuilt twin's folder {str(directory)!r}: "
            f"{error.strerror or error}; give a folder that can be created and written"
        ) from error
    import numba
    from numba.core.errors import NumbaPendingDeprecationWarning

    from pneufdd.sim import kernel

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        try:
            from numba.pycc.cc import CC
        except ImportError as error:
            raise PrebuiltBuildError(
                f"numba's ahead-of-time compiler (numba.pycc, numba {numba.__version__}) "
                f"cannot be loaded ({error}); it needs setuptools, and numbas after its "
                "removal have none; the twin runs on numba's JIT with the same results"
            ) from error
    signatures = _signatures()
    name = target.name.split(".")[0]
    workspace = Path(tempfile.mkdtemp(prefix=".build-", dir=directory))
    try:
        compiler = CC(name)  # type: ignore[no-untyped-call]
        compiler.output_dir = str(workspace)
        compiler.target_cpu = ""  # the platform's generic CPU: portable, same numbers
        for name, function in _KERNELS.items():
            export = compiler.export(name, signatures[name])  # type: ignore[no-untyped-call]
            export(getattr(kernel, function).py_func)
        with _wrappers_release_gil():
            try:
                compiler.compile()
            except Exception as error:  # compiler, linker or headers missing
                raise PrebuiltBuildError(
                    f"compiling the prebuilt twin failed ({type(error).__name__}: {error}); "
                    "it needs a C compiler (gcc) and Python's headers (Python.h); the twin "
                    "runs on numba's JIT with the same results"
                ) from error
        os.replace(workspace / compiler.output_file, target)
    finally:
        shutil.rmtree(workspace, ignore_errors=True)
    for old in directory.glob(_PREFIX + "*"):
        if old != target and old.is_file():
            old.unlink(missing_ok=True)
    return target
