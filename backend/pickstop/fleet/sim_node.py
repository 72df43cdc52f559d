"""The simulated vehicle on MQTT: takes orders from its ``order`` topic, publishes ``state``
on every change and at a fixed rate, ``connection`` (ONLINE, retained; the broker's last
will says the connection broke) and its ``factsheet`` (retained, and again on the instant
action ``factsheetRequest``).

``time_scale`` is simulated seconds per wall second (1: real time); 0 runs each order as fast
as it computes, publishing a state at every event (node reached, action started or ended).
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Any

from pickstop.fleet import mqtt
from pickstop.fleet import order as orders
from pickstop.fleet import vda5050 as v
from pickstop.fleet.vehicle import SimVehicle


class VehicleNode:
    def __init__(
        self,
        vehicle: SimVehicle,
        broker: mqtt.Broker,
        interface: str = mqtt.INTERFACE,
        rate_hz: float = 1.0,
        time_scale: float = 1.0,
    ) -> None:
        if rate_hz <= 0 or time_scale < 0:
            raise ValueError("rate_hz must be > 0 and time_scale >= 0")
        self.vehicle, self.rate_hz, self.time_scale = vehicle, rate_hz, time_scale
        self._connection_header = -1
        self._factsheet_header = -1

        def t(leaf: str) -> str:
            return mqtt.topic(
                interface, vehicle.version, vehicle.manufacturer, vehicle.serial_number, leaf
            )

        self.topics = {
            k: t(k) for k in ("order", "state", "connection", "factsheet", "instantActions")
        }
        self.link = mqtt.Link(
            broker, will=(self.topics["connection"], self._connection(v.BROKEN[vehicle.version]))
        )
        self.link.on_connect.append(self._online)
        self._inbox: queue.Queue[dict[str, Any]] = queue.Queue()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, name="pickstop-sim-vehicle", daemon=True)
        self.published = 0

    def _connection(self, state: str) -> dict[str, Any]:
        """A connection message (validated by the version's model)."""
        veh = self.vehicle
        self._connection_header += 1
        doc = {
            "headerId": self._connection_header,
            "timestamp": orders.timestamp(),
            "version": veh.version,
            "manufacturer": veh.manufacturer,
            "serialNumber": veh.serial_number,
            "connectionState": state,
        }
        return v.dump(v.CONNECTION_MODELS[veh.version].model_validate(doc))

    def _online(self) -> None:
        self.link.publish(self.topics["connection"], self._connection("ONLINE"), qos=1, retain=True)
        self.publish_factsheet()

    def publish_factsheet(self) -> None:
        self._factsheet_header += 1
        doc = self.vehicle.factsheet(self._factsheet_header)
        self.link.publish(self.topics["factsheet"], doc, qos=1, retain=True)

    def _instant(self, _topic: str, doc: dict[str, Any]) -> None:
        acts = doc.get("actions")
        if isinstance(acts, list) and any(
            isinstance(a, dict) and a.get("actionType") == "factsheetRequest" for a in acts
        ):
            self.publish_factsheet()

    def start(self) -> VehicleNode:
        self.link.subscribe(self.topics["order"], lambda _t, doc: self._inbox.put(doc))
        self.link.subscribe(self.topics["instantActions"], self._instant)
        self.link.start()
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)
        self.link.publish(
            self.topics["connection"], self._connection("OFFLINE"), qos=1, retain=True
        )
        self.link.stop()

    def publish_state(self) -> None:
        with self._lock:
            doc = self.vehicle.state()
        self.link.publish(self.topics["state"], doc)
        self.published += 1

    def _take_orders(self, wait: float) -> bool:
        try:
            doc = self._inbox.get(timeout=wait) if wait > 0 else self._inbox.get_nowait()
        except queue.Empty:
            return False
        with self._lock:
            self.vehicle.accept(doc)
        self.publish_state()  # acknowledges the order (or reports why it was refused)
        return True

    def _loop(self) -> None:
        period = 1.0 / self.rate_hz
        next_tick = time.monotonic()
        while not self._stop.is_set():
            veh = self.vehicle
            if self.time_scale == 0:
                while veh.busy and not self._stop.is_set():
                    with self._lock:
                        veh.advance(veh.next_event())
                    self.publish_state()
                    self._take_orders(0)
                if self._take_orders(max(0.0, next_tick - time.monotonic())):
                    continue
                self.publish_state()
                next_tick = time.monotonic() + period
                continue
            # real time (scaled): events inside a tick are published as they happen
            now = time.monotonic()
            if now >= next_tick:
                budget = period * self.time_scale
                while budget > 0 and veh.busy:
                    with self._lock:
                        step = min(budget, veh.next_event())
                        changed = veh.advance(step)
                    budget -= step
                    if changed:
                        self.publish_state()
                if budget > 0:
                    veh.clock += budget
                self.publish_state()
                next_tick += period
                if next_tick < now:
                    next_tick = now + period
            self._take_orders(max(0.0, min(next_tick - time.monotonic(), period)))
