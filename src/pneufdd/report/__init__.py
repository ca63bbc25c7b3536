"""Report: the self-contained HTML leak report and its figures."""

from __future__ import annotations

from pneufdd.report.html import render_report, write_report, write_text_atomic

__all__ = ["render_report", "write_report", "write_text_atomic"]
