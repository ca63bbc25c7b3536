"""Issue 39, items 1 and 4: the monitor's outputs are checked at start and never stop it.

The alarm log and the history database are refused at start (exit 2, nothing read or
written) when they would destroy an input or cannot be written; a webhook that is not
http(s) is refused at start; an output that fails while running is reported, its
alarms held and sent again once it works, and the monitor runs on.
"""

from __future__ import annotations

import json
import os
import threading
import typing
from http.server import BaseHTTPRequestHandler, HTTPServer

import pytest

from monitor_data import leak_run, reference
from pneufdd.cli.app import main
from pneufdd.diagnosis.reference.file import save_reference
from pneufdd.errors import InputError
from pneufdd.monitor.alarms import Alarm, AlarmSinks, check_webhook


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("monitor-outputs")
    ref = save_reference(reference(), folder / "ref.pnref")
    run = leak_run().write(folder / "run.parquet")
    return {"ref": ref, "run": run, "folder": folder}


def _monitor(files, *extra: str) -> int:
    args = ["monitor", "--reference", str(files["ref"]), "--once"]
    args += ["--source", f"replay:{files['run']}?speed=max", *extra]
    return main(args)


def _snapshot(files) -> dict[str, bytes]:
    return {k: files[k].read_bytes() for k in ("ref", "run")}


class _Flaky(BaseHTTPRequestHandler):
    """A webhook that answers 503 to its first ``fail`` requests, then 204."""

    fail: typing.ClassVar[int] = 0
    calls: typing.ClassVar[int] = 0
    received: typing.ClassVar[list[dict]] = []

    def do_POST(self) -> None:
        body = self.rfile.read(int(self.headers["Content-Length"]))
        _Flaky.calls += 1
        if _Flaky.calls <= _Flaky.fail:
            self.send_response(503)
        else:
            _Flaky.received.append(json.loads(body))
            self.send_response(204)
        self.end_headers()

    def log_message(self, *args: object) -> None:
        return None


@pytest.fixture
def flaky():
    _Flaky.fail, _Flaky.calls, _Flaky.received = 0, 0, []
    server = HTTPServer(("127.0.0.1", 0), _Flaky)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_port}/alarm"
    server.shutdown()
    server.server_close()
    thread.join()


@pytest.mark.parametrize(
    ("target", "culprit"),
    [("run", "--source"), ("ref", "--reference"), ("soft", "--source"), ("hard", "--reference")],
)
def test_an_alarm_log_onto_an_input_is_refused_at_start(files, tmp_path, capsys, target, culprit):
    links = {"soft": tmp_path / "soft.jsonl", "hard": tmp_path / "hard.jsonl"}
    links["soft"].symlink_to(files["run"])
    os.link(files["ref"], links["hard"])
    path = links.get(target, files.get(target))
    before = _snapshot(files)
    db = tmp_path / "h.db"
    assert _monitor(files, "--alarm-log", str(path), "--history", f"sqlite:///{db}") == 2
    err = capsys.readouterr().err
    assert f"--alarm-log: received {str(path)!r}" in err
    assert f"not one of this command's inputs (it is {culprit})" in err
    assert "monitoring" not in err  # refused before any work
    assert _snapshot(files) == before
    assert not db.exists()


def test_a_history_database_onto_an_input_or_the_alarm_log_is_refused(files, tmp_path, capsys):
    before = _snapshot(files)
    log = tmp_path / "alarms.jsonl"
    for url, expected in [
        (f"sqlite:///{files['run']}", "--history: received"),
        (f"sqlite:///{files['ref']}", "it is --reference"),
        (f"sqlite:///{log}", "--alarm-log writes there"),
    ]:
        assert _monitor(files, "--alarm-log", str(log), "--history", url) == 2
        assert expected in capsys.readouterr().err
    assert _snapshot(files) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("option", ["--history", "--alarm-log"])
