"""The portable ``.pnref`` reference file: one NPZ with a JSON header, no pickle.

Layout (format ``pneufdd-reference``, version :data:`FORMAT_VERSION`):

=====================  ===========================================================
entry                  content
=====================  ===========================================================
``header``             0-d unicode array holding a JSON object: format, version,
                       machine, machine description (the TOML mapping of
                       docs/machine-format.md, or null), channels, units, n_steps,
                       n_cycles, feature names, detection settings, localisation
                       settings, sources, supply pressure, trace rate, signature
                       locations, PLC sequence
``features``           (n_cycles, n_features) float64 reference feature vectors
``cycle_recording``    (n_cycles,) int64, optional: index in ``sources`` of the
                       recording each reference cycle came from (absent in files
                       written before; the detector then cross-validates cycles in turn)
                       (the header's optional ``recording_session`` gives each
                       source's session: triggered captures of one acquisition)
``band_mean``          (n_channels, n_samples) float64, optional
``band_std``           (n_channels, n_samples) float64, optional
``trace_offsets``      (n_steps + 1,) int64, optional (with the band arrays)
``sig_sizes``          (n_locations, n_sizes) float64, optional [kg/s]
``sig_deltas``         (n_locations, n_sizes, n_features) float64, optional
``sig_pressure``       (n_locations,) float64, optional [Pa]
``sig_interaction``    (n_locations, n_features) float64, optional
``sig_interaction_sizes`` (2,) float64, optional [kg/s]
``sig_mean_flow``      (n_locations, n_sizes) float64, optional: mean leaked mass
                       flow per machine cycle at each signature size [kg/s]
``sig_mean_flow_interaction`` (n_locations, 2) float64, optional: change of the
                       line and supply leaks' mean flows when both leak [kg/s]
``sig_plant_deviations`` (n_plants, n_locations, n_dev_sizes, n_features) float32,
                       optional: each plausible plant's leak effect minus the
                       signature's (the model uncertainty) [feature unit]
``sig_deviation_sizes`` (n_dev_sizes,) float64, with the above [kg/s]
=====================  ===========================================================

Version history: 1 (issue 5); 2 adds ``sig_mean_flow`` and
``sig_mean_flow_interaction`` (a leak is priced by the air it loses over a cycle, not
by its flow while its line is pressurised); 3 holds the machine description itself
(signatures, the simulation check and the cost duties come from it, never from a
machine looked up by name) and the localisation settings. A file of another version
is refused with a message asking to rebuild the reference.

The file is written to a temporary name and renamed into place; it is read with
``allow_pickle=False`` and every entry's presence, dtype and shape is checked. Before
any entry is loaded, the shape its ``.npy`` header declares must fit the bytes the
archive holds for it (a damaged header never asks for gigabytes), and the JSON
header's fields are checked for type and range (issue 14).
"""

from __future__ import annotations

import json
import math
import re
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pneufdd.diagnosis.effects.signatures import SignatureSet
from pneufdd.diagnosis.localisation.search import LocalisationSettings
from pneufdd.diagnosis.reference.model import DetectionSettings, ReferenceModel
from pneufdd.errors import (
    FileExistsInputError,
    FileFormatError,
    InputError,
    MissingFileError,
    describe,
)
from pneufdd.files import atomic_target
from pneufdd.limits import MAX_REFERENCE_CYCLES, check_memory
from pneufdd.physics.units import UNITS

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "load_reference", "save_reference"]

FORMAT_NAME = "pneufdd-reference"
FORMAT_VERSION = 3


def _header(model: ReferenceModel) -> dict[str, Any]:
    sig = model.signatures
    return {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "machine": model.machine,
        "machine_description": model.machine_description or None,
        "channels": list(model.channels),
        "units": list(model.units),
        "n_steps": model.n_steps,
        "n_cycles": model.n_cycles,
        "feature_names": list(model.feature_names),
        "settings": model.settings.to_dict(),
        "localisation": model.localisation.to_dict(),
        "sources": list(model.sources),
        "recording_session": list(model.recording_session),
        "supply_pressure": None if math.isnan(model.supply_pressure) else model.supply_pressure,
        "trace_rate_hz": model.trace_rate_hz,
        "signature_locations": None if sig is None else [str(x) for x in sig.locations],
        "signature_baseline_run": (
            None if sig is None or sig.baseline_run is None else list(sig.baseline_run)
        ),
        "sequence": list(model.sequence),
    }


def _reference_exists(target: Path) -> FileExistsInputError:
    return FileExistsInputError(
        describe(f"reference file {str(target)!r}", "exists", "overwrite=True")
    )


