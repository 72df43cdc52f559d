"""A plan as a VDA 5050 order (2.1.0 by default, 2.0.0 or 3.0.0 on request).

Nodes: start, every corner of the obstacle-aware floor path, each stop, goal; straight edges
join them. A docking leg (driven at a stop's fixed yaw where the base cannot turn) is an edge
with that ``orientation`` (GLOBAL; no rotation on it), between nodes carrying that ``theta``.
Node ``sequenceId`` s are even, edge ones odd, increasing along the route. Each stop
node carries ``allowedDeviationXY`` = its guaranteed radius (with checked shapes: the checked
circle in 2.x, the checked ellipse ``{a, b, theta}`` in 3.0), ``allowedDeviationTheta`` = the
yaw tolerance, and one blocking ``pick`` action per part (tray, part, grasp, and the witness arm
configuration with its joint names), or the action a vehicle type names for it
(:class:`~pickstop.fleet.vehicle_types.PickAction`). Everything is released (the base) unless
``release_stops`` keeps later stops in the horizon.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from pickstop.errors import InputError
from pickstop.fleet import route as rt
from pickstop.fleet import vda5050 as v
from pickstop.fleet.tolerance import StopShapes
from pickstop.fleet.vehicle_types import DEFAULT_PICK, PickAction
from pickstop.sequence import plan_model as pm


@dataclass(frozen=True)
class OrderOptions:
    version: str = "2.1.0"  # "2.0", "2.1", "3.0" (or with the patch: "2.1.0")
    manufacturer: str = "pickstop"
    serial_number: str = "sim-1"
    map_id: str | None = None  # default: "map"
    order_id: str | None = None  # default: derived from the plan
    order_update_id: int = 0
    header_id: int = 0
    timestamp: str | None = None  # default: now (UTC)
    release_stops: int | None = None  # release up to this many stops; None: all
    start_yaw: float | None = None  # [rad]
    goal_yaw: float | None = None  # [rad]
    yaw_tolerance: float | tuple[float, ...] | None = None  # [rad], one or one per stop
    pick: PickAction | None = None  # the vehicle type's pick; None: PickStop's own
    shapes: tuple[StopShapes, ...] | None = None  # per stop, checked (fleet.tolerance)


def version_of(text: str) -> v.VersionName:
    try:
        return v.VERSIONS[text]
    except KeyError:
        known = ", ".join(sorted(v.VERSIONS))
        raise InputError(
            f"vda_version: {text!r} is not a supported VDA 5050 version ({known})",
            field="vda_version",
        ) from None


def timestamp(t: datetime | None = None) -> str:
    """ISO 8601 in UTC with milliseconds and ``Z``, as the standard's examples."""
    t = t or datetime.now(UTC)
    return t.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


def order_id_of(plan: pm.Plan) -> str:
    """A stable order id: the same plan always gives the same id."""
    key = (plan.scene_hash, tuple((s.x, s.y, s.yaw) for s in plan.stops), tuple(plan.route))
    return "pickstop-" + hashlib.sha256(repr(key).encode()).hexdigest()[:16]


def pick_parameters(pick: rt.Pick, stop: int, action: PickAction) -> list[dict[str, Any]]:
    ours = {
        "stopIndex": stop,
        "trayId": pick.tray_id,
        "partId": pick.part_id,
        "graspIndex": pick.grasp_index,
        "jointNames": list(pick.joints),
        "jointPositions": [round(q, 6) for q in pick.theta],
    }
    return action.values(ours)


def action_id(order_id: str, stop: int, pick: rt.Pick) -> str:
    return f"{order_id}/stop{stop}/pick/{pick.tray_id}/{pick.part_id}"


