"""The dashboard (``pneufdd serve``) in a real browser beside a running monitor.

The server is the real command in its own process; the browser is the system's
chromium (apt) driven headless by playwright (never a downloaded browser); the monitor
is ``pneufdd monitor`` replaying a festo-dsd run whose 4-turn supply leak appears at
40 s, writing into the SQLite history the dashboard shows. The browser tests skip
only when ``/usr/bin/chromium`` is absent.
"""

from __future__ import annotations

import contextlib
import http.cookiejar
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import tomli_w

from monitor_data import free_port, leak_run, reference
from pneufdd.cli.app import main
from pneufdd.diagnosis.reference.file import save_reference
from pneufdd.monitor import fleet
from pneufdd.monitor.credentials import Credentials, hash_password, load_users
from pneufdd.monitor.database import HistoryDatabase

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
MACHINE = "festo-dsd"


def _wait_port(port: int, proc: subprocess.Popen | None = None, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while True:
        with socket.socket() as s, contextlib.suppress(OSError):
            s.connect(("127.0.0.1", port))
            return
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"the server exited: {proc.stderr.read() if proc.stderr else ''}")
        assert time.monotonic() < end, "the server did not start"
        time.sleep(0.1)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """A history, the reference and run of the replay, and `pneufdd serve` on it."""
    folder = tmp_path_factory.mktemp("dashboard")
    url = f"sqlite:///{folder / 'line1.db'}"
    db = HistoryDatabase(url)
    db.machine_id(MACHINE)  # the machine's page exists before the monitor starts
    port = free_port()
    command = [str(Path(sys.executable).with_name("pneufdd")), "serve", "--history", url]
    proc = subprocess.Popen(
        [*command, "--port", str(port)],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PNEUFDD_DASHBOARD_TOKEN": ""},
    )
    try:
        _wait_port(port, proc)
        yield {
            "folder": folder,
            "url": url,
            "db": db,
            "base": f"http://127.0.0.1:{port}",
            "ref": save_reference(reference(), folder / "ref.pnref"),
            "run": leak_run().write(folder / "run.parquet"),
        }
    finally:
        proc.terminate()
        proc.wait(20)
        if proc.stderr is not None:
            proc.stderr.close()
        db.close()


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.exists():
        pytest.skip("/usr/bin/chromium is absent (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as driver:
        chromium = driver.chromium.launch(
            executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS, headless=True
        )
        try:
            yield chromium
        finally:
            chromium.close()


@pytest.fixture(scope="module")
def watched(site, browser):
    """The machine page open while a monitor replay raises the alarm.

    Returns the page, the time the alarm was committed and the time it showed.
    """
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    requested: list[str] = []
    page.on("request", lambda r: requested.append(r.url))
    page.goto(f"{site['base']}/machines/{MACHINE}")
    page.wait_for_selector("#live.on", timeout=30_000)
    page.evaluate("window.__notReloaded = 42")
    committed: list[float] = []
    history = HistoryDatabase(site["url"])

    def watch() -> None:
        machine_id = history.machine_id(MACHINE)
        end = time.monotonic() + 300
        while time.monotonic() < end and not committed:
            if history.alarm_rows(machine_id):
                committed.append(time.monotonic())
            time.sleep(0.02)

    args = ["monitor", "--reference", str(site["ref"]), "--history", site["url"], "--once"]
    args += ["--source", f"replay:{site['run']}?speed=max"]
    codes: list[int] = []
    watcher = threading.Thread(target=watch)
    monitor = threading.Thread(target=lambda: codes.append(main(args)))
    watcher.start()
    monitor.start()
    page.wait_for_selector("tr[data-alarm-id][data-kind=leak]", timeout=300_000)
    shown = time.monotonic()
    watcher.join()
    monitor.join()
    history.close()
    yield {
        "page": page,
        "committed": committed,
        "shown": shown,
        "codes": codes,
        "requested": requested,
    }
    page.close()


def test_a_new_alarm_appears_without_a_reload_within_2_s(watched):
    assert watched["codes"] == [1]  # the leak is active at the end of the replay
    assert watched["committed"], "the monitor committed no alarm"
    delay = watched["shown"] - watched["committed"][0]
    assert delay <= 2.0, f"the alarm showed {delay:.2f} s after it was committed"
    assert watched["page"].evaluate("window.__notReloaded") == 42


def test_acknowledge_and_repair_round_trip_to_the_history(site, watched):
    page = watched["page"]
    page.wait_for_selector("tr[data-location=supply][data-state] button.repair")
    row = page.locator("tr[data-alarm-id][data-kind=leak]").first
    alarm_id = int(row.get_attribute("data-alarm-id"))
    row.locator("button.ack").click()
    page.wait_for_selector(f"tr[data-alarm-id='{alarm_id}'] td.ack:has-text('local user')")
    machine_id = site["db"].machine_id(MACHINE)
    stored = {a["id"]: a for a in fleet.alarm_list(site["db"], machine_id)}
    assert stored[alarm_id]["ack_user"] == "local user"
    assert stored[alarm_id]["ack_time"] is not None
    clicked = time.time()
    page.locator("tr[data-location=supply] button.repair").click()
    page.wait_for_selector("tr[data-location=supply][data-state=repaired]")
    leak = next(r for r in site["db"].leak_rows(machine_id) if r.location == "supply")
    assert leak.state == "repaired"
    assert clicked - 1.0 <= leak.repaired_at <= time.time() + 1.0
    # the same record `pneufdd history --repaired` writes, as `history --json` shows it
    assert page.evaluate("window.__notReloaded") == 42


def test_pages_fetch_nothing_from_outside_and_draw_their_charts(site, watched, browser):
    page = watched["page"]
    page.wait_for_selector(".chart .main-svg", timeout=30_000)
    assert page.locator(".chart .main-svg").count() >= 2
    assert page.locator(".schematic svg g.leak").count() == 0  # repaired above: none active
    pages = [f"{site['base']}/", f"{site['base']}/machines/{MACHINE}"]
    alarm = page.locator("tr[data-alarm-id][data-kind=leak]").first.get_attribute("data-alarm-id")
    pages.append(f"{site['base']}/alarms/{alarm}")
    other = browser.new_page(viewport={"width": 1400, "height": 1000})
    requested = list(watched["requested"])
    other.on("request", lambda r: requested.append(r.url))
    shots = os.environ.get("PNEUFDD_SCREENSHOTS")
    for k, address in enumerate(pages):
        other.goto(address)
        other.wait_for_load_state("networkidle")
        with urllib.request.urlopen(address, timeout=10) as response:
            source = response.read().decode()  # the page as served, not the drawn DOM
        outside = [
            u for u in re.findall(r"https?://[^\s\"'<>]+", source) if not u.startswith(site["base"])
        ]
        assert outside == [], address
        if shots:
            other.screenshot(path=str(Path(shots) / f"dashboard-{k}.png"), full_page=True)
    other.close()
    assert requested
    assert all(u.startswith(site["base"]) for u in requested), requested
    with urllib.request.urlopen(f"{site['base']}/fragments/fleet", timeout=10) as response:
        fleet_html = response.read().decode()
    assert f'data-machine="{MACHINE}"' in fleet_html


def _opener() -> tuple[urllib.request.OpenerDirector, http.cookiejar.CookieJar]:
    jar = http.cookiejar.CookieJar()
    return urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar)), jar