def save_reference(model: ReferenceModel, path: str | Path, overwrite: bool = False) -> Path:
    """Write ``model`` to ``path`` atomically.

    Parameters
    ----------
    model : ReferenceModel
        The reference.
    path : str or Path
        Target file, conventionally ``*.pnref``.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        The path written.
    """
    target = Path(path)
    if target.exists() and not overwrite:
        raise _reference_exists(target)
    arrays: dict[str, npt.NDArray[Any]] = {
        "header": np.array(json.dumps(_header(model), allow_nan=False)),
        "features": model.features,
    }
    if model.cycle_recording is not None:
        arrays["cycle_recording"] = np.asarray(model.cycle_recording, dtype=np.int64)
    if model.band_mean is not None and model.band_std is not None:
        arrays["band_mean"] = model.band_mean
        arrays["band_std"] = model.band_std
        arrays["trace_offsets"] = np.asarray(model.trace_offsets, dtype=np.int64)
    if model.signatures is not None:
        arrays["sig_sizes"] = model.signatures.sizes
        arrays["sig_deltas"] = model.signatures.deltas
        arrays["sig_pressure"] = model.signatures.nominal_pressure
        if model.signatures.interaction is not None:
            arrays["sig_interaction"] = model.signatures.interaction
            arrays["sig_interaction_sizes"] = np.asarray(model.signatures.interaction_sizes)
        if model.signatures.mean_flow is not None:
            arrays["sig_mean_flow"] = model.signatures.mean_flow
        if model.signatures.mean_flow_interaction is not None:
            arrays["sig_mean_flow_interaction"] = model.signatures.mean_flow_interaction
        sig = model.signatures
        if sig.plant_deviations is not None and sig.deviation_sizes is not None:
            # float32: 7 significant digits, far beyond the deviations' own precision
            arrays["sig_plant_deviations"] = sig.plant_deviations.astype(np.float32)
            arrays["sig_deviation_sizes"] = sig.deviation_sizes
        if sig.baseline is not None:
            arrays["sig_baseline"] = sig.baseline
    with atomic_target(target, overwrite, _reference_exists) as tmp, tmp.open("wb") as handle:
        np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]
    return target


def _bad(path: Path, what: str, received: object, allowed: object) -> FileFormatError:
    return FileFormatError(
        describe(f"reference file {str(path)!r}: {what}", received, str(allowed))
    )


def _array(
    data: Any, path: Path, name: str, kind: str, shape: tuple[int | None, ...]
) -> npt.NDArray[Any]:
    if name not in data.files:
        raise _bad(path, "missing entry", name, "a complete .pnref file")
    arr = np.asarray(data[name])
    if arr.dtype.kind != kind:
        raise _bad(path, f"dtype of {name!r}", str(arr.dtype), f"kind {kind!r}")
    if arr.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(arr.shape, shape, strict=True)
    ):
        raise _bad(path, f"shape of {name!r}", arr.shape, shape)
    return arr


def load_reference(path: str | Path) -> ReferenceModel:
    """Read and validate a ``.pnref`` reference file.

    Raises
    ------
    FileFormatError
        If the file is missing, not a reference file, of another version, or has a
        missing, mistyped or misshapen entry; the message names the file.
    """
    source = Path(path)
    if not source.is_file():
        raise MissingFileError(describe("reference file", str(source), "an existing .pnref file"))
    with open(source, "rb") as handle:
        return _load(handle, source)


MAX_DEFLATE_RATIO = 1032
"""Largest expansion of deflate (zlib's documented limit is 1032:1)."""


REFERENCE_LOAD_FACTOR = 4
"""Working memory per byte of a reference's arrays while it is loaded and used."""

_ENTRY = re.compile(r"[A-Za-z0-9_]{1,64}\.npy")
"""The entries numpy.savez writes: one per array, named after it."""


def _check_local_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, source: Path) -> None:
    """Refuse an entry whose local header disagrees with the archive's directory.

    zipfile reads an entry by its central-directory record and most of the local header
    goes unread, so a damaged local header (other flags, another compression method,
    name or checksum) would pass unnoticed; pneufdd writes both alike, so any
    disagreement is damage, and a damaged reference is refused.
    """
    fp = archive.fp
    if fp is None:  # pragma: no cover - the archive is open while its entries are read
        return
    fp.seek(info.header_offset)
    header = fp.read(30)
    name = fp.read(len(info.orig_filename.encode("utf-8")))
    if len(header) != 30:
        header = bytes(30)
    flags = int.from_bytes(header[6:8], "little")
    method = int.from_bytes(header[8:10], "little")
    crc = int.from_bytes(header[14:18], "little")
    crc_here = not flags & 0x08  # else it follows the data (a data descriptor)
    if (
        header[:4] != b"PK\x03\x04"
        or flags != info.flag_bits
        or method != info.compress_type
        or name != info.orig_filename.encode("utf-8")
        or (crc_here and crc != info.CRC)
    ):
        raise _bad(
            source,
            f"entry {info.filename!r}",
            "a local header that disagrees with the archive's directory",
            "an undamaged .pnref (NPZ) file",
        )


