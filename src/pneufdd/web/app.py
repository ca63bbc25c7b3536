"""The dashboard application (Starlette): pages, fragments, writes, events, metrics.

Routes (``docs/dashboard.md``):

=========================================  ===============================================
``GET /``                                  fleet view
``GET /machines/{name}``                   one machine: schematic, leaks, charts, alarms
``GET /alarms/{id}``                       the diagnosis report of an alarm
``GET /fragments/...``                     the live parts of those pages (HTML)
``GET /api/fleet``, ``/api/machines/{name}/figures``   JSON
``POST /api/alarms/{id}/ack``              acknowledge (operator)
``POST /api/machines/{name}/repaired``     mark a location repaired (operator), as
                                           ``pneufdd history --repaired``
``GET /events``                            server-sent events: ``change``
``GET /metrics``                           Prometheus text format
``GET|POST /login``, ``POST /logout``      when users or a token are configured
=========================================  ===============================================

Every write needs a CSRF token (starlette-csrf: a signed token in a cookie, echoed
in the ``x-csrftoken`` header; the middleware refuses any POST without it, 403).
"""

from __future__ import annotations

import contextlib
import json
import secrets
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path
from typing import Any

import anyio.to_thread
import jinja2
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.sessions import SessionMiddleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import (
    FileResponse,
    HTMLResponse,
    JSONResponse,
    RedirectResponse,
    Response,
    StreamingResponse,
)
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles
from starlette_csrf.middleware import CSRFMiddleware

from pneufdd.monitor import fleet
from pneufdd.monitor.credentials import Credentials, is_loopback
from pneufdd.monitor.database import HistoryDatabase, masked_url
from pneufdd.report.plotly_figures import (
    diagnosis_statistic_figure,
    leak_trend_figure,
    score_figure,
)
from pneufdd.report.schematic import schematic_svg
from pneufdd.web.feed import POLL_S, ChangeFeed

__all__ = ["ServeSettings", "create_app", "plotly_js_path"]

Handler = Callable[[Request], Awaitable[Response]]
MAX_LOCATION_CHARS = 100


@dataclass(frozen=True)
class ServeSettings:
    """What ``pneufdd serve`` was asked for."""

    history: str
    host: str = "127.0.0.1"
    port: int = 8050
    credentials: Credentials = field(default_factory=lambda: Credentials({}))
    https: bool = False
    poll_s: float = POLL_S


def plotly_js_path() -> Path:
    """The plotly.js bundle shipped inside the installed ``plotly`` package."""
    import plotly

    return Path(plotly.__file__).parent / "package_data" / "plotly.min.js"


def _utc(t: float | None) -> str:
    if t is None:
        return "-"
    return datetime.fromtimestamp(float(t), UTC).strftime("%Y-%m-%d %H:%M:%S")


def _money(x: float | None) -> str:
    return "-" if x is None else f"{x:,.0f}"


def _flow(x: float | None) -> str:
    return "-" if x is None else f"{x:,.1f}"