def test_an_appended_output_on_a_dangling_link_is_refused(files, tmp_path, capsys, option):
    """The history and the alarm log are appended to: on a link that leads nowhere the
    monitor created the database where the link pointed (outside what was named)."""
    (tmp_path / "h.db").symlink_to("elsewhere.db")
    (tmp_path / "a.jsonl").symlink_to("elsewhere.jsonl")
    db = "h.db" if option == "--history" else "fresh.db"
    log = "a.jsonl" if option == "--alarm-log" else "fresh.jsonl"
    argv = ["--history", f"sqlite:///{tmp_path / db}", "--alarm-log", str(tmp_path / log)]
    assert _monitor(files, *argv) == 2
    assert f"error: {option}: received" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.jsonl", "h.db"]  # links only


def test_an_alarm_log_that_cannot_be_written_is_refused_at_start(files, tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    for path, allowed in [
        (tmp_path, "a file path (this is a folder)"),
        (tmp_path / "file" / "alarms.jsonl", "is a file"),
        ("/proc/pneufdd-alarms.jsonl", "a file this user may write"),
    ]:
        db = tmp_path / "h.db"
        assert _monitor(files, "--alarm-log", str(path), "--history", f"sqlite:///{db}") == 2
        err = capsys.readouterr().err
        assert f"--alarm-log: received {str(path)!r}" in err
        assert allowed in err
        assert not db.exists()


@pytest.mark.parametrize(
    "url",
    ["notaurl", "file:///etc/passwd", "ftp://host/x", "http://", "http://h:99999/", "http://a b/"],
)
def test_a_webhook_that_is_not_http_is_refused_at_start(files, tmp_path, capsys, url):
    db = tmp_path / "h.db"
    assert _monitor(files, "--webhook", url, "--history", f"sqlite:///{db}") == 2
    err = capsys.readouterr().err
    assert f"--webhook: received {url!r}; allowed: an http:// or https:// URL" in err
    assert not db.exists()
    with pytest.raises(InputError, match="--webhook"):
        AlarmSinks(webhook=url)


@pytest.mark.parametrize("url", ["=", "ftp://broker/x", "mqtt://broker/"])
def test_a_refused_publish_url_leaves_no_history_behind(files, tmp_path, capsys, url):
    # found by make fuzz (seed 97,000,310): the history database was created before
    # --publish was checked, so an exit 2 left an empty h.db behind
    db = tmp_path / "h.db"
    assert _monitor(files, "--publish", url, "--history", f"sqlite:///{db}") == 2
    assert "--publish" in capsys.readouterr().err
    assert not db.exists()


def test_check_webhook_accepts_http_and_https():
    for url in ("http://127.0.0.1:8080/a", "HTTPS://alarms.example.com/x?y=1"):
        assert check_webhook(url) == url


def _alarm(k: int) -> Alarm:
    return Alarm("cell[/]", 1.0e9 + k, "leak", ("supply",), 40.0, 66.0, 0.9)


def test_a_webhook_that_fails_then_recovers_gets_every_alarm_in_order(flaky):
    _Flaky.fail = 3
    warnings: list[str] = []
    sinks = AlarmSinks(webhook=flaky, warn=warnings.append, retry_after_s=3600.0)
    sinks(_alarm(0))  # 503
    assert sinks.pending == 1
    assert sinks.retry() == 1  # not due yet: no request
    assert _Flaky.calls == 1
    sinks(_alarm(1))  # a new alarm retries the held one first: 503 again
    assert sinks.pending == 2
    assert sinks.retry(force=True) == 2  # 503, the third failure
    assert sinks.retry(force=True) == 0  # the server is back: both, oldest first
    assert [a["timestamp"] for a in _Flaky.received] == [1.0e9, 1.0e9 + 1]
    assert sum("webhook failed" in w and "503" in w for w in warnings) == 3
    assert warnings[-1] == "webhook works again: 2 held alarm(s) delivered"


def test_an_alarm_log_that_fails_at_run_time_is_retried(tmp_path):
    blocker = tmp_path / "logs"
    blocker.write_text("a file where the log's folder should be")
    log = blocker / "alarms.jsonl"
    warnings: list[str] = []
    sinks = AlarmSinks(log_path=log, warn=warnings.append)
    sinks(_alarm(0))  # cannot be written: reported, held, no exception
    assert sinks.pending == 1
    assert "alarm log failed" in warnings[0]
    blocker.unlink()
    assert sinks.retry(force=True) == 0
    assert [json.loads(x)["timestamp"] for x in log.read_text().splitlines()] == [1.0e9]


def test_the_monitor_runs_on_through_a_failing_webhook(files, tmp_path, capsys, flaky):
    _Flaky.fail = 1  # the first POST fails; the retry at the end of the run gets through
    log, db = tmp_path / "alarms.jsonl", tmp_path / "h.db"
    args = ["--webhook", flaky, "--alarm-log", str(log), "--history", f"sqlite:///{db}"]
    assert _monitor(files, *args) == 1  # a leak, still active: not 3
    err = capsys.readouterr().err
    summary = json.loads(err[err.rindex('{"cycles"') :].replace("\n", " "))
    assert summary["cycles"] >= 5  # every cycle of the run processed, after the failure too
    assert summary["recorded"] == summary["cycles"]
    assert summary["alarms"] >= 1
    assert "warning: webhook failed" in err
    assert "503" in err
    assert "webhook works again" in err
    assert len(_Flaky.received) == summary["alarms"]
    assert len(log.read_text().splitlines()) == summary["alarms"]


class _Killed(BaseException):
    """The process dies here."""


def test_an_alarm_committed_but_not_delivered_when_killed_is_delivered_at_the_next_start(
    files, tmp_path, monkeypatch
):
    """Issue 32: the alarm outbox. The monitor dies between an alarm's commit and its
    delivery to the alarm log: the alarm is in the history, queued for the log, the log
    has nothing. The next start delivers it (oldest first) before anything else, marks
    it delivered, and a replay fed again delivers nothing twice."""
    import math

    from pneufdd.monitor.database import HistoryDatabase
    from pneufdd.monitor.live import MachineMonitor
    from pneufdd.monitor.sources import ReplaySource
    from pneufdd.monitor.stream import run_stream

    url = f"sqlite:///{tmp_path / 'h.db'}"
    log = tmp_path / "alarms.jsonl"
    monkeypatch.setattr(AlarmSinks, "retry", lambda self, force=False: _raise_killed())
    history = HistoryDatabase(url)
    monitor = MachineMonitor(
        reference(), history, alarm=AlarmSinks(log_path=log), estimates="thread"
    )
    source = ReplaySource(leak_run(), speed=math.inf)
    with pytest.raises(_Killed):
        run_stream(monitor, source, source.rates_hz, source.lateness_s)
    monitor.worker.close()
    history.close()
    monkeypatch.undo()
    history = HistoryDatabase(url)
    machine = history.machine_id("festo-dsd")
    (stored,) = history.alarm_rows(machine)
    assert stored["locations"] == ["supply"]
    (key,) = AlarmSinks(log_path=log).keys.values()
    assert len(history.undelivered(machine, key)) == 1
    assert not log.exists()  # killed before the delivery
    warnings: list[str] = []
    restarted = MachineMonitor(
        reference(), history, alarm=AlarmSinks(log_path=log, warn=warnings.append)
    )
    (line,) = [json.loads(x) for x in log.read_text().splitlines()]  # delivered at start
    assert "left from an earlier run" in warnings[0]
    assert line["locations"] == ["supply"]
    assert line["timestamp"] == stored["timestamp"]
    assert line["id"] is not None
    assert history.undelivered(machine, key) == []
    source = ReplaySource(leak_run(), speed=math.inf)
    run_stream(restarted, source, source.rates_hz, source.lateness_s)
    restarted.close()
    assert len(log.read_text().splitlines()) == 1  # nothing twice
    assert len(history.alarm_rows(machine)) == 1
    history.close()


def _raise_killed() -> int:
    raise _Killed("between the commit and the delivery")