def _post(opener, url: str, body: dict, token: str | None) -> int:
    headers = {"content-type": "application/json"}
    if token is not None:
        headers["x-csrftoken"] = token
    request = urllib.request.Request(url, json.dumps(body).encode(), headers, method="POST")
    try:
        with opener.open(request, timeout=10) as response:
            return int(response.status)
    except urllib.error.HTTPError as exc:
        exc.close()
        return int(exc.code)


def test_a_write_without_a_csrf_token_is_refused(site, watched):
    opener, jar = _opener()
    with opener.open(f"{site['base']}/", timeout=10) as response:
        response.read()
    token = next(c.value for c in jar if c.name == "csrftoken")
    target = f"{site['base']}/api/machines/{MACHINE}/repaired"
    assert _post(opener, target, {"location": "DNC_A"}, None) == 403
    assert _post(opener, target, {"location": "DNC_A"}, "forged" + token[6:]) == 403
    assert _post(opener, target, {"location": "DNC_A"}, token) == 200
    bare = urllib.request.build_opener()  # no cookie at all
    assert _post(bare, target, {"location": "DNC_A"}, token) == 403


def test_metrics_of_the_dashboard_parse_and_match_the_history(site, watched):
    from prometheus_client.parser import text_string_to_metric_families

    with urllib.request.urlopen(f"{site['base']}/metrics", timeout=10) as response:
        text = response.read().decode()
    samples = {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(text)
        for s in family.samples
    }
    machine_id = site["db"].machine_id(MACHINE)
    alarms = site["db"].alarm_rows(machine_id)
    leak_alarms = sum(1 for a in alarms if a["kind"] == "leak")
    assert (
        samples[("pneufdd_alarms_total", (("kind", "leak"), ("machine", MACHINE)))] == leak_alarms
    )
    assert samples[("pneufdd_open_alarms", (("machine", MACHINE),))] == 0  # acknowledged above
    last = site["db"].cycle_rows(machine_id)[-1]["start"]
    assert samples[("pneufdd_last_cycle_timestamp_seconds", (("machine", MACHINE),))] == (
        pytest.approx(round(last * 1000) / 1000, abs=1e-6)
    )


