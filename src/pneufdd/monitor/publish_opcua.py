"""An OPC UA server (asyncua) showing each machine's state to PLCs, HMIs and SCADA.

``--publish "opcua://0.0.0.0:4841?users=/etc/pneufdd/users.toml"`` serves, at
``opc.tcp://<host>:4841/pneufdd``, the namespace ``urn:pneufdd:monitor`` with one object per
machine under ``Objects/pneufdd`` (string node ids ``<machine>.<Variable>``):

===========================  ==========  ================================================
variable                     type        meaning
===========================  ==========  ================================================
``State``                    String      ``leak``, ``leak-free`` or ``start-up``
``InAlarm``                  Boolean     a leak is declared (CUSUM)
``CycleScore``               Double      newest cycle's score T (NaN: skipped, start-up)
``Cusum``                    Double      CUSUM after the newest cycle
``CusumThreshold``           Double      its decision threshold
``LastCycle``                DateTime    start of the newest cycle (UTC)
``ActiveLeaks``              Int32       number of active leaks
``LeakFlowSLPM``             Double      total flow while pressurised [SLPM, 0 degC, 1013 mbar]
``AnnualCost``               Double      their total annual cost [$/yr]
``Findings``                 String      JSON list: location, state, flow_slpm, annual_cost
``LastAlarm``                String      JSON of the newest alarm (the alarm log's object)
``LastAlarmTime``            DateTime    its time (UTC)
===========================  ==========  ================================================

and, in the folder ``<machine>.Leaks``, per leak location ever found an object
``<machine>.Leaks.<location>`` with
``Location`` (String), ``Active`` (Boolean), ``FlowSLPM`` and ``AnnualCost`` (Double).

Security: only the policy **Basic256Sha256 with SignAndEncrypt**; clients log in with
a user name and password of the users file (``?users=PATH``, Argon2 hashes,
:mod:`pneufdd.monitor.credentials`), anonymous only with ``?anonymous=1`` and then only
on a loopback address. The server's certificate is self-signed, generated at first
start (RSA 2048, ``cryptography`` through asyncua's helpers) into ``?certs=DIR`` or
``$XDG_DATA_HOME/pneufdd/opcua`` (``~/.local/share/pneufdd/opcua``), never into the
working folder; the key file is readable by its owner only. Clients must trust that
certificate (``server-cert.der``).
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import threading
import urllib.parse
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pneufdd.errors import InputError, describe
from pneufdd.monitor.credentials import Credentials, check_bind, is_loopback, load_users

__all__ = ["NAMESPACE_URI", "OpcUaPublisher", "default_cert_dir", "ensure_certificate"]

NAMESPACE_URI = "urn:pneufdd:monitor"
APPLICATION_URI = "urn:pneufdd:monitor:server"
START_TIMEOUT_S = 30.0


def default_cert_dir() -> Path:
    """``$XDG_DATA_HOME/pneufdd/opcua``, else ``~/.local/share/pneufdd/opcua``."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "pneufdd" / "opcua"


def ensure_certificate(folder: Path, host: str) -> tuple[Path, Path]:
    """The server's certificate (DER) and key (PEM) in ``folder``; made when missing.

    The key is written with mode 0600, atomically; an existing pair is kept.
    """
    from asyncua.crypto.cert_gen import (
        dump_private_key_as_pem,
        generate_private_key,
        generate_self_signed_app_certificate,
    )
    from cryptography import x509
    from cryptography.hazmat.primitives.serialization import Encoding
    from cryptography.x509.oid import ExtendedKeyUsageOID

    from pneufdd.files import write_bytes_atomic

    cert, key = folder / "server-cert.der", folder / "server-key.pem"
    if cert.is_file() and key.is_file():
        return cert, key
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    private = generate_private_key()
    import socket

    hosts = dict.fromkeys([host or "localhost", socket.gethostname(), "localhost"])
    names: list[x509.GeneralName] = [x509.UniformResourceIdentifier(APPLICATION_URI)]
    names += [x509.DNSName(h) for h in hosts if h]
    certificate = generate_self_signed_app_certificate(
        private,
        APPLICATION_URI,
        {"organizationName": "pneufdd", "commonName": "pneufdd monitor"},
        names,
        extended=[ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH],
        days=3650,
    )
    write_bytes_atomic(key, dump_private_key_as_pem(private))
    key.chmod(0o600)
    write_bytes_atomic(cert, certificate.public_bytes(encoding=Encoding.DER))
    return cert, key


