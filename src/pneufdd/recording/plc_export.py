"""Write a recording as a plant's DAQ/PLC export would be: PLC tags, gauge bar, l/min.

A real plant's export names its columns after PLC tags (``Y1.0`` for an output,
``B1.4`` for an input), gives pressures in bar(g), flows in l/min on some standard and
positions in mm, on one time column, with no metadata. :func:`write_plc_csv` turns a
(simulated) recording into such a CSV and writes the tag map (``docs/recording.md``)
that reads it back; the end-to-end tests and the acceptance runs use it to play the
plant engineer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pneufdd.errors import FileExistsInputError, describe
from pneufdd.physics.units import kg_s_to_l_min_anr, pa_to_bar_gauge
from pneufdd.recording.model import Recording

__all__ = ["plc_tags", "write_plc_csv"]


def plc_tags(recording: Recording) -> dict[str, str]:
    """A PLC-style tag for every channel: outputs ``Y<n>.<bit>``, inputs ``B<n>.<bit>``,
    analog sensors ``B_P<n>``, ``B_F<n>``, ``B_X<n>``.

    Examples
    --------
    >>> from pneufdd.recording import Recording
    >>> rec = Recording.from_arrays(
    ...     {"P_In": [6e5, 6e5]}, 1000.0, {"U_A_A": [0, 1]}, 1000.0, units={"P_In": "Pa"}
    ... )
    >>> plc_tags(rec)
    {'P_In': 'B_P1', 'U_A_A': 'Y1.0'}
    """
    tags: dict[str, str] = {}
    counts = {"U": 0, "S": 0, "P": 0, "Q": 0, "X": 0}
    for name in recording.channels:
        kind = name[0]
        n = counts[kind]
        counts[kind] += 1
        if kind == "U":
            tags[name] = f"Y{1 + n // 8}.{n % 8}"
        elif kind == "S":
            tags[name] = f"B{1 + n // 8}.{n % 8}"
        else:
            tags[name] = f"B_{'F' if kind == 'Q' else kind}{n + 1}"
    return tags


def write_plc_csv(
    recording: Recording, csv_path: str | Path, map_path: str | Path, overwrite: bool = False
) -> dict[str, str]:
    """Write ``recording`` as a PLC-tagged CSV and the tag map that imports it.

    Parameters
    ----------
    recording : Recording
        Channels ``P_*`` [Pa], ``Q_*`` [kg/s], ``X_*`` [m], ``U_*``/``S_*`` (0/1).
    csv_path : str or Path
        CSV to write: time column ``t`` [s] at the fastest rate (slower channels
        sample-and-hold), pressures in bar(g), flows in l/min (ANR), positions in mm.
    map_path : str or Path
        Tag map (TOML) to write.
    overwrite : bool
        Replace existing files.

    Returns
    -------
    dict of str to str
        Channel -> tag.
    """
    csv_path, map_path = Path(csv_path), Path(map_path)
    for path in (csv_path, map_path):
        if path.exists() and not overwrite:
            raise FileExistsInputError(describe("output", str(path), "a new file (or overwrite)"))
    tags = plc_tags(recording)
    frame = recording.to_pandas()
    lines = ["[columns]", '"t" = { role = "time", unit = "s" }']
    out = {"t": np.round(frame.index.to_numpy() - frame.index[0], 6)}
    for name, tag in tags.items():
        values = frame[name].to_numpy()
        if name[0] in "US":
            out[tag] = np.nan_to_num(values).astype(np.int64)
            lines.append(f'"{tag}" = {{ role = "{name}" }}')
        elif name[0] == "P":
            out[tag] = np.round(pa_to_bar_gauge(values), 5)
            lines.append(f'"{tag}" = {{ role = "{name}", unit = "bar(g)" }}')
        elif name[0] == "Q":
            out[tag] = np.round(kg_s_to_l_min_anr(values), 4)
            lines.append(f'"{tag}" = {{ role = "{name}", unit = "l/min", basis = "ANR" }}')
        else:
            out[tag] = np.round(values * 1e3, 4)
            lines.append(f'"{tag}" = {{ role = "{name}", unit = "mm" }}')
    import pandas as pd

    pd.DataFrame(out).to_csv(csv_path, index=False)
    map_path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return tags
