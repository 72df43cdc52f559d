"""Progress of one order from the vehicle's VDA 5050 state messages (pure: no transport).

A state lists the nodes and edges still to traverse and the status of every action of the
order; the tracker turns each into: nodes reached, per-stop status, actions running, finished
or failed (with their result), errors, the vehicle's position, and whether the order is done.
States of another order, or older than one already seen (``headerId``), are ignored.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from pydantic import ValidationError

from pickstop.fleet import vda5050 as v

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
        if self.done and self.finished_at is None:
            self.finished_at = now
        return True

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
            "states": self.states,
            "latency": None
            if self.sent_at is None or self.acknowledged_at is None
            else self.acknowledged_at - self.sent_at,
        }