def _templates() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("pneufdd.web", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    env.filters.update(utc=_utc, money=_money, flow=_flow)
    return env


class Dashboard:
    """State shared by the handlers: the history, the templates, the change feed."""

    def __init__(self, settings: ServeSettings) -> None:
        self.settings = settings
        self.db = HistoryDatabase(settings.history)
        self.env = _templates()
        self.feed = ChangeFeed(lambda: fleet.change_stamp(self.db), settings.poll_s)

    # ------------------------------------------------------------ helpers
    def user(self, request: Request) -> tuple[str, str] | None:
        """(name, role) of the request, None when it must log in first."""
        creds = self.settings.credentials
        if not creds.required:
            return ("local user", "operator")
        session = request.session
        if "user" in session and "role" in session:
            return str(session["user"]), str(session["role"])
        header = request.headers.get("authorization", "")
        if header.lower().startswith("bearer ") and creds.check_token(header[7:].strip()):
            return ("token", "operator")
        return None

    def page(self, request: Request, template: str, **context: Any) -> HTMLResponse:
        who = self.user(request)
        text = self.env.get_template(template).render(
            user=who[0] if who else None,
            role=who[1] if who else None,
            can_write=bool(who and who[1] == "operator"),
            login=self.settings.credentials.required,
            history=masked_url(self.settings.history),
            now=_utc(time.time()),
            feed_error=self.feed.error,
            **context,
        )
        return HTMLResponse(text, headers={"Cache-Control": "no-store"})

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        return await anyio.to_thread.run_sync(fn, *args)

    async def machine_id(self, name: str) -> int | None:
        known = dict((n, i) for i, n in await self.run(self.db.machines))
        return known.get(name)


def _guard(dash: Dashboard, handler: Handler, role: str = "viewer", page: bool = False) -> Handler:
    """Let through a logged-in user of ``role`` (operator includes viewer)."""

    async def guarded(request: Request) -> Response:
        who = dash.user(request)
        if who is None:
            if page:
                return RedirectResponse("/login", status_code=303)
            return JSONResponse({"error": "log in first"}, status_code=401)
        if role == "operator" and who[1] != "operator":
            return JSONResponse({"error": "operators only"}, status_code=403)
        return await handler(request)

    return guarded


# ---------------------------------------------------------------- handlers
def _fleet_handlers(dash: Dashboard) -> dict[str, Handler]:
    async def summary() -> list[fleet.FleetRow]:
        rows: list[fleet.FleetRow] = await dash.run(fleet.fleet_summary, dash.db, time.time())
        return rows

    async def fleet_page(request: Request) -> Response:
        return dash.page(request, "fleet.html", rows=await summary())

    async def fleet_fragment(request: Request) -> Response:
        return dash.page(request, "fleet_table.html", rows=await summary())

    async def fleet_json(request: Request) -> Response:
        return JSONResponse({"machines": [r.to_dict() for r in await summary()]})

    return {"page": fleet_page, "fragment": fleet_fragment, "json": fleet_json}


def _machine_context(db: HistoryDatabase, machine_id: int, name: str) -> dict[str, Any]:
    info = fleet.load_machine_info(db, machine_id)
    trends = fleet.leak_trends(db, machine_id)
    active = [t for t in trends if t["state"] != "repaired"]
    return {
        "machine": name,
        "info": info,
        "trends": trends,
        "active": active,
        "schematic": schematic_svg(info.description if info else None, active),
        "alarms": fleet.alarm_list(db, machine_id),
        "gaps": db.gap_rows(machine_id)[-200:][::-1],
    }


def _machine_figures(db: HistoryDatabase, machine_id: int, name: str) -> dict[str, Any]:
    info = fleet.load_machine_info(db, machine_id)
    cycles = fleet.cycle_series(db, machine_id)
    gaps = db.gap_rows(machine_id, cycles[0]["start"] if cycles else None)
    span = f"{_utc(cycles[0]['start'])} .. {_utc(cycles[-1]['start'])} UTC" if cycles else "none"
    score = score_figure(
        cycles,
        info.cycle_threshold if info else None,
        info.cusum_threshold if info else None,
        gaps,
        f"{name}: cycle score and CUSUM, newest {len(cycles)} cycles ({span})",
    )
    trend = leak_trend_figure(
        fleet.leak_trends(db, machine_id), f"{name}: leak sizes over time (axis from zero)"
    )
    return {"score": json.loads(score), "trend": json.loads(trend)}


def _machine_handlers(dash: Dashboard) -> dict[str, Handler]:
    async def context(request: Request) -> dict[str, Any] | None:
        name = request.path_params["name"]
        machine_id = await dash.machine_id(name)
        if machine_id is None:
            return None
        found: dict[str, Any] = await dash.run(_machine_context, dash.db, machine_id, name)
        return found

    async def machine_page(request: Request) -> Response:
        found = await context(request)
        if found is None:
            return HTMLResponse("unknown machine", status_code=404)
        return dash.page(request, "machine.html", **found)

    async def machine_fragment(request: Request) -> Response:
        found = await context(request)
        if found is None:
            return HTMLResponse("unknown machine", status_code=404)
        return dash.page(request, "machine_live.html", **found)

    async def figures(request: Request) -> Response:
        name = request.path_params["name"]
        machine_id = await dash.machine_id(name)
        if machine_id is None:
            return JSONResponse({"error": "unknown machine"}, status_code=404)
        return JSONResponse(await dash.run(_machine_figures, dash.db, machine_id, name))

    async def alarm_page(request: Request) -> Response:
        alarm_id = request.path_params["alarm_id"]
        found = await dash.run(fleet.diagnosis_of_alarm, dash.db, alarm_id)
        if found is None:
            return HTMLResponse("no diagnosis stored for this alarm", status_code=404)
        name, data = found
        when = _utc(data["window"]["time"])
        figure = diagnosis_statistic_figure(
            data.get("detection", {}), f"{name}: per-cycle statistic of the alarm at {when} UTC"
        )
        return dash.page(
            request, "diagnosis.html", machine=name, alarm_id=alarm_id, d=data, figure=figure
        )

    return {
        "page": machine_page,
        "fragment": machine_fragment,
        "figures": figures,
        "alarm": alarm_page,
    }


def _write_handlers(dash: Dashboard) -> dict[str, Handler]:
    async def ack(request: Request) -> Response:
        who = dash.user(request)
        assert who is not None  # guarded
        done = await dash.run(
            fleet.acknowledge, dash.db, request.path_params["alarm_id"], who[0], time.time()
        )
        return JSONResponse({"acknowledged": bool(done)}, status_code=200 if done else 409)

    async def repaired(request: Request) -> Response:
        name = request.path_params["name"]
        if await dash.machine_id(name) is None:
            return JSONResponse({"error": "unknown machine"}, status_code=404)
        try:
            body = await request.json()
            location = str(body["location"])
        except (ValueError, KeyError, TypeError):
            return JSONResponse({"error": 'send {"location": ...}'}, status_code=400)
        if not location or len(location) > MAX_LOCATION_CHARS:
            return JSONResponse({"error": "location: 1 to 100 characters"}, status_code=400)
        count = await dash.run(dash.db.mark_repaired, name, location, time.time())
        return JSONResponse({"repaired": int(count)})

    return {"ack": ack, "repaired": repaired}


def _session_handlers(dash: Dashboard) -> dict[str, Handler]:
    async def login_page(request: Request) -> Response:
        if not dash.settings.credentials.required:
            return RedirectResponse("/", status_code=303)
        return dash.page(request, "login.html", users=bool(dash.settings.credentials.users))

    async def login(request: Request) -> Response:
        creds = dash.settings.credentials
        try:
            body = await request.json()
        except ValueError:
            body = {}
        who: tuple[str, str] | None = None
        if isinstance(body, dict) and body.get("token"):
            if creds.check_token(str(body["token"])):
                who = ("token", "operator")
        elif isinstance(body, dict) and body.get("user"):
            user = await dash.run(
                creds.check_password, str(body["user"]), str(body.get("password", ""))
            )
            if user is not None:
                who = (user.name, user.role)
        if who is None:
            return JSONResponse({"error": "not recognised"}, status_code=401)
        request.session.clear()
        request.session.update({"user": who[0], "role": who[1]})
        return JSONResponse({"user": who[0], "role": who[1]})

    async def logout(request: Request) -> Response:
        request.session.clear()
        return JSONResponse({"logged_out": True})

    return {"login_page": login_page, "login": login, "logout": logout}


def _stream_handlers(dash: Dashboard) -> dict[str, Handler]:
    async def events(request: Request) -> Response:
        return StreamingResponse(
            dash.feed.events(),
            media_type="text/event-stream",
            headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
        )

    async def metrics(request: Request) -> Response:
        from pneufdd.monitor.metrics import history_metrics

        body, content_type = await dash.run(history_metrics, dash.db, time.time())
        return Response(body, media_type=content_type)

    async def plotly_js(request: Request) -> Response:
        return FileResponse(plotly_js_path(), media_type="text/javascript")

    return {"events": events, "metrics": metrics, "plotly": plotly_js}


def create_app(settings: ServeSettings) -> Starlette:
    """The dashboard over ``settings.history`` (opened and migrated here).

    Sessions and CSRF tokens are signed with secrets drawn at start (a restart logs
    everyone out). On a loopback bind only ``Host`` headers naming the loopback are
    answered (a web page cannot reach the dashboard through DNS rebinding).
    """
    dash = Dashboard(settings)
    f, m = _fleet_handlers(dash), _machine_handlers(dash)
    w, s, e = _write_handlers(dash), _session_handlers(dash), _stream_handlers(dash)
    static = resources.files("pneufdd.web") / "static"
    routes = [
        Route("/", _guard(dash, f["page"], page=True)),
        Route("/fragments/fleet", _guard(dash, f["fragment"])),
        Route("/api/fleet", _guard(dash, f["json"])),
        Route("/machines/{name:str}", _guard(dash, m["page"], page=True)),
        Route("/fragments/machines/{name:str}", _guard(dash, m["fragment"])),
        Route("/api/machines/{name:str}/figures", _guard(dash, m["figures"])),
        Route("/alarms/{alarm_id:int}", _guard(dash, m["alarm"], page=True)),
        Route(
            "/api/alarms/{alarm_id:int}/ack", _guard(dash, w["ack"], "operator"), methods=["POST"]
        ),
        Route(
            "/api/machines/{name:str}/repaired",
            _guard(dash, w["repaired"], "operator"),
            methods=["POST"],
        ),
        Route("/events", _guard(dash, e["events"])),
        Route("/metrics", _guard(dash, e["metrics"])),
        Route("/login", s["login_page"]),
        Route("/login", s["login"], methods=["POST"]),
        Route("/logout", s["logout"], methods=["POST"]),
        Route("/static/plotly.min.js", e["plotly"]),
        Mount("/static", StaticFiles(directory=str(static)), name="static"),
    ]
    hosts = ["127.0.0.1", "localhost", "[::1]", "::1"] if is_loopback(settings.host) else ["*"]
    middleware = [
        Middleware(TrustedHostMiddleware, allowed_hosts=hosts),
        Middleware(
            SessionMiddleware,
            secret_key=secrets.token_urlsafe(32),
            session_cookie="pneufdd_session",
            same_site="strict",
            https_only=settings.https,
        ),
        Middleware(
            CSRFMiddleware,
            secret=secrets.token_urlsafe(32),
            cookie_secure=settings.https,
            cookie_samesite="strict",
        ),
    ]

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        async with anyio.create_task_group() as group:
            group.start_soon(dash.feed.run)
            try:
                yield
            finally:
                group.cancel_scope.cancel()
        dash.db.close()

    app = Starlette(routes=routes, middleware=middleware, lifespan=lifespan)
    app.state.dashboard = dash
    return app
