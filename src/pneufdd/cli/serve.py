"""``pneufdd serve``: the dashboard over a fault history (docs/dashboard.md).

Binds 127.0.0.1 by default; any other interface is refused without authentication
(``--users`` file of hashed passwords, or a token from ``--token-file`` or
``$PNEUFDD_DASHBOARD_TOKEN``). Exit codes: 0 stopped, 2 bad input.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from pneufdd.cli.exit_codes import ExitCode

__all__ = ["register"]


def serve_command(
    history: Annotated[
        str, typer.Option(help="SQLAlchemy URL of the fault history (SQLite or PostgreSQL).")
    ] = "sqlite:///pneufdd-history.db",
    host: Annotated[
        str,
        typer.Option(
            help="Interface to listen on; other than loopback only with --users or a token."
        ),
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=1, max=65535, help="TCP port.")] = 8050,
    users: Annotated[
        Path | None,
        typer.Option(help="Users file (TOML, Argon2 password hashes; `pneufdd users add`)."),
    ] = None,
    token_file: Annotated[
        Path | None,
        typer.Option(
            help="File whose first line is the access token (else $PNEUFDD_DASHBOARD_TOKEN)."
        ),
    ] = None,
    certfile: Annotated[
        Path | None, typer.Option(help="TLS certificate (PEM): serve HTTPS.")
    ] = None,
    keyfile: Annotated[Path | None, typer.Option(help="TLS private key (PEM).")] = None,
) -> None:
    """Serve the web dashboard: fleet, machines, alarms; updates live while monitors run."""
    from rich.console import Console

    from pneufdd.errors import InputError, describe
    from pneufdd.monitor.credentials import Credentials, check_bind, load_users, read_token
    from pneufdd.monitor.database import masked_url, sqlite_path

    err = Console(stderr=True, highlight=False, markup=False)
    credentials = Credentials(load_users(users) if users else {}, read_token(token_file))
    check_bind("--host", host, credentials.required)
    if (certfile is None) != (keyfile is None):
        raise InputError(describe("--certfile/--keyfile", "only one", "both or neither"))
    database = sqlite_path(history)
    if database is not None and not database.exists():
        raise InputError(describe("--history", masked_url(history), "an existing history database"))

    import uvicorn

    from pneufdd.web.app import ServeSettings, create_app

    settings = ServeSettings(history, host, port, credentials, https=certfile is not None)
    app = create_app(settings)
    scheme = "https" if certfile else "http"
    shown = f"[{host}]" if ":" in host else host
    how = "no login (loopback only)" if not credentials.required else "login required"
    err.print(f"dashboard of {masked_url(history)} on {scheme}://{shown}:{port}/ ({how})")
    if credentials.required and certfile is None and host not in ("127.0.0.1", "localhost", "::1"):
        err.print(
            "warning: passwords and session cookies cross the network in clear: "
            "use --certfile/--keyfile or a TLS proxy"
        )
    uvicorn.run(
        app,
        host=host,
        port=port,
        log_level="warning",
        access_log=False,  # URLs and headers stay out of the logs
        ssl_certfile=str(certfile) if certfile else None,
        ssl_keyfile=str(keyfile) if keyfile else None,
        timeout_graceful_shutdown=2,
    )
    raise typer.Exit(ExitCode.OK)


def register(app: typer.Typer) -> None:
    """Attach ``serve`` to ``app``."""
    app.command("serve")(serve_command)
