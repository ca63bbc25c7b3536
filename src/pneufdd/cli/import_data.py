"""``pneufdd import``: a CSV/TDMS/Parquet export under PLC tag names -> a pneufdd recording."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]


def import_data(
    data: Annotated[Path, typer.Argument(help="Export to import (.csv, .tdms or .parquet).")],
    tag_map: Annotated[
        Path,
        typer.Option("--map", help="Tag map (.toml): each column's role, unit and flow basis."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Recording to write (.parquet).")],
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing OUT.")
    ] = False,
    export_format: Annotated[
        str | None,
        typer.Option(
            "--format",
            help="Layout of a CSV export: twincat-scope, tia-trace, codesys-trace or csv-de "
            "(the map then needs only the roles; its own options win). TDMS and Parquet "
            "are read as they are.",
        ),
    ] = None,
) -> None:
    """Read DATA through the tag map and write it as a pneufdd recording (SI units)."""
    from rich.console import Console

    from pneufdd.cli.outputs import check_outputs
    from pneufdd.recording.tag_map import load_tag_map, read_mapped

    check_outputs({"--out": out}, {"DATA": data, "--map": tag_map}, overwrite)
    recording = read_mapped(data, load_tag_map(tag_map, preset=export_format))
    out.parent.mkdir(parents=True, exist_ok=True)  # as every output (cli/outputs.py)
    recording.write(out, overwrite=overwrite)
    rates = sorted({recording.rate(c) for c in recording.channels})
    Console(stderr=True).print(
        f"wrote {out}: {len(recording.analog_channels)} analog, "
        f"{len(recording.digital_channels)} digital channels, "
        f"{recording.duration:.3f} s at {', '.join(f'{r:g}' for r in rates)} Hz, "
        f"starting {recording.start_time.isoformat()}",
        highlight=False,
        markup=False,
        soft_wrap=True,
    )
    for switch, how in (recording.metadata.get("derived_switches") or {}).items():
        on, off = 1e3 * how["on_m"], 1e3 * how["off_m"]
        Console(stderr=True).print(
            f"{switch} derived from {how['position']} ({how['rule']}): on at "
            f"{on:.3f} mm, off at {off:.3f} mm",
            highlight=False,
            markup=False,
            soft_wrap=True,
        )


def register(app: typer.Typer) -> None:
    """Attach the ``import`` command to ``app``."""
    app.command("import")(import_data)
