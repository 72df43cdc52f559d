"""MQTT transport for VDA 5050: broker addresses, topic names, and a reconnecting client.

Topics are ``{interfaceName}/{majorVersion}/{manufacturer}/{serialNumber}/{topic}``
(interface name default ``uagv``). The client is paho-mqtt's, run in its own network thread;
it reconnects after a lost connection (with back-off) and subscribes again each time it
connects, so a broker restart costs the messages sent while it was down, nothing more (VDA
5050 states are complete snapshots: the next one carries everything).
"""

from __future__ import annotations

import json
import threading
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlparse

import paho.mqtt.client as paho

from pickstop.errors import InputError

INTERFACE = "uagv"
LEVEL_FORBIDDEN = "/+#"


@dataclass(frozen=True)
class Broker:
    host: str
    port: int

    @property
    def url(self) -> str:
        return f"mqtt://{self.host}:{self.port}"


def parse_broker(url: str) -> Broker:
    """``mqtt://HOST:PORT`` (port default 1883) -> :class:`Broker`; anything else: InputError."""
    u = urlparse(url if "://" in url else f"mqtt://{url}")
    if u.scheme != "mqtt":
        raise InputError(f"broker: {url!r}: only mqtt:// is supported", field="broker")
    try:
        port = u.port or 1883
    except ValueError:
        raise InputError(f"broker: {url!r}: the port is not a number", field="broker") from None
    if not u.hostname:
        raise InputError(f"broker: {url!r}: no host", field="broker")
    if not 0 < port < 65536:
        raise InputError(f"broker: {url!r}: port out of range", field="broker")
    return Broker(u.hostname, port)


def check_level(name: str, value: str) -> str:
    if not value or any(c in value for c in LEVEL_FORBIDDEN):
        raise InputError(
            f"{name}: {value!r} must be non-empty without '/', '+' or '#' (a topic level)",
            field=name,
        )
    return value


def topic(interface: str, version: str, manufacturer: str, serial: str, leaf: str) -> str:
    """The VDA 5050 topic of one vehicle, e.g. ``uagv/v2/acme/agv-1/order``."""
    major = "v" + version.split(".")[0]
    return f"{interface}/{major}/{manufacturer}/{serial}/{leaf}"


Handler = Callable[[str, dict[str, Any]], None]


class Link:
    """One MQTT connection: JSON publish, subscriptions that survive reconnects."""

    def __init__(
        self,
        broker: Broker,
        client_id: str | None = None,
        will: tuple[str, dict[str, Any]] | None = None,
    ) -> None:
        self.broker = broker
        self.client = paho.Client(
            paho.CallbackAPIVersion.VERSION2,
            client_id=client_id or f"pickstop-{uuid.uuid4().hex[:12]}",
        )
        self.client.reconnect_delay_set(min_delay=1, max_delay=2)
        if will is not None:
            self.client.will_set(will[0], json.dumps(will[1]), qos=1, retain=True)
        self._subs: dict[str, tuple[int, Handler]] = {}
        self._lock = threading.Lock()
        self.connected = threading.Event()
        self.connects = 0  # how many times it (re)connected
        self.on_connect: list[Callable[[], None]] = []  # run after each (re)connect
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message

    def start(self, timeout: float = 10.0) -> Link:
        try:
            self.client.connect_async(self.broker.host, self.broker.port, keepalive=5)
        except (OSError, ValueError) as e:
            raise InputError(f"broker {self.broker.url}: {e}", field="broker") from None
        self.client.loop_start()
        if not self.connected.wait(timeout):
            self.stop()
            raise InputError(
                f"broker {self.broker.url}: no connection within {timeout:.0f} s", field="broker"
            )
        return self

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()

    def subscribe(self, topic_: str, handler: Handler, qos: int = 0) -> None:
        with self._lock:
            self._subs[topic_] = (qos, handler)
        if self.connected.is_set():
            self.client.subscribe(topic_, qos)

    def publish(
        self, topic_: str, doc: dict[str, Any], qos: int = 0, retain: bool = False
    ) -> paho.MQTTMessageInfo:
        return self.client.publish(topic_, json.dumps(doc), qos=qos, retain=retain)

    # -- paho callbacks (network thread) ---------------------------------------------------------
    def _on_connect(self, client: Any, userdata: Any, flags: Any, rc: Any, props: Any) -> None:
        if rc.is_failure:
            return
        with self._lock:
            subs = list(self._subs.items())
        for t, (qos, _) in subs:
            client.subscribe(t, qos)
        self.connects += 1
        self.connected.set()
        for f in self.on_connect:
            f()

    def _on_disconnect(self, client: Any, userdata: Any, flags: Any, rc: Any, props: Any) -> None:
        self.connected.clear()

    def _on_message(self, client: Any, userdata: Any, msg: Any) -> None:
        with self._lock:
            handlers = [
                h for t, (_, h) in self._subs.items() if paho.topic_matches_sub(t, msg.topic)
            ]
        try:
            doc = json.loads(msg.payload)
        except (ValueError, UnicodeDecodeError):
            return  # not JSON: not a VDA 5050 message
        if not isinstance(doc, dict):
            return
        for h in handlers:
            h(msg.topic, doc)
