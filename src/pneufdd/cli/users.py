"""``pneufdd users``: the users file of the dashboard and the OPC UA server (hashed passwords)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

__all__ = ["register"]

users_app = typer.Typer(
    help="Users of `serve` and `monitor --publish opcua://` (hashed passwords).",
    no_args_is_help=True,
)


@users_app.command("add")
def add_user(
    file: Annotated[Path, typer.Option(help="Users file (TOML); created when missing.")],
    name: Annotated[str, typer.Option(help="User name.")],
    role: Annotated[str, typer.Option(help="viewer (read only) or operator.")] = "viewer",
    password_stdin: Annotated[
        bool, typer.Option("--password-stdin", help="Read the password from standard input.")
    ] = False,
) -> None:
    """Add a user, or set a user's role and password (asked for, never on the command line)."""
    import tomllib

    import tomli_w

    from pneufdd.errors import InputError, describe
    from pneufdd.files import write_text_atomic
    from pneufdd.limits import read_text_capped
    from pneufdd.monitor.credentials import ROLES, hash_password, load_users

    if role not in ROLES:
        raise InputError(describe("--role", role, list(ROLES)))
    if not name or len(name) > 200 or any(c.isspace() or ord(c) < 32 for c in name):
        raise InputError(describe("--name", name, "1 to 200 characters, no spaces"))
    data: dict[str, dict[str, dict[str, str]]] = {"users": {}}
    if file.exists():
        load_users(file)  # refuses a damaged file before it is rewritten
        data = tomllib.loads(read_text_capped(file, f"users file {file}"))
        data.setdefault("users", {})
    if password_stdin:
        password = sys.stdin.readline().rstrip("\n")
    else:
        password = typer.prompt("password", hide_input=True, confirmation_prompt=True)
    if len(password) < 8:
        raise InputError(describe("password", f"{len(password)} characters", "at least 8"))
    data["users"][name] = {"role": role, "password_hash": hash_password(password)}
    write_text_atomic(file, tomli_w.dumps(data))
    file.chmod(0o600)
    typer.echo(f"{name} ({role}) written to {file}")


def register(app: typer.Typer) -> None:
    """Attach ``users`` to ``app``."""
    app.add_typer(users_app, name="users")