def test_a_host_header_other_than_the_loopback_is_refused(site):
    request = urllib.request.Request(f"{site['base']}/", headers={"Host": "attacker.example"})
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=10)
    refused.value.close()
    assert refused.value.code == 400


def test_a_non_local_bind_without_authentication_is_refused(site, capsys, monkeypatch):
    monkeypatch.delenv("PNEUFDD_DASHBOARD_TOKEN", raising=False)
    for host in ("0.0.0.0", "192.0.2.10", "::"):
        assert main(["serve", "--history", site["url"], "--host", host]) == 2
        err = capsys.readouterr().err
        assert "--host" in err
        assert "authentication" in err
    monkeypatch.setenv("PNEUFDD_DASHBOARD_TOKEN", "short")
    assert main(["serve", "--history", site["url"], "--host", "0.0.0.0"]) == 2
    assert "short" not in capsys.readouterr().err  # a secret is never printed


def test_login_roles_and_tokens(site, tmp_path):
    """Users with hashed passwords: a viewer reads but may not write; a token is an operator."""
    import uvicorn

    from pneufdd.web.app import ServeSettings, create_app

    users_file = tmp_path / "users.toml"
    users_file.write_text(
        tomli_w.dumps(
            {
                "users": {
                    "vic": {"role": "viewer", "password_hash": hash_password("viewer password 1")},
                }
            }
        )
    )
    token = "t0ken-" + "x" * 30
    port = free_port()
    settings = ServeSettings(
        site["url"], "127.0.0.1", port, Credentials(load_users(users_file), token)
    )
    server = uvicorn.Server(
        uvicorn.Config(
            create_app(settings), host="127.0.0.1", port=port, log_level="warning", access_log=False
        )
    )
    thread = threading.Thread(target=server.run)
    thread.start()
    try:
        _wait_port(port)
        base = f"http://127.0.0.1:{port}"
        opener, jar = _opener()
        with opener.open(f"{base}/", timeout=10) as login_page:  # redirected to log in
            assert login_page.url.endswith("/login")
            page_text = login_page.read().decode()
        csrf = next(c.value for c in jar if c.name == "csrftoken")
        with pytest.raises(urllib.error.HTTPError) as anonymous:
            opener.open(f"{base}/api/fleet", timeout=10)
        anonymous.value.close()
        assert anonymous.value.code == 401
        assert _post(opener, f"{base}/login", {"user": "vic", "password": "wrong"}, csrf) == 401
        assert (
            _post(opener, f"{base}/login", {"user": "vic", "password": "viewer password 1"}, csrf)
            == 200
        )
        with opener.open(f"{base}/api/fleet", timeout=10) as response:
            fleet_json = json.loads(response.read())
        assert [m["machine"] for m in fleet_json["machines"]] == [MACHINE]
        target = f"{base}/api/machines/{MACHINE}/repaired"
        assert _post(opener, target, {"location": "DNC_A"}, csrf) == 403  # viewer
        with opener.open(f"{base}/machines/{MACHINE}", timeout=10) as response:
            page_text += response.read().decode()
        for secret in ("viewer password 1", token, "$argon2"):
            assert secret not in page_text
        request = urllib.request.Request(
            f"{base}/metrics", headers={"Authorization": f"Bearer {token}"}
        )
        with urllib.request.urlopen(request, timeout=10) as response:
            assert b"pneufdd_alarms_total" in response.read()
    finally:
        server.should_exit = True
        thread.join(20)