def _options(url: str) -> dict[str, Any]:
    parts = urllib.parse.urlsplit(url)
    allowed = "opcua://host:port[?users=FILE][&certs=DIR][&anonymous=1]"
    try:
        port = parts.port or 4840
    except ValueError:
        raise InputError(describe("--publish", url, allowed)) from None
    if parts.scheme != "opcua" or not parts.hostname or parts.username or parts.password:
        raise InputError(describe("--publish", url, allowed))
    query = dict(urllib.parse.parse_qsl(parts.query))
    unknown = set(query) - {"users", "certs", "anonymous"}
    if unknown:
        raise InputError(
            describe("--publish option", sorted(unknown), ["users", "certs", "anonymous"])
        )
    return {
        "host": parts.hostname,
        "port": port,
        "users": Path(query["users"]) if "users" in query else None,
        "certs": Path(query["certs"]) if "certs" in query else default_cert_dir(),
        "anonymous": query.get("anonymous") in ("1", "true", "yes"),
    }


def _node_id(text: str, namespace: int) -> Any:
    """A string node id ``ns=<namespace>;s=<text>``."""
    from asyncua import ua

    make: Any = ua.NodeId
    return make(text, namespace)


class _Users:
    """asyncua's user manager over the users file (Argon2 hashes)."""

    def __init__(self, credentials: Credentials, anonymous: bool) -> None:
        self.credentials = credentials
        self.anonymous = anonymous

    def get_user(
        self,
        iserver: Any,
        username: str | None = None,
        password: str | None = None,
        certificate: Any = None,
    ) -> Any:
        from asyncua.crypto.permission_rules import User, UserRole

        if username is None:
            return User(role=UserRole.User, name="anonymous") if self.anonymous else None
        found = self.credentials.check_password(username, password or "")
        return None if found is None else User(role=UserRole.User, name=found.name)


