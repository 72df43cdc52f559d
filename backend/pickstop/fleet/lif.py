"""A plan as a LIF (Layout Interchange Format, VDMA) 2.0 layout: its stops as stations.

One layout holds the route as a track: a node per waypoint (start, floor-path corners, stops,
goal; :func:`pickstop.fleet.route.waypoints`) and an edge between consecutive ones. Each stop is
a station whose one interaction node is the stop's pose: the node's ``theta`` is the stop's yaw,
its actions are the picks (one ``REQUIRED`` action per part, the vehicle type's action type and
parameters as in the VDA 5050 order; values other than text as JSON text, the schema's
type for them), and the edge arriving at it carries the stop's
``allowedDeviationXY`` (the schema holds it on edges only): its checked ellipse where shapes
were checked (:mod:`pickstop.fleet.tolerance`), else the circle of its guaranteed radius
(``a = b``, ``theta = 0``, as LIF asks for a circle). A docking leg's edge holds the stop's yaw
(``GLOBAL``, reached before entering). LIF has no yaw tolerance on a node: the VDA 5050 order
carries it.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

from pickstop.errors import InputError
from pickstop.fleet import order as orders
from pickstop.fleet import route as rt
from pickstop.fleet.tolerance import StopShapes
from pickstop.fleet.vehicle_types import DEFAULT_PICK, PickAction
from pickstop.sequence import plan_model as pm

LIF_VERSION = "2.0.0"


@dataclass(frozen=True)
class LifOptions:
    vehicle_type_id: str = "pickstop.sim"  # [factsheet.manufacturer].[factsheet.seriesName]
    project: str = "pickstop"
    creator: str = "pickstop"
    layout_id: str | None = None  # default: the plan's order id
    map_id: str = "map"
    timestamp: str | None = None  # default: now (UTC)
    start_yaw: float | None = None  # [rad]
    goal_yaw: float | None = None  # [rad]
    shapes: Sequence[StopShapes] | None = None  # per stop, checked
    pick: PickAction | None = None  # the vehicle type's pick; None: PickStop's own


def _text(value: Any) -> str:
    """An action parameter's value as the LIF 2.0 schema types it: a string (JSON text for a
    number, list or flag)."""
    return value if isinstance(value, str) else json.dumps(value)


def _deviation(w: rt.Waypoint) -> dict[str, float]:
    a, b, th = w.ellipse if w.ellipse is not None else (w.tolerance_xy, w.tolerance_xy, 0.0)
    return {"a": a, "b": b, "theta": th}


def _node(w: rt.Waypoint, opts: LifOptions, layout: str, act: PickAction) -> dict[str, Any]:
    prop: dict[str, Any] = {"vehicleTypeId": opts.vehicle_type_id}
    if w.yaw is not None:
        prop["theta"] = w.yaw
    if w.stop is not None:
        prop["actions"] = [
            {
                "actionType": act.action_type,
                "actionDescription": f"pick {p.part_id} from {p.tray_id}",
                "requirementType": "REQUIRED",
                "blockingType": act.blocking_type,
                "actionParameters": [
                    {"key": kv["key"], "value": _text(kv["value"])}
                    for kv in orders.pick_parameters(p, w.stop, act)
                ],
            }
            for p in w.picks
        ]
    name = w.id if w.stop is None else f"stop {w.stop}"
    return {
        "nodeId": f"{layout}/{w.id}",
        "nodeName": name,
        "mapId": opts.map_id,
        "nodePosition": {"x": w.x, "y": w.y},
        "vehicleTypeNodeProperties": [prop],
    }


def _edge(a: rt.Waypoint, b: rt.Waypoint, opts: LifOptions, layout: str, speed: float) -> Any:
    prop: dict[str, Any] = {"vehicleTypeId": opts.vehicle_type_id, "maxSpeed": speed}
    if b.hold_yaw is not None:  # a docking leg: driven straight at the stop's yaw
        prop |= {"vehicleOrientations": [b.hold_yaw], "orientationType": "GLOBAL",
                 "reachOrientationBeforeEntering": True}  # fmt: skip
    if b.kind == "stop":
        prop["allowedDeviationXY"] = _deviation(b)
    return {
        "edgeId": f"{layout}/{a.id}->{b.id}",
        "startNodeId": f"{layout}/{a.id}",
        "endNodeId": f"{layout}/{b.id}",
        "vehicleTypeEdgeProperties": [prop],
    }


def build_lif(plan: pm.Plan, opts: LifOptions | None = None) -> dict[str, Any]:
    """The plan's LIF document: one layout, its route as nodes and edges, a station per stop."""
    opts = opts or LifOptions()
    for name in ("vehicle_type_id", "project", "creator", "map_id"):
        if not getattr(opts, name):
            raise InputError(f"{name}: must be non-empty", field=name)
    wps = rt.waypoints(plan, opts.start_yaw, opts.goal_yaw, None, opts.shapes)
    layout = opts.layout_id or orders.order_id_of(plan)
    act = opts.pick or DEFAULT_PICK
    speed = plan.parameters.max_speed
    stations = [
        {
            "stationId": f"{layout}/station{w.stop}",
            "interactionNodeIds": [f"{layout}/{w.id}"],
            "stationName": f"stop {w.stop}",
            "stationDescription": "trays " + ", ".join(sorted({p.tray_id for p in w.picks})),
            "stationPosition": {"x": w.x, "y": w.y, "theta": w.yaw},
        }
        for w in wps
        if w.stop is not None
    ]
    return {
        "metaInformation": {
            "projectIdentification": opts.project,
            "creator": opts.creator,
            "exportTimestamp": opts.timestamp or orders.timestamp(),
            "lifVersion": LIF_VERSION,
        },
        "layouts": [
            {
                "layoutId": layout,
                "layoutName": f"plan {plan.scene_hash[:12]}",
                "layoutVersion": "1",
                "layoutDescription": f"{len(plan.stops)} stops planned by pickstop",
                "nodes": [_node(w, opts, layout, act) for w in wps],
                "edges": [_edge(a, b, opts, layout, speed) for a, b in pairwise(wps)],
                "stations": stations,
            }
        ],
    }