def _check_entries(handle: Any, source: Path) -> None:
    """Refuse entries whose declared dtype or shape the archive cannot hold."""
    try:
        archive = zipfile.ZipFile(handle)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise _bad(source, "not readable", type(exc).__name__, "a .pnref (NPZ) file") from exc
    total = 0
    seen: set[str] = set()
    with archive:
        for info in archive.infolist():
            # only what numpy.savez writes: no path, no duplicate (zipfile reads the last
            # of two alike, a check the first), no encryption (zipfile raised RuntimeError)
            if not _ENTRY.fullmatch(info.filename) or info.filename in seen:
                raise _bad(source, "entry name", info.filename, "one <array>.npy per array")
            if info.flag_bits & 0x1:
                raise _bad(source, f"entry {info.filename!r}", "encrypted", "not encrypted")
            seen.add(info.filename)
            name = info.filename[:-4]
            _check_local_header(archive, info, source)
            try:
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(member)
                    else:
                        shape, _, dtype = np.lib.format.read_array_header_2_0(member)
            except (
                ValueError,
                OSError,
                EOFError,
                zlib.error,
                zipfile.BadZipFile,
                NotImplementedError,  # a compression method zipfile does not know
            ) as exc:
                raise _bad(source, f"entry {name!r}", str(exc)[:80], "a NumPy array") from exc
            if dtype.hasobject:
                raise _bad(source, f"dtype of {name!r}", str(dtype), "numbers or text (no pickle)")
            declared = math.prod(shape) * dtype.itemsize
            if declared > info.file_size or info.file_size > MAX_DEFLATE_RATIO * max(
                info.compress_size, 1
            ) + (1 << 16):
                raise _bad(
                    source,
                    f"shape of {name!r}",
                    f"{shape} ({declared:,} bytes)",
                    f"what the file holds ({info.file_size:,} bytes uncompressed)",
                )
            total += declared
    check_memory(  # deflate packs 1032:1: a 7.8 MB file may declare 8 GB of zeros
        f"reference file {str(source)!r}: its arrays ({total:,} bytes uncompressed)",
        REFERENCE_LOAD_FACTOR * total,
        error=FileFormatError,
    )


def _header_fields(header: dict[str, Any], source: Path) -> None:
    """Check the JSON header's fields for type and range before they are used."""

    def need(key: str, ok: bool, allowed: str) -> None:
        if not ok:
            raise _bad(source, f"header field {key!r}", header.get(key), allowed)

    def is_int(value: object, low: int, high: int) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high

    def str_list(value: object) -> bool:
        return isinstance(value, list) and all(isinstance(v, str) for v in value)

    need("channels", str_list(header.get("channels")), "a list of channel names")
    need("units", str_list(header.get("units")), "a list of units, one per channel")
    need(
        "units",
        len(header["units"]) == len(header["channels"]),
        f"{len(header['channels'])} units (one per channel)",
    )
    need(
        "units",
        all(u in UNITS and UNITS[u].si_unit == u for u in header["units"]),
        "SI units ('Pa', 'kg/s', 'm', ...)",
    )
    need("n_steps", is_int(header.get("n_steps"), 1, 100_000), "an integer from 1 to 100000")
    need(
        "n_cycles",
        is_int(header.get("n_cycles"), 1, MAX_REFERENCE_CYCLES),
        f"an integer from 1 to {MAX_REFERENCE_CYCLES:,} (docs/limits.md)",
    )
    need("feature_names", str_list(header.get("feature_names")), "a list of feature names")
    check_memory(  # a FileFormatError: the file, not an option, asks for too much
        f"reference file {str(source)!r}: header fields 'n_cycles' x 'feature_names' "
        f"({header['n_cycles']:,} x {len(header['feature_names']):,} features)",
        REFERENCE_BYTES_PER_VALUE * header["n_cycles"] * max(len(header["feature_names"]), 1),
        error=FileFormatError,
    )
    rate = header.get("trace_rate_hz")
    need(
        "trace_rate_hz",
        isinstance(rate, int | float)
        and not isinstance(rate, bool)
        and math.isfinite(rate)
        and 0 < rate <= 1e5,
        "a rate > 0 and <= 100000 Hz",
    )
    need("machine", isinstance(header.get("machine"), str), "the machine's name")
    for key in ("settings", "localisation"):
        need(key, isinstance(header.get(key), dict), "a table of settings")
    supply = header.get("supply_pressure")
    need(
        "supply_pressure",
        supply is None
        or (isinstance(supply, int | float) and not isinstance(supply, bool) and supply > 0),
        "null or a pressure > 0 [Pa]",
    )
    need("sources", str_list(header.get("sources", [])), "a list of file names")
    sessions = header.get("recording_session", [])
    need(
        "recording_session",
        isinstance(sessions, list)
        and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in sessions),
        "a list of session numbers >= 0, one per source",
    )
    locations = header.get("signature_locations")
    need("signature_locations", locations is None or str_list(locations), "null or names")
    sequence = header.get("sequence", [])
    need("sequence", isinstance(sequence, list), "a list of steps")
    for step in sequence:
        need(
            "sequence",
            isinstance(step, dict)
            and str_list(step.get("valves"))
            and isinstance(step.get("switches", []), list)
            and all(
                isinstance(s, list)
                and len(s) == 2
                and isinstance(s[0], str)
                and s[1] in (0, 1)
                and not isinstance(s[1], bool)
                for s in step.get("switches", [])
            ),
            "steps of {'valves': [...], 'switches': [[name, 0 or 1], ...]}",
        )


