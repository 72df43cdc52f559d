"""Send an order to a vehicle over MQTT and follow it to the end.

Before anything is sent, :func:`checked_order` reads the vehicle's ``factsheet`` (retained on
its topic; asked for with the instant action ``factsheetRequest`` if none is there), builds the
order with the action mapping of its vehicle type, and refuses it (:class:`VehicleRefusal`)
naming every action or parameter the factsheet does not list. The order goes to
``{interface}/{major}/{manufacturer}/{serial}/order``; the vehicle's ``state`` topic feeds an
:class:`OrderTracker`. Until a state names the order it is sent again every ``resend`` seconds
(QoS 0, as VDA 5050 recommends, may lose it, e.g. across a broker restart; a vehicle discards a
repeat of the order it runs).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from pickstop.errors import PickStopError
from pickstop.fleet import factsheet as fs
from pickstop.fleet import mqtt
from pickstop.fleet import order as orders
from pickstop.fleet import vda5050 as v
from pickstop.fleet.arrivals import Arrival
from pickstop.fleet.tracker import OrderTracker
from pickstop.fleet.vehicle_types import DEFAULT_PICK, PickAction, VehicleType, VehicleTypes

REFUSALS = ("orderError", "validationError", "orderUpdateError", "noRouteError")


def refusal(doc: dict[str, Any], order_id: str, since_sent: float) -> str | None:
    """Why a state says our order was refused, or None. An error naming the order (an
    ``orderId`` reference) counts at once; one naming none only a second after sending, since
    a state published before the vehicle read the order may carry an older order's error."""
    errors = doc.get("errors")
    why = []
    for e in errors if isinstance(errors, list) else []:
        if not isinstance(e, dict) or e.get("errorType") not in REFUSALS:
            continue
        raw = e.get("errorReferences")
        refs: list[Any] = raw if isinstance(raw, list) else []
        named = [r.get("referenceValue") for r in refs if isinstance(r, dict)
                 and r.get("referenceKey") == "orderId"]  # fmt: skip
        if order_id in named or (not named and since_sent > 1.0):
            why.append(str(e.get("errorDescription") or e.get("errorType")))
    return "; ".join(why) or None


class DispatchError(PickStopError):
    """The order did not complete (no vehicle, refused, timeout, cancelled)."""


class DispatchCancelled(DispatchError):
    """Whoever started the dispatch stopped following it."""


class VehicleRefusal(DispatchError):
    """The vehicle's factsheet says it cannot run the order; nothing was sent."""

    exit_code = 3

    def __init__(self, message: str, problems: list[str]) -> None:
        super().__init__(message, field="factsheet")
        self.problems = problems


