"""``pneufdd monitor``: watch a running machine (OPC UA, MQTT or a replay) and keep its history.

Exit codes: 0 the run judged cycles and ended without an active leak, 1 a leak was
declared and is still active at the end, 2 bad input, and also a run that judged no
cycle at all (no complete cycle, every one skipped for lost samples, or only start-up
cycles): it says nothing about leaks, and says so.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

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
        bool,
        typer.Option("--once", help="Process the source to its end and exit (replays, tests)."),
    ] = False,
    alarm_log: Annotated[
        Path | None,
        typer.Option(
            help="JSON-lines file every alarm is appended to (default: beside a SQLite"
            " history, <history>-alarms.jsonl; none for other databases)."
        ),
    ] = None,
    webhook: Annotated[
        str | None, typer.Option(help="http(s) URL every alarm is POSTed to as JSON.")
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
    verbose: Annotated[bool, typer.Option("--verbose", help="Print every cycle's score.")] = False,
    publish: Annotated[
        list[str] | None,
        typer.Option(
            help="Publish each machine's state: opcua://host:port?users=FILE (OPC UA server,"
            " Basic256Sha256 SignAndEncrypt) or mqtt://broker/topic (retained JSON);"
            " repeatable (docs/monitor.md, Publishing)."
        ),
    ] = None,
    metrics_port: Annotated[
        int | None,
        typer.Option(min=1, max=65535, help="Serve Prometheus /metrics on 127.0.0.1:PORT."),
    ] = None,
) -> None:
    """Watch a machine: score every cycle, declare leaks sequentially, record the history."""
    from rich.console import Console

    from pneufdd.diagnosis.reference.file import load_reference
    from pneufdd.monitor.alarms import AlarmSinks, check_webhook
    from pneufdd.monitor.cycles import needed_channels
    from pneufdd.monitor.database import masked_url, open_history, sqlite_path
    from pneufdd.monitor.live import MachineMonitor
    from pneufdd.monitor.sequential import check_arl0
    from pneufdd.monitor.sources import open_source
    from pneufdd.monitor.stream import run_stream

    check_arl0(arl0)  # every option is checked before the history is created
    if alarm_log is None:  # beside the history, never silently into the working folder
        database = sqlite_path(history)
        if database is not None:
            alarm_log = database.with_name(f"{database.stem}-alarms.jsonl")
    _check_outputs(reference, source, tags, history, alarm_log)
    if webhook is not None:
        check_webhook(webhook)  # before any work: a bad URL never waits for the first alarm
    # names and values in messages are plain text (a machine named "cell[/]" is no markup)
    err = Console(stderr=True, highlight=False, markup=False)
    if not verbose:  # asyncua's own tracebacks of a lost server: the monitor says it in a line
        logging.getLogger("asyncua").addHandler(logging.NullHandler())
    model = load_reference(reference)
    analog, digital = needed_channels(model)
    src = open_source(source, analog, digital, tags, log=lambda m: err.print(m))
    # the publishers before the history: a refused --publish leaves no database behind
    publishers = _publishers(publish or [], metrics_port, lambda m: err.print(f"warning: {m}"))
    try:
        db = open_history(history)
        db.check_writable()  # a read-only history fails now, not at the first cycle
    except BaseException:
        publishers.close()
        raise
    sinks = AlarmSinks(
        echo=lambda m: typer.echo(m),
        log_path=alarm_log,
        webhook=webhook,
        warn=lambda m: err.print(f"warning: {m}"),
    )
    mon = MachineMonitor(
        model, db, machine, arl0=arl0, alarm=sinks, source=masked_url(source), publish=publishers
    )
    _store_machine_info(mon)
    err.print(
        f"monitoring {mon.machine}: CUSUM threshold {mon.cusum.decision_threshold:.2f} "
        f"(ARL0 {arl0:.3g} cycles, rho {mon.cusum.rho:.2f}); history {masked_url(history)}; "
        f"alarm log {alarm_log if alarm_log is not None else 'none (--alarm-log PATH)'}"
    )

    show = _show(err, mon, sinks, verbose)

    try:
        stats = run_stream(
            mon,
            src,
            src.rates_hz,
            src.lateness_s,
            on_cycle=show,
            max_cycles=max_cycles,
            flush=once,
            losses=getattr(src, "losses", None),
            say=lambda m: err.print(m),
        )
        if not once and (max_cycles is None or stats.cycles < max_cycles):
            err.print("the source ended; waiting for more (Ctrl-C stops; --once exits here)")
            while True:
                time.sleep(3600)
    except KeyboardInterrupt:
        stats = mon.stats
        err.print("stopped")
        if mon.busy:
            mon.worker.abandon()
            err.print("an estimate was running: it runs again at the next start")
    finally:
        publishers.close()
        held = sinks.retry(force=True)
        mon.worker.close()
        db.close()
    raise typer.Exit(_finish(err, mon, src, stats, held))


def _show(err: Any, mon: Any, sinks: Any, verbose: bool) -> Callable[[Any], None]:
    """What is said live about each cycle (and the alarm outputs' due retries)."""

    def show(outcome: Any) -> None:
        sinks.retry()  # alarms held by a failing output, when their retry is due
        if outcome.declared:
            err.print(
                f"cycle at {outcome.start:.3f}: leak declared (CUSUM {outcome.cusum:.2f} >= "
                f"{mon.cusum.decision_threshold:.2f}); locating and sizing beside the "
                "ingestion, the alarm follows"
            )
        if outcome.incomplete:
            shares = ", ".join(f"{c} {100 * s:.0f} % of samples" for c, s in outcome.incomplete)
            err.print(
                f"cycle {mon.stats.cycles} at {outcome.start:.3f} skipped: {shares} "
                "(the source lost samples; not scored)"
            )
        if outcome.cycles_lost:
            err.print(
                f"gap: {outcome.gap_s:.1f} s without a cycle before the cycle at "
                f"{outcome.start:.3f}, about {outcome.cycles_lost} cycle(s) lost (recorded)"
            )
        if verbose and outcome.recorded:
            err.print(
                f"cycle {outcome.start:.3f}: score {outcome.score:.3f} CUSUM {outcome.cusum:.2f}"
            )

    return show


def _finish(err: Any, mon: Any, src: Any, stats: Any, held: int) -> ExitCode:
    """Print the notes and the summary; the exit code.

    1 while a leak is active; 2 when no cycle was judged, now or by an earlier run
    (already recorded): such a run says nothing about leaks, and says so; else 0.
    """
    if held:
        err.print(
            f"warning: {held} alarm delivery(ies) still held (their outputs fail; see above); "
            "they are kept in the history and delivered at the next start"
        )
    notes = getattr(src, "notes", None)
    for note in [*stats.notes, *(notes() if notes is not None else [])]:
        err.print(f"note: {note}")
    summary = _summary(stats, mon.state.in_alarm)
    clocks = getattr(src, "clocks", None)
    if clocks is not None and clocks.to_dict():
        summary["clock_offsets"] = clocks.to_dict()
    err.print(json.dumps(summary))
    if mon.state.in_alarm:
        return ExitCode.LEAK_FOUND
    if stats.judged + stats.skipped == 0:
        err.print(  # an exit 2 says "error:" (its history keeps what was recorded)
            f"error: no cycle was judged ({stats.cycles} complete cycle(s): "
            f"{stats.startup} start-up, {stats.incomplete} skipped for lost samples; see the "
            "notes above): this run says nothing about leaks"
        )
        return ExitCode.INPUT_ERROR
    return ExitCode.OK


def _summary(stats: Any, leak_active: bool) -> dict[str, Any]:
    """The run's last line (JSON)."""
    return {
        "cycles": stats.cycles,
        "recorded": stats.recorded,
        "already_recorded": stats.skipped,
        "judged": stats.judged,
        "startup": stats.startup,
        "alarms": stats.alarms,
        "diagnoses": stats.diagnoses,
        "gaps": stats.gaps,
        "cycles_lost": stats.cycles_lost,
        "incomplete_skipped": stats.incomplete,
        "seconds": round(stats.seconds, 3),
        "leak_active": leak_active,
    }


def _publishers(urls: list[str], metrics_port: int | None, warn: Callable[[str], None]) -> Any:
    """The publish hook: OPC UA servers, MQTT publishers, the metrics endpoint."""
    from pneufdd.errors import InputError, describe
    from pneufdd.monitor.publish import Publisher, Publishers

    made: list[Publisher] = []
    try:
        for url in urls:
            if url.startswith("opcua://"):
                from pneufdd.monitor.publish_opcua import OpcUaPublisher

                made.append(OpcUaPublisher(url, warn))
            elif url.startswith(("mqtt://", "mqtts://")):
                from pneufdd.monitor.publish_mqtt import MqttPublisher

                made.append(MqttPublisher(url, warn))
            else:
                raise InputError(
                    describe("--publish", url, ["opcua://...", "mqtt://...", "mqtts://..."])
                )
        if metrics_port is not None:
            from pneufdd.monitor.metrics import MonitorMetrics

            metrics = MonitorMetrics()
            metrics.serve(metrics_port)
            made.append(metrics)
    except BaseException:
        Publishers(made, warn).close()
        raise
    return Publishers(made, warn)


def _store_machine_info(mon: Any) -> None:
    """What the dashboard draws from: description, thresholds, step names (schema 3)."""
    import time as clock

    from pneufdd.monitor.fleet import save_machine_info
    from pneufdd.report.steps import step_labels

    model = mon.model
    description = model.description
    names = [s.name for s in description.steps] if description is not None else []
    save_machine_info(
        mon.history,
        mon.machine_id,
        clock.time(),
        model.machine_description,
        mon.cusum.decision_threshold,
        float(mon.detector.threshold_),
        step_labels(model.sequence, names, model.n_steps),
    )


def _check_outputs(
    reference: Path, source: str, tags: Path | None, history: str, alarm_log: Path | None
) -> None:
    """Refuse at start an alarm log or history database that would harm an input or fail.

    The alarm log and a SQLite history (with its journal files) are outputs: never the
    reference, the replayed recording or the tag map (resolved through links), never
    each other, never a folder, and in a place this user may write.
    """
    from pneufdd.cli.outputs import (
        check_appended,
        check_outputs,
        check_writable,
        database_files,
    )

    replay = source[len("replay:") :].partition("?")[0] if source.startswith("replay:") else None
    inputs = {"--reference": reference, "--source": replay, "--tags": tags}
    database = database_files(history)
    outputs: dict[str, str | Path | None] = {"--alarm-log": alarm_log}
    outputs.update({f"--history ({path.name})": path for path in database[1:]})
    outputs["--history"] = database[0] if database else None
    check_outputs(outputs, inputs, overwrite=True)  # both are appended to, never replaced
    for option, path in outputs.items():  # appended to: never through a dangling link
        if path is not None:
            check_appended(option, path)
    if alarm_log is not None:
        check_writable("--alarm-log", alarm_log)
    if database:
        check_writable("--history", database[0])


def register(app: typer.Typer) -> None:
    """Attach ``monitor`` to ``app``."""
    app.command("monitor")(monitor_command)
