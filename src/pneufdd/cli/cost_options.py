"""The options every command that prices air shares: eq. 1.1's settings, --json, --report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["HoursOption", "JsonOption", "KwOption", "PriceOption", "ReportOption"]

JsonOption = Annotated[Path | None, typer.Option("--json", help="Write the result as JSON.")]
ReportOption = Annotated[Path | None, typer.Option("--report", help="Write an HTML report.")]
HoursOption = Annotated[float, typer.Option(help="Operating hours per year (eq. 1.1).")]
PriceOption = Annotated[float, typer.Option(help="Electricity price [$/kWh] (eq. 1.1).")]
KwOption = Annotated[
    float, typer.Option("--kw-per-100cfm", help="Compressor kW per 100 cfm (eq. 1.1).")
]
