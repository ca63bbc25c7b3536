"""The commissioning figure: the twin's predicted effect of the test leak against the measured.

One panel per port with a recording: every feature's change in reference standard
deviations, the twin's prediction on the horizontal axis, the measurement on the
vertical one; on the diagonal the twin was right. Both axes are differences, centred on
zero (:func:`~pneufdd.report.axes.difference_range`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pneufdd.diagnosis.commissioning import CommissioningResult
from pneufdd.report.axes import difference_range
from pneufdd.report.figures import save_figure

__all__ = ["commissioning_figure"]

MAX_PANELS = 16
"""Ports drawn (the first ones of the plan) [-]."""


def commissioning_figure(result: CommissioningResult, path: Path) -> Path:
    """Draw the twin's against the measured effect per port and save it to ``path``."""
    import matplotlib.pyplot as plt

    ports = [p for p in result.ports if p.measured.size][:MAX_PANELS]
    n = max(len(ports), 1)
    cols = min(n, 4)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    scale = np.asarray(result.reference.detector.scale_, dtype=np.float64)
    for ax, port in zip(axes.flat, ports, strict=False):
        x = port.predicted / scale
        y = port.measured / scale
        low, high = difference_range(np.concatenate([x, y]).tolist(), [1.0])
        ax.plot([low, high], [low, high], color="0.6", lw=0.8)
        ax.scatter(x, y, s=6, color="C0" if port.status == "corrected" else "C3")
        ax.set_xlim(low, high)
        ax.set_ylim(low, high)
        ax.set_title(f"{port.port} {port.orifice}: {port.status}", fontsize="small")
        ax.set_xlabel("twin [reference SD]", fontsize="x-small")
        ax.set_ylabel("measured [reference SD]", fontsize="x-small")
    for ax in list(axes.flat)[len(ports) :]:
        ax.set_visible(False)
    fig.suptitle(f"test leak effect per feature: {result.reference.machine}", fontsize="medium")
    fig.tight_layout()
    return save_figure(fig, path)