class OpcUaPublisher:
    """The OPC UA server (own thread and event loop); :meth:`publish` updates its nodes.

    Raises
    ------
    InputError
        A malformed URL, a non-loopback host without users, neither users nor
        ``anonymous=1``, or a server that does not start (the port taken).
    """

    name = "OPC UA publisher"

    def __init__(self, url: str, warn: Callable[[str], None] | None = None) -> None:
        opts = _options(url)
        self.warn = warn
        users = load_users(opts["users"]) if opts["users"] else {}
        if opts["anonymous"] and not is_loopback(opts["host"]):
            raise InputError(
                describe(
                    "--publish anonymous=1",
                    opts["host"],
                    "a loopback host (127.0.0.1); elsewhere ?users=FILE",
                )
            )
        check_bind("--publish host", opts["host"], bool(users))
        if not users and not opts["anonymous"]:
            raise InputError(
                describe("--publish", url, "?users=FILE, or ?anonymous=1 on 127.0.0.1")
            )
        self.endpoint = f"opc.tcp://{opts['host']}:{opts['port']}/pneufdd"
        self.cert, self.key = ensure_certificate(opts["certs"], opts["host"])
        self._users = _Users(Credentials(users), opts["anonymous"])
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._nodes: dict[str, dict[str, Any]] = {}
        self._findings: dict[tuple[str, str], dict[str, Any]] = {}
        self._thread = threading.Thread(target=self._serve, name="pneufdd-opcua", daemon=True)
        self._thread.start()
        if not self._ready.wait(START_TIMEOUT_S) or self._error is not None:
            raise InputError(
                describe("--publish", self.endpoint, f"a server that starts ({self._error})")
            ) from self._error

    # ------------------------------------------------------------ server thread
    def _serve(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._start())
        except BaseException as exc:  # reported by __init__
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        self._loop.run_forever()

    async def _start(self) -> None:
        from asyncua import ua
        from asyncua.server.server import Server

        server = Server(user_manager=self._users)  # type: ignore[arg-type]
        await server.init()
        server.set_endpoint(self.endpoint)
        server.set_server_name("pneufdd monitor")
        await server.set_application_uri(APPLICATION_URI)
        await server.load_certificate(str(self.cert))
        await server.load_private_key(str(self.key))
        server.set_security_policy([ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt])
        tokens: list[type] = [ua.UserNameIdentityToken]
        if self._users.anonymous:
            tokens.append(ua.AnonymousIdentityToken)
        server.set_identity_tokens(tokens)
        self.namespace = await server.register_namespace(NAMESPACE_URI)
        self.root = await server.nodes.objects.add_folder(
            _node_id("pneufdd", self.namespace), "pneufdd"
        )
        await server.start()
        self.server = server

    async def _variable(self, parent: Any, node_id: str, name: str, value: Any, kind: Any) -> Any:
        from asyncua import ua

        return await parent.add_variable(
            _node_id(node_id, self.namespace), name, ua.Variant(value, kind)
        )

    async def _machine(self, machine: str) -> dict[str, Any]:
        from asyncua import ua

        found = self._nodes.get(machine)
        if found is not None:
            return found
        obj = await self.root.add_object(_node_id(machine, self.namespace), machine)
        v = ua.VariantType
        spec = {
            "State": ("", v.String),
            "InAlarm": (False, v.Boolean),
            "CycleScore": (math.nan, v.Double),
            "Cusum": (0.0, v.Double),
            "CusumThreshold": (math.nan, v.Double),
            "LastCycle": (datetime(1970, 1, 1, tzinfo=UTC), v.DateTime),
            "ActiveLeaks": (0, v.Int32),
            "LeakFlowSLPM": (0.0, v.Double),
            "AnnualCost": (0.0, v.Double),
            "Findings": ("[]", v.String),
            "LastAlarm": ("", v.String),
            "LastAlarmTime": (datetime(1970, 1, 1, tzinfo=UTC), v.DateTime),
        }
        nodes: dict[str, Any] = {
            "__object__": obj,
            "__findings__": await obj.add_folder(
                _node_id(f"{machine}.Leaks", self.namespace), "Leaks"
            ),
        }
        for name, (value, kind) in spec.items():
            nodes[name] = (await self._variable(obj, f"{machine}.{name}", name, value, kind), kind)
        self._nodes[machine] = nodes
        return nodes

    async def _finding(self, machine: str, location: str) -> dict[str, Any]:
        from asyncua import ua

        key = (machine, location)
        found = self._findings.get(key)
        if found is not None:
            return found
        folder = (await self._machine(machine))["__findings__"]
        base = f"{machine}.Leaks.{location}"
        obj = await folder.add_object(_node_id(base, self.namespace), location)
        v = ua.VariantType
        nodes = {}
        for name, value, kind in (
            ("Location", location, v.String),
            ("Active", True, v.Boolean),
            ("FlowSLPM", math.nan, v.Double),
            ("AnnualCost", math.nan, v.Double),
        ):
            nodes[name] = (await self._variable(obj, f"{base}.{name}", name, value, kind), kind)
        self._findings[key] = nodes
        return nodes

    async def _update(self, state: Mapping[str, Any]) -> None:
        from asyncua import ua

        machine = str(state["machine"])
        nodes = await self._machine(machine)
        findings = list(state["findings"])

        def num(x: Any) -> float:
            return math.nan if x is None else float(x)

        values: dict[str, Any] = {
            "State": state["state"],
            "InAlarm": bool(state["in_alarm"]),
            "CycleScore": num(state["score"]),
            "Cusum": float(state["cusum"]),
            "CusumThreshold": float(state["cusum_threshold"]),
            "LastCycle": datetime.fromtimestamp(float(state["last_cycle"]), UTC),
            "ActiveLeaks": len(findings),
            "LeakFlowSLPM": sum(num(f["flow_slpm"]) for f in findings),
            "AnnualCost": sum(num(f["annual_cost"]) for f in findings),
            "Findings": json.dumps(findings, allow_nan=False),
        }
        alarm = state.get("last_alarm")
        if alarm:
            values["LastAlarm"] = json.dumps(alarm, allow_nan=False)
            values["LastAlarmTime"] = datetime.fromtimestamp(float(alarm["timestamp"]), UTC)
        for name, value in values.items():
            node, kind = nodes[name]
            await node.write_value(ua.DataValue(ua.Variant(value, kind)))
        active = {str(f["location"]): f for f in findings}
        for location in active.keys() | {loc for m, loc in self._findings if m == machine}:
            leak = active.get(location)
            entry = await self._finding(machine, location)
            for name, value in (
                ("Active", leak is not None),
                ("FlowSLPM", num(leak["flow_slpm"]) if leak else math.nan),
                ("AnnualCost", num(leak["annual_cost"]) if leak else math.nan),
            ):
                node, kind = entry[name]
                await node.write_value(ua.DataValue(ua.Variant(value, kind)))

    # ------------------------------------------------------------ publisher
    def publish(self, state: Mapping[str, Any], diagnosis: Mapping[str, Any] | None) -> None:
        """Write the snapshot into the machine's nodes (waits at most 10 s)."""
        future = asyncio.run_coroutine_threadsafe(self._update(state), self._loop)
        future.result(timeout=10.0)

    def close(self) -> None:
        """Stop the server and its thread."""
        if not self._loop.is_running():
            return
        asyncio.run_coroutine_threadsafe(self.server.stop(), self._loop).result(timeout=10.0)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10.0)
        if not self._thread.is_alive():
            self._loop.close()