def build_order(plan: pm.Plan, opts: OrderOptions | None = None) -> v.Order:
    """The plan's order message, validated by the version's model."""
    opts = opts or OrderOptions()
    version = version_of(opts.version)
    _check_options(opts)
    wps = rt.waypoints(plan, opts.start_yaw, opts.goal_yaw, opts.yaw_tolerance, opts.shapes)
    oid = opts.order_id or order_id_of(plan)
    map_id = opts.map_id or "map"
    last = _last_released(plan, wps, opts.release_stops)
    v3 = v.v3(version)
    act = opts.pick or DEFAULT_PICK
    nodes, edges = [], []
    for i, w in enumerate(wps):
        nodes.append(_node(i, w, oid, map_id, act, v3, released=i <= last))
        if i > 0:
            speed = plan.parameters.max_speed
            edges.append(_edge(i, wps[i - 1], w, speed, v3, released=i <= last))
    doc = {
        "headerId": opts.header_id,
        "timestamp": opts.timestamp or timestamp(),
        "version": version,
        "manufacturer": opts.manufacturer,
        "serialNumber": opts.serial_number,
        "orderId": oid,
        "orderUpdateId": opts.order_update_id,
        "nodes": nodes,
        "edges": edges,
    }
    return v.ORDER_MODELS[version].model_validate(doc)


def _check_options(opts: OrderOptions) -> None:
    """``release_stops`` not negative; the vehicle's names usable as topic levels."""
    if opts.release_stops is not None and opts.release_stops < 0:
        raise InputError("release_stops: must be >= 0", field="release_stops")
    for name in ("manufacturer", "serial_number"):
        value = getattr(opts, name)
        if not value or any(c in value for c in "/+#"):
            raise InputError(
                f"{name}: {value!r} must be non-empty without '/', '+' or '#' (a topic level)",
                field=name,
            )


def _last_released(plan: pm.Plan, wps: list[rt.Waypoint], release_stops: int | None) -> int:
    """The index of the last released waypoint: the base ends at the last released stop's
    node (or the goal when all are released)."""
    if release_stops is None or release_stops >= len(plan.stops):
        return len(wps) - 1
    if release_stops == 0:
        return 0
    return next(i for i, w in enumerate(wps) if w.stop == release_stops - 1)


def _node(
    i: int, w: rt.Waypoint, oid: str, map_id: str, act: PickAction, v3: bool, released: bool
) -> dict[str, Any]:
    """Waypoint ``i`` as an order node, with its picks as actions."""
    actions = [
        {
            "actionType": act.action_type,
            "actionId": action_id(oid, w.stop, p),
            ("actionDescriptor" if v3 else "actionDescription"): (
                f"pick {p.part_id} from {p.tray_id}"
            ),
            "blockingType": act.blocking_type,
            "actionParameters": pick_parameters(p, w.stop, act),
        }
        for p in w.picks
        if w.stop is not None
    ]
    via = "floor path corner" if w.yaw is None else "docking leg end: turn here"
    desc = {"start": "start", "via": via, "goal": "goal"}.get(
        w.kind, f"stop {w.stop}: trays {', '.join(sorted({p.tray_id for p in w.picks}))}"
    )
    return {
        "nodeId": w.id,
        "sequenceId": 2 * i,
        ("nodeDescriptor" if v3 else "nodeDescription"): desc,
        "released": released,
        "nodePosition": _node_position(w, map_id, v3),
        "actions": actions,
    }


def _node_position(w: rt.Waypoint, map_id: str, v3: bool) -> dict[str, Any]:
    """Where the node lies and its allowed deviations: a circle (2.x) or an ellipse (3.0)."""
    pos: dict[str, Any] = {"x": w.x, "y": w.y, "mapId": map_id}
    if w.yaw is not None:
        pos["theta"] = w.yaw
    if v3 and w.ellipse is not None:
        a, b, th = w.ellipse
        pos["allowedDeviationXY"] = {"a": a, "b": b, "theta": th}
    elif v3:
        pos["allowedDeviationXY"] = {"a": w.tolerance_xy, "b": w.tolerance_xy, "theta": 0.0}
    else:
        pos["allowedDeviationXY"] = w.tolerance_xy
    if w.tolerance_yaw is not None:
        pos["allowedDeviationTheta"] = w.tolerance_yaw
    return pos


