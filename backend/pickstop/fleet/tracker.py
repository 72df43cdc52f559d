"""Progress of one order from the vehicle's VDA 5050 state messages (pure: no transport).

A state lists the nodes and edges still to traverse and the status of every action of the
order; the tracker turns each into: nodes reached, per-stop status, actions running, finished
or failed (with their result), errors, the vehicle's position, and whether the order is done.
States of another order, or older than one already seen (``headerId``), are ignored. At each
stop node (a node with actions) it notes the arrival (:mod:`pickstop.fleet.arrivals`): the
pose reported in the first state whose ``lastNodeId`` is the node while not driving.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from pydantic import ValidationError

from pickstop.fleet import vda5050 as v
from pickstop.fleet.arrivals import Arrival, PickOutcome, Pose
from pickstop.fleet.vehicle_types import DEFAULT_PICK, PickAction

DONE_ACTION = ("FINISHED", "FAILED")


@dataclass
class OrderTracker:
    order: v.Order
    sent_at: float | None = None  # [s] monotonic time the order was published
    acknowledged_at: float | None = None  # first state naming the order
    states: int = 0  # states of this order taken
    ignored: int = 0  # other orders', stale or malformed
    last_header: int = -1
    reached: list[str] = field(default_factory=list)
    actions: dict[str, dict[str, Any]] = field(default_factory=dict)
    errors: list[dict[str, Any]] = field(default_factory=list)
    position: dict[str, float] | None = None
    driving: bool = False
    pending_nodes: int | None = None
    pending_edges: int | None = None
    finished_at: float | None = None
    pick: PickAction = DEFAULT_PICK  # how the order's picks name their tray and part
    #: node id -> (reported pose, state timestamp) of each stop node the vehicle stood at
    landed: dict[str, tuple[Pose, str]] = field(default_factory=dict)

    @property
    def done(self) -> bool:
        """Every node traversed and every action finished or failed."""
        return (
            self.pending_nodes == 0
            and self.pending_edges == 0
            and not self.driving
            and len(self.actions) == sum(len(n.actions) for n in self.order.nodes)
            and all(a["status"] in DONE_ACTION for a in self.actions.values())
        )

    def update(self, doc: dict[str, Any], now: float | None = None) -> bool:
        """Take one state message; True if it belonged to this order and was new."""
        now = time.monotonic() if now is None else now
        model = v.STATE_MODELS[self.order.version if self.order.version in v.STATE_MODELS
                               else "2.1.0"]  # fmt: skip
        try:
            st = model.model_validate(doc)
        except ValidationError:
            self.ignored += 1
            return False
        if st.order_id != self.order.order_id or st.header_id <= self.last_header:
            self.ignored += 1
            return False
        self.last_header = st.header_id
        self.states += 1
        if self.acknowledged_at is None:
            self.acknowledged_at = now
        pending = {n.node_id for n in st.node_states}
        self.reached = [
            n.node_id
            for n in self.order.nodes
            if n.node_id not in pending and n.sequence_id <= st.last_node_sequence_id
        ]
        self.pending_nodes = len(st.node_states)
        self.pending_edges = len(st.edge_states)
        self.driving = st.driving
        known = {a.action_id for n in self.order.nodes for a in n.actions}
        for a in st.action_states:
            if a.action_id in known:
                result = getattr(a, "result_description", None) or getattr(a, "action_result", None)
                self.actions[a.action_id] = {"status": a.action_status, "result": result}
        self.errors = [
            e.model_dump(mode="json", by_alias=True, exclude_none=True) for e in st.errors
        ]
        pos = st.mobile_robot_position if isinstance(st, v.State30) else st.agv_position
        if pos is not None:
            self.position = {"x": pos.x, "y": pos.y, "theta": pos.theta}
            at = st.last_node_id
            if not st.driving and at not in self.landed and at in self._stop_nodes:
                self.landed[at] = (Pose(x=pos.x, y=pos.y, theta=pos.theta), st.timestamp)
        if self.done and self.finished_at is None:
            self.finished_at = now
        return True

    def __post_init__(self) -> None:
        self._stop_nodes = {n.node_id for n in self.order.nodes if n.actions}

    def arrivals(self, final: bool = False) -> list[Arrival]:
        """The arrivals at stop nodes whose picks have all ended, in order; ``final``: also
        those the vehicle stood at whose picks had not (the order ended or was given up)."""
        out = []
        stops = [n for n in self.order.nodes if n.actions]
        for k, n in enumerate(stops):
            if n.node_id not in self.landed:
                continue
            acts = [(a, self.actions.get(a.action_id, {})) for a in n.actions]
            ended = all(s.get("status") in DONE_ACTION for _, s in acts)
            if not (ended or final):
                continue
            picks = []
            for a, s in acts:
                ours = self.pick.ours({q.key: q.value for q in a.action_parameters or []})
                picks.append(
                    PickOutcome(
                        action_id=a.action_id,
                        tray_id=None if ours.get("trayId") is None else str(ours["trayId"]),
                        part_id=None if ours.get("partId") is None else str(ours["partId"]),
                        status=s.get("status", "WAITING"),
                        result=s.get("result"),
                    )
                )
            pose, stamp = self.landed[n.node_id]
            p = n.node_position
            if p is None:
                continue  # nothing planned to compare with
            out.append(
                Arrival(
                    order_id=self.order.order_id,
                    node_id=n.node_id,
                    sequence_id=n.sequence_id,
                    stop=k,
                    trays=sorted({q.tray_id for q in picks if q.tray_id is not None}),
                    manufacturer=self.order.manufacturer,
                    serial_number=self.order.serial_number,
                    map_id=p.map_id,
                    planned=Pose(x=p.x, y=p.y, theta=p.theta),
                    reported=pose,
                    time=stamp,
                    picks=picks,
                    ok=all(q.status == "FINISHED" for q in picks),
                )
            )
        return out

    def stops(self) -> list[dict[str, Any]]:
        """Per stop node: reached, and the status of its picks (pending, running, finished,
        failed)."""
        out = []
        for n in self.order.nodes:
            if not n.actions:
                continue
            sts = [self.actions.get(a.action_id, {}).get("status", "WAITING") for a in n.actions]
            if "FAILED" in sts and all(s in DONE_ACTION for s in sts):
                status = "failed"
            elif all(s == "FINISHED" for s in sts):
                status = "finished"
            elif n.node_id in self.reached:
                status = "running"
            else:
                status = "pending"
            pos = n.node_position
            out.append(
                {
                    "node_id": n.node_id,
                    "x": None if pos is None else pos.x,
                    "y": None if pos is None else pos.y,
                    "reached": n.node_id in self.reached,
                    "status": status,
                    "failed": [
                        {"action_id": a.action_id, "result": self.actions[a.action_id]["result"]}
                        for a in n.actions
                        if self.actions.get(a.action_id, {}).get("status") == "FAILED"
                    ],
                }
            )
        return out

    def summary(self) -> dict[str, Any]:
        """What a job record or the planner shows."""
        statuses = [a["status"] for a in self.actions.values()]
        n_actions = sum(len(n.actions) for n in self.order.nodes)
        return {
            "order_id": self.order.order_id,
            "done": self.done,
            "nodes": len(self.order.nodes),
            "nodes_reached": len(self.reached),
            "reached": self.reached,
            "actions": n_actions,
            "actions_finished": statuses.count("FINISHED"),
            "actions_failed": statuses.count("FAILED"),
            "actions_running": statuses.count("RUNNING") + statuses.count("INITIALIZING"),
            "stops": self.stops(),
            "errors": self.errors,
            "position": self.position,
            "arrivals": [a.model_dump(mode="json", exclude_none=True) for a in self.arrivals()],
            "states": self.states,
            "latency": None
            if self.sent_at is None or self.acknowledged_at is None
            else self.acknowledged_at - self.sent_at,
        }
