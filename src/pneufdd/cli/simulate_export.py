"""``pneufdd simulate --export-format NAME``: write the twin's run as a field export.

Self-contained so that ``simulate`` only calls :func:`check_export` before the run and
:func:`write_export` after it (``docs/recording.md``, "Field exports").
"""

from __future__ import annotations

from pathlib import Path

from pneufdd.errors import ChannelError, InputError, describe
from pneufdd.recording.model import Recording

__all__ = ["check_export", "write_export"]


def check_export(
    export_format: str | None, out: Path, export_map: Path | None, overwrite: bool
) -> None:
    """Refuse a bad ``--export-format``/``--export-map``/``--out`` before the simulation."""
    if export_format is None:
        if export_map is not None:
            raise InputError(describe("--export-map", str(export_map), "only with --export-format"))
        return
    # the export's writer (and its layouts) only when an export is asked for: a plain
    # `simulate` starts without them
    from pneufdd.cli.outputs import check_outputs
    from pneufdd.recording.field_export import EXPORT_FORMATS

    if export_format not in EXPORT_FORMATS:
        raise InputError(describe("--export-format", export_format, EXPORT_FORMATS))
    if out.suffix.lower() != ".csv":
        raise InputError(
            describe(f"--out (with --export-format {export_format})", str(out), "a .csv file")
        )
    role_map = None if export_map is not None else out.with_suffix(".toml")
    check_outputs({"--out": out, "role map": role_map}, {"--export-map": export_map}, overwrite)


def write_export(
    recording: Recording, export_format: str, out: Path, export_map: Path | None, overwrite: bool
) -> str:
    """Write ``recording`` to ``out`` in the export's layout; return what was written.

    Column names and units come from ``export_map`` (a tag map; only its channels are
    written) or are the channel names in bar(g), l/min (ANR) and mm, and then the role
    map that reads the export back is written beside it (``OUT`` with ``.toml``).
    """
    from pneufdd.files import write_text_atomic
    from pneufdd.recording.field_export import write_field_export
    from pneufdd.recording.tag_map import load_tag_map

    tags = None
    if export_map is not None:
        parsed = load_tag_map(export_map)
        tags = {c.role: (c.column, c.unit) for c in parsed.channels}
        missing = sorted(set(tags) - set(recording.channels))
        if missing:
            raise ChannelError(
                describe(
                    f"--export-map {export_map.name}: roles the run does not have",
                    missing,
                    recording.channels,
                )
            )
    text = write_field_export(recording, out, export_format, tags, overwrite=overwrite)
    if export_map is not None:
        return f"{out} ({export_format}, columns of {export_map.name})"
    role_map = out.with_suffix(".toml")
    write_text_atomic(role_map, text, overwrite=overwrite)
    return f"{out} ({export_format}) and its role map {role_map}"