REFERENCE_BYTES_PER_VALUE = 80
"""Working memory of one reference feature value while a reference is loaded and its
detectors are fitted (the matrix, its cross-validation folds and scaled copies) [bytes]."""

MAX_FEATURE_MAGNITUDE = 1e12
"""Largest magnitude of a reference feature value (features are SI: Pa, kg, s, m)."""


def _settings(data: Any, source: Path) -> DetectionSettings:
    """The detection settings of a file's header, validated (an error names the file)."""
    try:
        return DetectionSettings.from_dict(data)
    except InputError as exc:
        raise FileFormatError(f"reference file {str(source)!r}: {exc}") from None


def _check_features(features: npt.NDArray[Any], source: Path) -> None:
    """Refuse infinite or absurd feature values (NaN marks a feature not measured)."""
    finite = features[np.isfinite(features)]
    if np.isinf(features).any() or (
        finite.size and float(np.max(np.abs(finite))) > MAX_FEATURE_MAGNITUDE
    ):
        raise _bad(
            source,
            "values of 'features'",
            "infinite or larger than 1e12 in magnitude",
            f"finite values of magnitude <= {MAX_FEATURE_MAGNITUDE:g} (SI units)",
        )


def _load(handle: Any, source: Path) -> ReferenceModel:
    _check_entries(handle, source)
    handle.seek(0)
    try:
        data = np.load(handle, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise _bad(source, "not readable", type(exc).__name__, "a .pnref (NPZ) file") from exc
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise _bad(source, "content", "a single array", "a .pnref (NPZ) archive")
    try:
        with data:
            try:
                header = json.loads(str(_array(data, source, "header", "U", ())))
            except (json.JSONDecodeError, RecursionError) as exc:
                raise _bad(source, "header", "invalid JSON", "a JSON object") from exc
            if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
                raise _bad(
                    source,
                    "format",
                    header.get("format") if isinstance(header, dict) else header,
                    FORMAT_NAME,
                )
            if header.get("version") != FORMAT_VERSION:
                raise FileFormatError(
                    describe(
                        f"reference file {str(source)!r}: format version",
                        header.get("version"),
                        f"version {FORMAT_VERSION} (the version this pneufdd reads)",
                    )
                    + "; rebuild the reference with 'pneufdd reference build' from its "
                    "leak-free recordings (add --machine DESCRIPTION when they carry no "
                    "machine description)"
                )
            _header_fields(header, source)
            try:
                channels = tuple(str(c) for c in header["channels"])
                units = tuple(str(u) for u in header["units"])
                n_steps = int(header["n_steps"])
                n_cycles = int(header["n_cycles"])
                names = tuple(str(n) for n in header["feature_names"])
                settings = _settings(header["settings"], source)
                localisation = LocalisationSettings.from_dict(header["localisation"])
                description = header["machine_description"]
                if description is not None and not isinstance(description, dict):
                    raise TypeError("machine_description is not a table")
                machine = str(header["machine"])
                rate = float(header["trace_rate_hz"])
            except FileFormatError:
                raise
            except (KeyError, TypeError, ValueError, AttributeError) as exc:
                raise _bad(source, "header field", str(exc), "a complete header") from exc
            n_feat = len(names)
            features = _array(data, source, "features", "f", (n_cycles, n_feat))
            _check_features(features, source)
            cycle_recording = None
            if "cycle_recording" in data.files:
                cycle_recording = _array(data, source, "cycle_recording", "i", (n_cycles,))
            band_mean = band_std = offsets = None
            if "band_mean" in data.files:
                band_mean = _array(data, source, "band_mean", "f", (len(channels), None))
                n_samples = band_mean.shape[1]
                band_std = _array(data, source, "band_std", "f", (len(channels), n_samples))
                offsets = _array(data, source, "trace_offsets", "i", (n_steps + 1,))
                if int(offsets[-1]) != n_samples:
                    raise _bad(source, "trace_offsets[-1]", int(offsets[-1]), n_samples)
                std_ok = np.isnan(band_std) | (band_std >= 0)
                if not np.all(std_ok) or np.any(np.isinf(band_std)):
                    raise _bad(source, "band_std", "negative or infinite values", ">= 0")
            signatures = None
            locations = header.get("signature_locations")
            if locations is not None:
                n_loc = len(locations)
                sizes = _array(data, source, "sig_sizes", "f", (n_loc, None))
                deltas = _array(data, source, "sig_deltas", "f", (n_loc, sizes.shape[1], n_feat))
                pressure = _array(data, source, "sig_pressure", "f", (n_loc,))
                inter = inter_sizes = None
                if "sig_interaction" in data.files:
                    inter = _array(data, source, "sig_interaction", "f", (n_loc, n_feat))
                    inter_sizes = _array(data, source, "sig_interaction_sizes", "f", (2,))
                mean_flow = None
                if "sig_mean_flow" in data.files:
                    mean_flow = _array(data, source, "sig_mean_flow", "f", sizes.shape)
                flow_inter = None
                if "sig_mean_flow_interaction" in data.files:
                    flow_inter = _array(data, source, "sig_mean_flow_interaction", "f", (n_loc, 2))
                deviations = deviation_sizes = None
                if "sig_plant_deviations" in data.files:
                    deviation_sizes = _array(data, source, "sig_deviation_sizes", "f", (None,))
                    deviations = _array(
                        data,
                        source,
                        "sig_plant_deviations",
                        "f",
                        (None, n_loc, deviation_sizes.size, n_feat),
                    )
                baseline = None
                baseline_run = header.get("signature_baseline_run")
                if baseline_run is not None:  # absent from references saved before it was kept
                    if not (
                        isinstance(baseline_run, list)
                        and len(baseline_run) == 2
                        and all(isinstance(x, int) for x in baseline_run)
                    ):
                        raise _bad(source, "signature_baseline_run", baseline_run, "[cycles, seed]")
                    baseline = _array(data, source, "sig_baseline", "f", (n_feat,))
                    baseline_run = tuple(baseline_run)
                signatures = SignatureSet(
                    tuple(locations),
                    sizes,
                    deltas,
                    names,
                    pressure,
                    inter,
                    inter_sizes,
                    mean_flow,
                    flow_inter,
                    deviations,
                    deviation_sizes,
                    baseline,
                    baseline_run,
                )
            supply = header.get("supply_pressure")
            model = ReferenceModel(
                machine=machine,
                machine_description=dict(description or {}),
                channels=channels,
                units=units,
                n_steps=n_steps,
                features=features,
                band_mean=band_mean,
                band_std=band_std,
                trace_offsets=offsets,
                trace_rate_hz=rate,
                supply_pressure=float("nan") if supply is None else float(supply),
                signatures=signatures,
                settings=settings,
                sources=tuple(str(s) for s in header.get("sources", [])),
                sequence=tuple(dict(step) for step in header.get("sequence", [])),
                localisation=localisation,
                cycle_recording=cycle_recording,
                recording_session=tuple(header.get("recording_session", [])),
            )
    except FileFormatError:
        raise
    except (InputError, zipfile.BadZipFile, OSError, ValueError, EOFError, zlib.error) as exc:
        raise _bad(source, "content", str(exc), "a valid pneufdd reference") from exc
    if model.feature_names != names:
        raise _bad(source, "feature_names", "inconsistent with channels/n_steps", "consistent")
    return model