class Dispatcher:
    """One MQTT connection following one vehicle; orders are run one after another."""

    def __init__(
        self,
        broker: mqtt.Broker,
        manufacturer: str,
        serial_number: str,
        version: str = "2.1.0",
        interface: str = mqtt.INTERFACE,
    ) -> None:
        mqtt.check_level("manufacturer", manufacturer)
        mqtt.check_level("serial_number", serial_number)
        mqtt.check_level("interface", interface)

        def t(leaf: str) -> str:
            return mqtt.topic(interface, version, manufacturer, serial_number, leaf)

        self.version, self.manufacturer, self.serial_number = version, manufacturer, serial_number
        self.topics = {
            k: t(k) for k in ("order", "state", "connection", "factsheet", "instantActions")
        }
        self.link = mqtt.Link(broker)
        self.tracker: OrderTracker | None = None
        self._cond = threading.Condition()
        self.vehicle_seen = threading.Event()
        self.connection: str | None = None
        self.refused: str | None = None  # why the vehicle refused the current order
        self._last_sent = 0.0  # [s] monotonic
        self._header = -1  # headerId of the last order message sent
        self._recorded = 0  # arrivals of the current order handed to ``record``
        self._factsheet: dict[str, Any] | None = None
        self._factsheet_seen = threading.Event()
        self.link.subscribe(self.topics["state"], self._on_state)
        self.link.subscribe(self.topics["connection"], self._on_connection, qos=1)
        self.link.subscribe(self.topics["factsheet"], self._on_factsheet, qos=1)

    def start(self) -> Dispatcher:
        self.link.start()
        return self

    def stop(self) -> None:
        self.link.stop()

    def _on_state(self, _topic: str, doc: dict[str, Any]) -> None:
        self.vehicle_seen.set()
        with self._cond:
            tr = self.tracker
            if tr is None:
                return
            if tr.update(doc):
                self._cond.notify_all()
            elif tr.acknowledged_at is None and self.refused is None:
                # Still on another order, with an error about an order: ours was refused.
                why = refusal(doc, tr.order.order_id, time.monotonic() - self._last_sent)
                if why:
                    self.refused = why
                    self._cond.notify_all()

    def _on_factsheet(self, _topic: str, doc: dict[str, Any]) -> None:
        self._factsheet = doc
        self._factsheet_seen.set()

    def read_factsheet(self, wait: float = 10.0, ask_after: float = 1.0) -> fs.Capabilities:
        """The vehicle's factsheet: the retained one, or the answer to a ``factsheetRequest``
        sent after ``ask_after`` [s]; DispatchError if none comes within ``wait`` [s]."""
        t_end = time.monotonic() + wait
        if not self._factsheet_seen.wait(min(ask_after, wait)):
            self._request_factsheet()
            self._factsheet_seen.wait(max(0.0, t_end - time.monotonic()))
        if self._factsheet is None:
            raise DispatchError(
                f"no factsheet on {self.topics['factsheet']} within {wait:.0f} s (a VDA 5050 "
                "2.0+ vehicle publishes one; dispatch without checking it with --no-factsheet)"
            )
        return fs.read(self._factsheet)

    def _request_factsheet(self) -> None:
        m, s = self.manufacturer, self.serial_number
        action = {"actionType": "factsheetRequest", "actionId": f"factsheet-{time.time_ns()}",
                  "blockingType": "NONE"}  # fmt: skip
        doc = {"headerId": 0, "timestamp": orders.timestamp(), "version": self.version,
               "manufacturer": m, "serialNumber": s, "actions": [action]}  # fmt: skip
        self.link.publish(self.topics["instantActions"],
                          v.dump(v.INSTANT_MODELS[self.version].model_validate(doc)))  # fmt: skip

    def _on_connection(self, _topic: str, doc: dict[str, Any]) -> None:
        self.connection = doc.get("connectionState")
        if self.connection == "ONLINE":
            self.vehicle_seen.set()

    def run(
        self,
        order: v.Order,
        timeout: float = 600.0,
        wait_vehicle: float = 10.0,
        resend: float = 2.0,
        progress: Callable[[dict[str, Any]], None] | None = None,
        cancelled: Callable[[], bool] | None = None,
        record: Callable[[Arrival], None] | None = None,
        pick: PickAction | None = None,
    ) -> dict[str, Any]:
        """Publish ``order``, follow it until done; returns the tracker's summary.
        ``record`` takes each arrival at a stop as its picks end (and, however the order
        ends, those still open); ``pick``: how the order names its picks (its vehicle type's)."""
        tr = OrderTracker(order, pick=pick or DEFAULT_PICK)
        with self._cond:
            self._recorded = 0
        try:
            return self._follow(order, tr, timeout, wait_vehicle, resend, progress, cancelled,
                                record)  # fmt: skip
        finally:
            if record is not None:
                with self._cond:
                    rest = tr.arrivals(final=True)[self._recorded :]
                for a in rest:
                    record(a)

    def _follow(
        self,
        order: v.Order,
        tr: OrderTracker,
        timeout: float,
        wait_vehicle: float,
        resend: float,
        progress: Callable[[dict[str, Any]], None] | None,
        cancelled: Callable[[], bool] | None,
        record: Callable[[Arrival], None] | None,
    ) -> dict[str, Any]:
        """Send ``order`` and follow ``tr`` until done: hand ``record`` each new arrival,
        ``progress`` the summary at most every 0.5 s, send the order again every ``resend``
        [s] until a state names it; raise if it is refused, cancelled or not done in
        ``timeout`` [s]. Returns the tracker's last summary."""
        doc, sent_at = self._send(order, tr, wait_vehicle)
        t_end = sent_at + timeout
        last_sent, last_report = sent_at, 0.0
        while True:
            with self._cond:
                if tr.done:
                    break
                self._cond.wait(0.1)
                done = tr.done
                summary = tr.summary() if progress else None
                fresh = tr.arrivals()[self._recorded :] if record is not None else []
                self._recorded += len(fresh)
            if record is not None:
                for a in fresh:
                    record(a)
            now = time.monotonic()
            if done:
                break
            self._check_going(order, tr, now > t_end, timeout, cancelled)
            if tr.acknowledged_at is None and now - last_sent > resend:
                doc = self._resend(doc)
                last_sent = self._last_sent = now
            if progress is not None and summary is not None and now - last_report > 0.5:
                progress(summary)
                last_report = now
        with self._cond:
            summary = tr.summary()
        if progress is not None:
            progress(summary)
        return summary

    def _send(
        self, order: v.Order, tr: OrderTracker, wait_vehicle: float
    ) -> tuple[dict[str, Any], float]:
        """Publish ``order`` once a vehicle is seen (within ``wait_vehicle`` [s]), ``tr``
        following it from now; returns the message sent and when [s, monotonic]."""
        if not self.vehicle_seen.wait(wait_vehicle):
            raise DispatchError(
                f"no vehicle on {self.topics['state']} (no state or ONLINE connection in "
                f"{wait_vehicle:.0f} s)"
            )
        doc = v.dump(order)
        self._header = max(self._header + 1, order.header_id)
        doc["headerId"] = self._header  # per topic, one more with every message sent
        with self._cond:
            self.tracker = tr
            self.refused = None
            tr.sent_at = sent_at = time.monotonic()
        self._last_sent = time.monotonic()
        self.link.publish(self.topics["order"], doc)
        return doc, sent_at

    def _resend(self, doc: dict[str, Any]) -> dict[str, Any]:
        """Publish the order message ``doc`` again, with the next header id and a new
        timestamp; returns the message sent."""
        self._header += 1
        doc = {**doc, "headerId": self._header, "timestamp": orders.timestamp()}
        self.link.publish(self.topics["order"], doc)
        return doc

    def _check_going(
        self,
        order: v.Order,
        tr: OrderTracker,
        overdue: bool,
        timeout: float,
        cancelled: Callable[[], bool] | None,
    ) -> None:
        """Raise if the vehicle refused ``order``, whoever follows it ``cancelled``, or it is
        ``overdue`` (not done in ``timeout`` [s])."""
        if self.refused is not None:
            raise DispatchError(f"the vehicle refused order {order.order_id}: {self.refused}")
        if cancelled is not None and cancelled():
            raise DispatchCancelled(f"order {order.order_id} cancelled")
        if overdue:
            raise DispatchError(
                f"order {order.order_id} not done after {timeout:.0f} s: "
                f"{len(tr.reached)}/{len(order.nodes)} nodes reached"
            )


