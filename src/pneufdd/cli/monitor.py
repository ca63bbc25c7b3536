"""``pneufdd monitor``: watch a running machine (OPC UA, MQTT or a replay) and keep its history.

Exit codes: 0 the run ended without an active leak, 1 a leak was declared and is still
active at the end (``--once``), 2 bad input.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated

import typer

from pneufdd.cli.exit_codes import ExitCode

__all__ = ["register"]


def monitor_command(
    reference: Annotated[Path, typer.Option(help="The machine's leak-free reference (.pnref).")],
    source: Annotated[
        str,
        typer.Option(
            help="opcua://host:port/path, mqtt://host:port/topic or replay:run.parquet[?speed=10]"
            " (speed=max: as fast as possible)."
        ),
    ],
    tags: Annotated[
        Path | None, typer.Option(help="Tag map (TOML): channel -> OPC UA node and grid rate.")
    ] = None,
    history: Annotated[
        str, typer.Option(help="SQLAlchemy URL of the fault history.")
    ] = "sqlite:///pneufdd-history.db",
    machine: Annotated[
        str | None, typer.Option(help="Machine name in the history (default: the reference's).")
    ] = None,
    once: Annotated[
        bool, typer.Option(help="Process the source to its end and exit (replays, tests).")
    ] = False,
    alarm_log: Annotated[
        Path, typer.Option(help="JSON-lines file every alarm is appended to.")
    ] = Path("pneufdd-alarms.jsonl"),
    webhook: Annotated[
        str | None, typer.Option(help="URL every alarm is POSTed to as JSON.")
    ] = None,
    arl0: Annotated[
        float,
        typer.Option(
            help="In-control average run length of the CUSUM: cycles between false alarms."
        ),
    ] = 1.0e6,
    max_cycles: Annotated[
        int | None, typer.Option(min=1, help="Stop after this many cycles.")
    ] = None,
    verbose: Annotated[bool, typer.Option(help="Print every cycle's score.")] = False,
) -> None:
    """Watch a machine: score every cycle, declare leaks sequentially, record the history."""
    from rich.console import Console

    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor.alarms import AlarmSinks
    from pneufdd.monitor.cycles import needed_channels
    from pneufdd.monitor.database import open_history
    from pneufdd.monitor.live import CycleOutcome, MachineMonitor, run_stream
    from pneufdd.monitor.sources import open_source

    err = Console(stderr=True, highlight=False)
    model = load_reference(reference)
    analog, digital = needed_channels(model)
    src = open_source(source, analog, digital, tags, log=lambda m: err.print(m))
    db = open_history(history)
    db.check_writable()  # a read-only history fails now, not at the first cycle
    sinks = AlarmSinks(
        echo=lambda m: typer.echo(m),
        log_path=alarm_log,
        webhook=webhook,
        warn=lambda m: err.print(f"warning: {m}"),
    )
    mon = MachineMonitor(model, db, machine, arl0=arl0, alarm=sinks)
    err.print(
        f"monitoring {mon.machine}: CUSUM threshold {mon.cusum.decision_threshold:.2f} "
        f"(ARL0 {arl0:.3g} cycles, rho {mon.cusum.rho:.2f}); history {history}"
    )

    def show(outcome: CycleOutcome) -> None:
        if verbose and outcome.recorded:
            err.print(
                f"cycle {outcome.start:.3f}: score {outcome.score:.3f} CUSUM {outcome.cusum:.2f}"
            )

    try:
        stats = run_stream(
            mon,
            src,
            src.rates_hz,
            src.lateness_s,
            on_cycle=show,
            max_cycles=max_cycles,
            flush=once,
        )
        if not once and (max_cycles is None or stats.cycles < max_cycles):
            err.print("the source ended; waiting for more (Ctrl-C stops; --once exits here)")
            while True:
                time.sleep(3600)
    except KeyboardInterrupt:
        stats = mon.stats
        err.print("stopped")
    finally:
        db.close()
    for note in stats.notes:
        err.print(f"note: {note}")
    summary = {
        "cycles": stats.cycles,
        "recorded": stats.recorded,
        "already_recorded": stats.skipped,
        "alarms": stats.alarms,
        "diagnoses": stats.diagnoses,
        "seconds": round(stats.seconds, 3),
        "leak_active": mon.state.in_alarm,
    }
    err.print(json.dumps(summary))
    raise typer.Exit(ExitCode.LEAK_FOUND if mon.state.in_alarm else ExitCode.OK)


def register(app: typer.Typer) -> None:
    """Attach ``monitor`` to ``app``."""
    app.command("monitor")(monitor_command)
