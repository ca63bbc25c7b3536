"""``pneufdd history``: the leaks of a machine over time, from the fault history database."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any

import typer

from pneufdd.cli.exit_codes import ExitCode
from pneufdd.errors import InputError, describe

__all__ = ["parse_since", "register"]


def parse_since(text: str | None) -> float | None:
    """``--since``: an ISO date/time (UTC when no zone) -> seconds since 1970-01-01 UTC.

    Examples
    --------
    >>> parse_since("1970-01-02")
    86400.0
    """
    if text is None:
        return None
    try:
        when = datetime.fromisoformat(text)
    except ValueError as exc:
        raise InputError(describe("--since", text, "an ISO date or time, e.g. 2026-11-24")) from exc
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    return when.timestamp()


def _iso(t: float | None) -> str | None:
    return None if t is None else datetime.fromtimestamp(t, UTC).isoformat()


def history_command(
    history: Annotated[
        str, typer.Option(help="SQLAlchemy URL of the fault history.")
    ] = "sqlite:///pneufdd-history.db",
    machine: Annotated[str | None, typer.Option(help="Only this machine.")] = None,
    since: Annotated[str | None, typer.Option(help="Only from this ISO date/time on.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
    figure: Annotated[
        Path | None,
        typer.Option(help="Draw leak size and cost over time into this file (PNG/SVG/PDF)."),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing figure.")
    ] = False,
    repaired: Annotated[
        str | None,
        typer.Option(help="Mark the active leak at this location repaired (needs --machine)."),
    ] = None,
) -> None:
    """Print the leaks with first-seen time, size trend and cost to date; draw them (--figure)."""
    from rich.console import Console
    from rich.table import Table

    from pneufdd.cli.outputs import check_outputs
    from pneufdd.monitor.database import HistoryDatabase, masked_url, sqlite_path

    start = parse_since(since)
    url = history
    database = sqlite_path(url)
    if database is not None and not database.exists():
        raise InputError(describe("--history", masked_url(url), "an existing history database"))
    # before anything is read: the figure never lands on the database (links included)
    check_outputs({"--figure": figure}, {"--history": database}, overwrite=overwrite)
    db = HistoryDatabase(url)
    try:
        if repaired is not None:
            if machine is None:
                raise InputError(describe("--machine", None, "the machine of --repaired"))
            count = db.mark_repaired(machine, repaired, datetime.now(UTC).timestamp())
            typer.echo(f"marked {count} leak(s) at {repaired} repaired")
        known = db.machines()
        if machine is not None and machine not in [n for _, n in known]:
            raise InputError(describe("--machine", machine, [n for _, n in known]))
        report: list[dict[str, Any]] = []
        for machine_id, name in known:
            if machine is not None and name != machine:
                continue
            span = db.cycle_span(machine_id, start)
            leaks = []
            for row in db.leak_rows(machine_id):
                if start is not None and row.last_seen < start:
                    continue
                sizes = db.leak_sizes(row.id)
                leaks.append(
                    {
                        "location": row.location,
                        "state": row.state,
                        "first_seen": _iso(row.first_seen),
                        "last_seen": _iso(row.last_seen),
                        "repaired_at": _iso(row.repaired_at),
                        "flow_slpm": row.flow_slpm,
                        "annual_cost": row.annual_cost,
                        "confidence": row.confidence,
                        "cost_to_date": row.cost_to_date,
                        "sizes": [
                            {"time": _iso(t), "flow_slpm": f, "annual_cost": c} for t, f, c in sizes
                        ],
                    }
                )
            report.append(
                {
                    "machine": name,
                    "cycles": {
                        "count": db.cycle_count(machine_id, start),
                        "first": None if span is None else _iso(span[0]),
                        "last": None if span is None else _iso(span[1]),
                    },
                    "alarms": db.alarm_rows(machine_id, start),
                    "leaks": leaks,
                    "gaps": [
                        {**g, "start": _iso(g["start"]), "end": _iso(g["end"])}
                        for g in db.gap_rows(machine_id, start)
                    ],
                    "undelivered_alarms": db.undelivered_counts(machine_id),
                }
            )
    finally:
        db.close()
    if as_json:
        typer.echo(json.dumps({"machines": report}, indent=2, allow_nan=False))
    else:
        from rich.markup import escape

        out = Console(highlight=False)
        for entry in report:
            cyc = entry["cycles"]
            gaps = entry["gaps"]
            out.print(
                f"[bold]{escape(entry['machine'])}[/]: {cyc['count']} cycles "
                f"({cyc['first']} .. {cyc['last']}), {len(entry['alarms'])} alarms, "
                f"{len(gaps)} gaps ({sum(g['cycles_lost'] for g in gaps)} cycles lost)"
            )
            for output, count in entry["undelivered_alarms"].items():
                out.print(
                    f"  {count} alarm(s) not yet delivered to {output} (the monitor delivers "
                    "them when it runs and the output works)",
                    markup=False,
                )
            for gap in gaps:
                out.print(
                    f"  gap {gap['start']} .. {gap['end']}: {gap['cycles_lost']} cycle(s) "
                    f"lost, source {gap['source']}",
                    markup=False,
                )
            table = Table()
            for col in ("location", "state", "first seen", "size trend [SLPM]", "cost to date [$]"):
                table.add_column(col)
            for leak in entry["leaks"]:
                trend = " -> ".join(
                    f"{s['flow_slpm']:.1f}" for s in leak["sizes"] if s["flow_slpm"] is not None
                )
                table.add_row(
                    escape(leak["location"]),
                    escape(leak["state"]),
                    str(leak["first_seen"]),
                    trend or "-",
                    f"{leak['cost_to_date']:.2f}",
                )
            out.print(table)
    if figure is not None:
        from pneufdd.report.history_figure import history_figure

        history_figure(report, figure)
        if not as_json:
            typer.echo(f"wrote {figure}")
    raise typer.Exit(ExitCode.OK)


def register(app: typer.Typer) -> None:
    """Attach ``history`` to ``app``."""
    app.command("history")(history_command)
