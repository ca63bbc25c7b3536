"""Who may read and who may act: the users file, password hashes, tokens, bind rules.

One users file serves the dashboard (``pneufdd serve --users``) and the OPC UA server
of ``pneufdd monitor --publish opcua://...?users=``. It is TOML; a password is stored
only as an Argon2id hash (argon2-cffi, RFC 9106 parameters of its ``PasswordHasher``),
written by ``pneufdd users add``::

    [users.ann]
    role = "operator"        # acknowledge alarms, mark leaks repaired
    password_hash = "$argon2id$v=19$m=65536,t=3,p=4$..."

    [users.viewer]
    role = "viewer"          # read only
    password_hash = "$argon2id$..."

A token (``PNEUFDD_DASHBOARD_TOKEN``, or the first line of ``--token-file``) is the
other way in: whoever holds it is an operator. Secrets are never taken from the command
line, never printed and never logged.

Network services bind the loopback interface unless authenticated
(:func:`check_bind`): a host other than ``127.0.0.1``, ``::1`` or ``localhost`` is
refused without users or a token.
"""

from __future__ import annotations

import hmac
import ipaddress
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from pneufdd.errors import InputError, describe
from pneufdd.limits import read_text_capped

__all__ = [
    "ROLES",
    "TOKEN_ENV",
    "Credentials",
    "User",
    "check_bind",
    "hash_password",
    "is_loopback",
    "load_users",
    "read_token",
]

ROLES = ("viewer", "operator")
"""``viewer`` reads; ``operator`` also acknowledges alarms and marks repairs."""
TOKEN_ENV = "PNEUFDD_DASHBOARD_TOKEN"
MIN_TOKEN_CHARS = 16
MAX_USERS = 10_000


@dataclass(frozen=True)
class User:
    """A user of the users file (the hash is never shown)."""

    name: str
    role: str
    password_hash: str

    def __repr__(self) -> str:
        return f"User(name={self.name!r}, role={self.role!r})"


def hash_password(password: str) -> str:
    """The Argon2id hash of ``password`` (argon2-cffi defaults, RFC 9106 low-memory)."""
    from argon2 import PasswordHasher

    return str(PasswordHasher().hash(password))


def load_users(path: Path) -> dict[str, User]:
    """Read a users file (format in the module docstring).

    Raises
    ------
    InputError
        Naming the file and the entry that is not valid.
    """
    text = read_text_capped(path, f"users file {path}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(describe(f"users file {path}", f"not TOML ({exc})", "TOML")) from exc
    table = data.get("users", {})
    if not isinstance(table, Mapping) or len(table) > MAX_USERS:
        raise InputError(describe(f"users file {path}: [users]", type(table).__name__, "a table"))
    users = {}
    for name, entry in table.items():
        where = f"users file {path}: users.{name}"
        if not isinstance(entry, Mapping):
            raise InputError(describe(where, type(entry).__name__, "a table"))
        role = entry.get("role")
        if role not in ROLES:
            raise InputError(describe(f"{where}.role", role, list(ROLES)))
        hashed = entry.get("password_hash")
        if not isinstance(hashed, str) or not hashed.startswith("$argon2"):
            raise InputError(
                describe(
                    f"{where}.password_hash",
                    "missing or not an Argon2 hash",
                    "a hash written by `pneufdd users add`",
                )
            )
        users[str(name)] = User(str(name), str(role), hashed)
    return users


def read_token(token_file: Path | None) -> str | None:
    """The token: the first line of ``token_file``, else ``$PNEUFDD_DASHBOARD_TOKEN``.

    Raises
    ------
    InputError
        If the token is shorter than 16 characters (guessable).
    """
    if token_file is not None:
        lines = read_text_capped(token_file, f"--token-file {token_file}").splitlines()
        token = lines[0].strip() if lines else ""
        where = f"--token-file {token_file}"
    else:
        token = os.environ.get(TOKEN_ENV, "").strip()
        where = f"${TOKEN_ENV}"
        if not token:
            return None
    if len(token) < MIN_TOKEN_CHARS:
        raise InputError(
            describe(
                where,
                f"a token of {len(token)} characters",
                f"at least {MIN_TOKEN_CHARS} (e.g. python -c 'import secrets; "
                "print(secrets.token_urlsafe(32))')",
            )
        )
    return token


@dataclass(frozen=True)
class Credentials:
    """The ways in: users (name -> :class:`User`) and/or a token."""

    users: Mapping[str, User]
    token: str | None = None

    @property
    def required(self) -> bool:
        """Whether anyone must log in (users or a token are configured)."""
        return bool(self.users) or self.token is not None

    def check_password(self, name: str, password: str) -> User | None:
        """The user when ``password`` matches the stored hash; None otherwise."""
        from argon2 import PasswordHasher
        from argon2.exceptions import InvalidHashError, VerificationError

        user = self.users.get(name)
        if user is None:
            # spend the same time on an unknown name: no user enumeration by timing
            hash_password(password)
            return None
        try:
            PasswordHasher().verify(user.password_hash, password)
        except (VerificationError, InvalidHashError):
            return None
        return user

    def check_token(self, token: str) -> bool:
        """Whether ``token`` is the configured token (constant-time comparison)."""
        return self.token is not None and hmac.compare_digest(
            self.token.encode("utf-8"), token.encode("utf-8")
        )


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (``127.0.0.0/8``, ``::1``, ``localhost``).

    Examples
    --------
    >>> is_loopback("127.0.0.1"), is_loopback("localhost"), is_loopback("0.0.0.0")
    (True, True, False)
    """
    name = host.strip("[]").lower()
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def check_bind(option: str, host: str, authenticated: bool) -> None:
    """Refuse to listen on a non-loopback ``host`` without authentication.

    Raises
    ------
    InputError
        Naming the option, the host and what is needed.
    """
    if not is_loopback(host) and not authenticated:
        raise InputError(
            describe(
                option,
                host,
                "127.0.0.1 (the default), or another interface only with authentication "
                "(users file or token; docs/dashboard.md, section Security)",
            )
        )