def _edge(
    i: int, a: rt.Waypoint, w: rt.Waypoint, max_speed: float, v3: bool, released: bool
) -> dict[str, Any]:
    """The edge from waypoint ``a`` to waypoint ``i`` (``w``); max_speed [m/s]."""
    edge: dict[str, Any] = {
        "edgeId": f"{a.id}->{w.id}",
        "sequenceId": 2 * i - 1,
        "released": released,
        ("maximumSpeed" if v3 else "maxSpeed"): max_speed,
        "length": math.dist((a.x, a.y), (w.x, w.y)),
        "actions": [],
    }
    if w.hold_yaw is not None:  # a docking leg: driven straight at the stop's yaw
        edge |= {"orientation": w.hold_yaw, "orientationType": "GLOBAL"}
        edge |= {"reachOrientationBeforeEntering": True} if v3 else {"rotationAllowed": False}
    if not v3:
        edge |= {"startNodeId": a.id, "endNodeId": w.id}
    return edge


def check_order(order: v.Order) -> list[str]:
    """The standard's constraints beyond the schema; an empty list when all hold."""
    problems = []
    nodes: list[Any] = list(order.nodes)
    edges: list[Any] = list(order.edges)
    if not nodes:
        return ["the order has no nodes"]
    ids = [n.node_id for n in nodes]
    if len(set(ids)) != len(ids):
        problems.append("node ids are not unique")
    if len({e.edge_id for e in edges}) != len(edges):
        problems.append("edge ids are not unique")
    acts = [a.action_id for n in nodes for a in n.actions] + [
        a.action_id for e in edges for a in e.actions
    ]
    if len(set(acts)) != len(acts):
        problems.append("action ids are not unique")
    if any(n.sequence_id % 2 for n in nodes):
        problems.append("a node's sequenceId is odd")
    if any(e.sequence_id % 2 == 0 for e in edges):
        problems.append("an edge's sequenceId is even")
    seq = sorted([*nodes, *edges], key=lambda x: x.sequence_id)
    if [x.sequence_id for x in seq] != list(range(seq[0].sequence_id, seq[-1].sequence_id + 1)):
        problems.append("sequenceIds do not run consecutively from node to edge to node")
    if len(edges) != max(0, len(nodes) - 1):
        problems.append("edges do not join consecutive nodes")
    for e, a, b in zip(edges, nodes, nodes[1:], strict=False):
        if e.sequence_id != a.sequence_id + 1:
            problems.append(f"edge {e.edge_id} does not follow node {a.node_id}")
        start = getattr(e, "start_node_id", a.node_id)
        end = getattr(e, "end_node_id", b.node_id)
        if (start, end) != (a.node_id, b.node_id):
            problems.append(f"edge {e.edge_id} does not join {a.node_id} to {b.node_id}")
        if e.released and not (a.released and b.released):
            problems.append(f"edge {e.edge_id} is released but an end node is not")
    rel = [n.released for n in nodes]
    if rel and (not rel[0] or rel != sorted(rel, reverse=True)):
        problems.append("released nodes are not a prefix starting at the first node")
    if any(
        e.released != (a.released and b.released)
        for e, a, b in zip(edges, nodes, nodes[1:], strict=False)
    ):
        problems.append("an edge's released flag differs from its nodes'")
    for n in nodes:
        p = n.node_position
        if p is None:
            continue
        dev = p.allowed_deviation_xy
        if dev is not None:
            vals = [dev] if isinstance(dev, float | int) else [dev.a, dev.b]
            if any(x < 0 or not math.isfinite(x) for x in vals):
                problems.append(f"node {n.node_id}: negative allowedDeviationXY")
        if p.allowed_deviation_theta is not None and p.allowed_deviation_theta < 0:
            problems.append(f"node {n.node_id}: negative allowedDeviationTheta")
    return problems
