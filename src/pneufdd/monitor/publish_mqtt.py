"""Publish the machine's state and diagnoses to an MQTT broker (paho-mqtt), retained.

``--publish mqtt://broker:1883/plant/line1`` (``mqtts://`` for TLS, port 8883 by
default) publishes, QoS 1 and **retained**, so a client that subscribes later gets the
newest message at once:

========================================  ====================================================
topic                                     payload (JSON, ``docs/monitor.md`` section Publishing)
========================================  ====================================================
``<base>/<machine>/state``                the snapshot of every cycle (schema ``pneufdd.state/1``)
``<base>/<machine>/diagnosis``            the newest location and sizing run (the ``diagnose
                                          --json`` document with ``machine``, ``time``)
``<base>/<machine>/alarm``                the newest alarm (the alarm log's object)
========================================  ====================================================

Credentials come from the environment (``PNEUFDD_MQTT_USERNAME``,
``PNEUFDD_MQTT_PASSWORD``), never from the command line; the password is never printed.
The client reconnects by itself (paho, 1-30 s back-off); messages published while the
broker is away are queued by paho and sent on reconnection.
"""

from __future__ import annotations

import json
import os
import urllib.parse
from collections.abc import Callable, Mapping
from typing import Any

from pneufdd.errors import InputError, describe

__all__ = ["MQTT_PASSWORD_ENV", "MQTT_USER_ENV", "MqttPublisher"]

MQTT_USER_ENV = "PNEUFDD_MQTT_USERNAME"
MQTT_PASSWORD_ENV = "PNEUFDD_MQTT_PASSWORD"


def _topic_part(name: str) -> str:
    """A machine name as one topic level: MQTT's wildcards and separators replaced."""
    return "".join("_" if c in "/+#" or ord(c) < 32 else c for c in name) or "_"


class MqttPublisher:
    """Retained QoS-1 publishing of each snapshot (see the module docstring)."""

    name = "MQTT publisher"

    def __init__(self, url: str, warn: Callable[[str], None] | None = None) -> None:
        import paho.mqtt.client as mqtt
        from paho.mqtt.enums import CallbackAPIVersion

        parts = urllib.parse.urlsplit(url)
        allowed = "mqtt://host[:port]/base/topic or mqtts://... (base topic required)"
        if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
            raise InputError(describe("--publish", url, allowed))
        if parts.username or parts.password:
            raise InputError(
                describe(
                    "--publish",
                    "a URL with credentials",
                    f"credentials in ${MQTT_USER_ENV} and ${MQTT_PASSWORD_ENV}",
                )
            )
        self.base = parts.path.strip("/")
        if not self.base or any(c in self.base for c in "+#"):
            raise InputError(describe("--publish topic", self.base or "(none)", allowed))
        self.warn = warn
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv5, client_id="")
        user = os.environ.get(MQTT_USER_ENV)
        if user:
            self.client.username_pw_set(user, os.environ.get(MQTT_PASSWORD_ENV))
        if parts.scheme == "mqtts":
            self.client.tls_set()
        self.client.reconnect_delay_set(1, 30)
        port = parts.port or (8883 if parts.scheme == "mqtts" else 1883)
        self.where = f"{parts.scheme}://{parts.hostname}:{port}/{self.base}"
        self._last: Any = None
        self.client.connect_async(parts.hostname, port, keepalive=30)
        self.client.loop_start()

    def _send(self, topic: str, payload: Mapping[str, Any]) -> None:
        text = json.dumps(payload, allow_nan=False)
        self._last = self.client.publish(topic, text, qos=1, retain=True)

    def publish(self, state: Mapping[str, Any], diagnosis: Mapping[str, Any] | None) -> None:
        """Publish the snapshot (and the diagnosis and alarm, when new), retained."""
        prefix = f"{self.base}/{_topic_part(str(state['machine']))}"
        message = {k: v for k, v in state.items() if k != "new_alarms"}
        self._send(f"{prefix}/state", message)
        if diagnosis is not None:
            self._send(f"{prefix}/diagnosis", diagnosis)
        for alarm in state.get("new_alarms", []):
            self._send(f"{prefix}/alarm", alarm)

    def close(self, timeout_s: float = 5.0) -> None:
        """Send what is queued (up to ``timeout_s``), then disconnect."""
        if self._last is not None:
            try:
                self._last.wait_for_publish(timeout_s)
            except (RuntimeError, ValueError) as exc:  # never connected, or refused
                if self.warn is not None:
                    self.warn(f"MQTT publisher: the last message was not sent ({exc})")
        self.client.disconnect()
        self.client.loop_stop()
