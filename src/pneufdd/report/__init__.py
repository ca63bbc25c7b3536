"""Report: the self-contained HTML leak report and its figures.

May import: :mod:`pneufdd.diagnosis`, :mod:`pneufdd.calibration`,
:mod:`pneufdd.features` and the layers below; not cli.
"""

from __future__ import annotations

from pneufdd.report.html import render_report, write_report

__all__ = ["render_report", "write_report"]
