"""Feature-matrix builder: recordings -> a (cycles x features) pandas DataFrame.

Each recording is segmented (:func:`pneufdd.signals.segmentation.segment`) against
one sequence - the machine's when given (or stored in the first recording's
metadata), otherwise the one learned from the first recording (the reference), so
that step numbers mean the same in every row. Every
complete cycle becomes a row; rejected cycles are skipped (their reasons are in
``df.attrs["rejected"]``). Columns: the registered features of the chosen groups
(:mod:`pneufdd.features.registry` names), then the labels from each recording's
metadata: ``leak_<location>`` (size, 0 where absent, in the metadata's unit) and
``leak_class`` (the leaking locations joined by ``+``, or ``none``).

A feature that cannot be computed for a cycle is NaN; the first reason per column
is kept in ``df.attrs["nan_reasons"]``. Units are in ``df.attrs["units"]``.

This is a plain function, not a scikit-learn transformer: its input is a list of
recordings, not a numeric array, so the scikit-learn estimator checks do not apply.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from pneufdd.errors import ChannelError, InputError, describe, naming
from pneufdd.features import air, motion, table44, wavelet  # noqa: F401 - registration
from pneufdd.features.context import CycleView, Options, RecordingData
from pneufdd.features.registry import REGISTRY, Feature, Unavailable, column_name
from pneufdd.recording.model import Channel, Recording
from pneufdd.signals.quality import (
    check_carried_description,
    check_channels,
    check_sequence_channels,
    usable_cycles,
)
from pneufdd.signals.segmentation import Segmentation, StepSpec, plc_sequence, segment

__all__ = ["GROUPS", "feature_matrix", "features_of", "labels_of"]

GROUPS = ("motion", "air", "table44", "wavelet")


def features_of(groups: Iterable[str]) -> list[Feature]:
    """Registered features of the named groups, in registration order."""
    chosen = list(groups)
    unknown = sorted(set(chosen) - set(GROUPS))
    if unknown:
        raise InputError(describe("feature groups", unknown, GROUPS))
    return [f for f in REGISTRY.values() if f.group in chosen]


def labels_of(metadata: dict[str, Any]) -> dict[str, float | str]:
    """Leak labels from a recording's metadata ``leaks`` list.

    Examples
    --------
    >>> labels_of({"leaks": [{"location": "DNC_B", "size": 4, "unit": "turns"}]})
    {'leak_DNC_B': 4.0, 'leak_class': 'DNC_B'}
    """
    out: dict[str, float | str] = {}
    leaks = metadata.get("leaks") or []
    if isinstance(leaks, dict):
        leaks = [{"location": k, "size": v} for k, v in leaks.items()]
    for leak in leaks:
        if not isinstance(leak, dict) or "location" not in leak:
            raise InputError(
                describe("metadata 'leaks' entry", leak, "a mapping with 'location' and 'size'")
            )
        size = leak.get("size", np.nan)
        out[f"leak_{leak['location']}"] = float(size) if size is not None else float("nan")
    located = sorted(k[5:] for k, v in out.items() if isinstance(v, float) and v != 0)
    out["leak_class"] = "+".join(located) if located else "none"
    return out


def feature_matrix(
    recordings: Sequence[Recording] | Recording,
    actuators: Sequence[str] = ("DNC",),
    groups: Iterable[str] = GROUPS,
    sequence: Sequence[StepSpec] | None = None,
    options: Options | None = None,
    on_missing: str = "raise",
    names: Sequence[str] | None = None,
) -> pd.DataFrame:
    """Build the (cycles x features) table of one or more recordings.

    Parameters
    ----------
    recordings : Recording or sequence of Recording
        The runs; the first is the reference when ``sequence`` is None.
    actuators : sequence of str
        Actuators for the per-actuator features (default DNC, as in chapters 4-5).
    groups : iterable of str
        Feature families: ``motion`` (section 3.3), ``air`` (eq. 4.17, per step,
        per stroke, minimum supply pressure), ``table44`` (Table 4.4), ``wavelet``
        (section 5.3.3).
    sequence : sequence of StepSpec, optional
        The machine's sequence. When omitted:
        :func:`pneufdd.signals.segmentation.plc_sequence` of the first recording (the
        description it carries, checked first, else learned from its signals).
    options : Options, optional
        Filter cut-off, mother wavelet, validity threshold, detection fractions.
    on_missing : {"raise", "nan"}
        A feature whose channels the recording lacks: raise a ChannelError that
        names them, or give NaN columns (with the reason in ``attrs``).
    names : sequence of str, optional
        The recordings' file names, for messages.

    The analog channels the features use are judged first
    (:func:`pneufdd.signals.quality.check_channels`), then the gap rule applies:
    short gaps are interpolated, cycles touched by longer ones are left out and
    listed in ``attrs["rejected"]`` with the channel (docs/data-quality.md).

    Returns
    -------
    pandas.DataFrame
        Index ``(recording, cycle)``; feature columns, then label columns.
    """
    recs = [recordings] if isinstance(recordings, Recording) else list(recordings)
    if not recs:
        raise InputError(describe("recordings", "none", "at least one Recording"))
    if on_missing not in ("raise", "nan"):
        raise InputError(describe("on_missing", on_missing, ["raise", "nan"]))
    opts = options or Options()
    wavelet.check_wavelet(opts.wavelet)
    feats = features_of(groups)
    if sequence is None:
        first = names[0] if names is not None else "recording 1"
        try:
            check_carried_description(recs[0], first)
            sequence = plc_sequence(recs[0])
        except InputError as exc:
            raise naming(exc, first) from exc
    specs = tuple(sequence)
    rows: list[dict[str, Any]] = []
    index: list[tuple[int, int]] = []
    units: dict[str, str] = {}
    reasons: dict[str, str] = {}
    rejected: list[dict[str, Any]] = []
    for r, rec in enumerate(recs):
        where = names[r] if names is not None else f"recording {r + 1}"
        check_carried_description(rec, where)
        check_sequence_channels(
            rec,
            [name for spec in specs for name, _ in spec.switches],
            [v.removesuffix(":off") for spec in specs for v in spec.valves],
            where,
        )
        try:
            seg = segment(rec, specs)
        except InputError as exc:
            raise naming(exc, where) from exc
        rejected += [{"recording": r, "cycle": c.index, "reason": c.reason} for c in seg.rejected]
        used: set[str] = set()
        plan = _plan(rec, seg, feats, actuators, on_missing, reasons, used)
        analog = [c for c in rec.analog_channels if c in used]
        check_channels(rec, analog, where)
        repaired, gaps = usable_cycles(rec, seg.complete, analog, where)
        rejected += [
            {"recording": r, "cycle": i, "reason": f"data gap in {channel} (gap rule)"}
            for i, channel in gaps.skipped
        ]
        rec = _with_values(rec, repaired)
        data = RecordingData(rec, opts)
        labels = labels_of(rec.metadata)
        cycles = [c for c, ok in zip(seg.complete, gaps.usable, strict=True) if ok]
        for cycle in cycles:
            view = CycleView(data, cycle)
            row: dict[str, Any] = {}
            for feat, target, col in plan:
                units[col] = feat.unit
                if col in reasons and reasons[col].startswith("missing"):
                    row[col] = np.nan
                    continue
                try:
                    row[col] = float(feat.func(view, target))
                except Unavailable as exc:
                    row[col] = np.nan
                    reasons.setdefault(col, str(exc))
            row.update(labels)
            rows.append(row)
            index.append((r, cycle.index))
    df = pd.DataFrame(rows, index=pd.MultiIndex.from_tuples(index, names=["recording", "cycle"]))
    label_cols = sorted(c for c in df.columns if c.startswith("leak_") and c != "leak_class")
    for c in label_cols:
        df[c] = df[c].fillna(0.0)
    feature_cols = [c for c in df.columns if c not in label_cols and c != "leak_class"]
    if "leak_class" in df.columns:
        df = df[[*feature_cols, *label_cols, "leak_class"]]
    df.attrs["units"] = units
    df.attrs["nan_reasons"] = reasons
    df.attrs["rejected"] = rejected
    df.attrs["wavelet"] = opts.wavelet
    return df


def _with_values(rec: Recording, values: dict[str, npt.NDArray[np.float64]]) -> Recording:
    """``rec`` with the samples of some channels replaced (same rates, units, offsets)."""
    channels = []
    for name in rec.channels:
        ch = rec.info(name)
        if name in values:
            ch = Channel(name, values[name], ch.rate_hz, ch.unit, ch.kind, ch.t0)
        channels.append(ch)
    return Recording(channels, rec.start_time, rec.metadata)


def _plan(
    rec: Recording,
    seg: Segmentation,
    feats: list[Feature],
    actuators: Sequence[str],
    on_missing: str,
    reasons: dict[str, str],
    used: set[str],
) -> list[tuple[Feature, Any, str]]:
    steps = range(1, len(seg.sequence) + 1)
    plan: list[tuple[Feature, Any, str]] = []
    for feat in feats:
        targets: Iterable[Any]
        targets = (
            actuators if feat.scope == "actuator" else steps if feat.scope == "step" else [None]
        )
        for target in targets:
            col = column_name(feat, target)
            need = feat.channels(str(target) if feat.scope == "actuator" else None)
            missing = [n for n in need if n not in rec.channels]
            used.update(n for n in need if n in rec.channels)
            if missing:
                if on_missing == "raise":
                    raise ChannelError(
                        f"feature {col!r} needs channel(s) {missing} which the recording "
                        f"lacks; it has: {list(rec.channels)}"
                    )
                reasons.setdefault(col, f"missing channel(s) {missing}")
            plan.append((feat, target, col))
    return plan