#: ``build(pick) -> order``: the plan's order with a vehicle type's pick (None: PickStop's own)
BuildOrder = Callable[[PickAction | None], v.Order]


def checked_order(
    d: Dispatcher,
    build: BuildOrder,
    types: VehicleTypes | None = None,
    type_name: str | None = None,
    factsheet: bool = True,
    wait: float = 10.0,
) -> tuple[v.Order, VehicleType | None]:
    """The order to send ``d``'s vehicle and its vehicle type: read its factsheet (unless
    ``factsheet`` is False), choose the type (named, or the first matching the vehicle and its
    factsheet's series), build the order with its pick, and check it against the factsheet.
    Raises :class:`VehicleRefusal` naming every problem; nothing is sent."""
    caps = d.read_factsheet(wait) if factsheet else None
    manufacturer, serial = d.manufacturer, d.serial_number
    vt = (types or VehicleTypes()).select(
        manufacturer, serial, None if caps is None else caps.series_name, type_name
    )
    order = build(None if vt is None else vt.pick)
    if caps is not None:
        problems = fs.check_order(order, caps)
        if problems:
            who = f"{manufacturer}/{serial}" + (f" ({caps.series_name})" if caps.series_name
                                                  else "")  # fmt: skip
            kind = f" as vehicle type {vt.name!r}" if vt is not None else ""
            raise VehicleRefusal(
                f"vehicle {who} cannot run order {order.order_id}{kind}, by its factsheet: "
                + "; ".join(problems)
                + (
                    ""
                    if vt is not None
                    else " (a vehicle type maps PickStop's pick onto the "
                    "action the vehicle executes)"
                ),
                problems,
            )
    return order, vt
