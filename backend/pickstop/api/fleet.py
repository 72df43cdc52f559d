"""The fleet documents of a stored plan, made off the event loop for ``/plans/{id}/export``
and ``/plans/{id}/dispatch``: a VDA 5050 order, a Nav2 goal or a LIF layout, and the job
spec that sends the order to a vehicle.

Tolerances are the plan's proven ones by default (``tolerances=verified``: each stop's checked
circle, ellipse and yaw window, proven once per plan, :mod:`pickstop.api.plan_proofs`), or
its inscribed radius and the scene's yaw error (``radius``).
"""

from __future__ import annotations

import json
from dataclasses import replace
from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from pickstop.api.problems import Problem

if TYPE_CHECKING:
    from pickstop.fleet.dispatch_job import DispatchJob

Level = Annotated[str, Field(min_length=1, max_length=100, pattern=r"^[^/+#]+$")]
Tolerances = Literal["verified", "radius"]
TOLERANCES = (
    "verified: each stop's circle (2.x), ellipse (3.0) and yaw window proven by the exact "
    "check with the robot's full geometry, proven on the plan's first use (seconds) and kept; "
    "radius: the plan's inscribed radius and the scene's yaw error, unproven off the grid"
)


class DispatchRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    manufacturer: Level = "pickstop"
    serial_number: Level = "sim-1"
    interface_name: Level = "uagv"
    vda_version: Literal["2.0", "2.1", "3.0"] = "2.1"
    map_id: Annotated[str, Field(min_length=1, max_length=100)] | None = None
    timeout: float = Field(default=600.0, gt=0, le=24 * 3600, description="[s]")
    wait_vehicle: float = Field(default=10.0, gt=0, le=600, description="[s]")
    vehicle_type: Annotated[str, Field(min_length=1, max_length=100)] | None = Field(
        default=None,
        description="a type of the service's vehicle types file (default: the first matching "
        "the vehicle and its factsheet)",
    )
    check_factsheet: bool = Field(
        default=True,
        description="read the vehicle's factsheet and refuse an order it cannot run before "
        "sending it (false: a vehicle older than VDA 5050 2.0)",
    )
    tolerances: Tolerances = Field(default="verified", description=TOLERANCES)


def vehicle_types(s: Any) -> Any:
    """The service's vehicle types (``PICKSTOP_VEHICLE_TYPES``), or none."""
    from pickstop.fleet.vehicle_types import VehicleTypes, load_vehicle_types

    path = s.settings.vehicle_types
    return VehicleTypes() if path is None else load_vehicle_types(path)


def stored_plan(s: Any, plan_id: str) -> tuple[Any, dict[str, Any]]:
    """The stored plan ``plan_id`` (a route plan) and its scene document; 404 if none."""
    from pickstop.fleet import route as rt

    row = s.store.plan(plan_id)
    if row is None:
        raise Problem(404, "Not found", f"no plan {plan_id!r}")
    return rt.load_plan(json.loads(row["doc"])), json.loads(row["scene_doc"])


def stop_tolerances(
    s: Any, plan_id: str, plan: Any, scene_doc: dict[str, Any], which: str
) -> tuple[Any, Any]:
    """(shapes, yaw tolerances) per stop as proven (``verified``), or (None, None): the plan's
    radius and the scene's yaw error."""
    if which != "verified":
        return None, None
    proof = s.proofs.proof(plan_id, plan, scene_doc)
    return proof.shapes, proof.yaw


def scene_yaws(scene_doc: dict[str, Any]) -> tuple[float | None, float | None]:
    """The scene's start and goal yaws [rad], None where it gives none."""

    def yaw(key: str) -> float | None:
        v = scene_doc.get(key) or {}
        return float(v["yaw"]) if isinstance(v, dict) and "yaw" in v else None

    return yaw("start"), yaw("goal")


def export_document(s: Any, plan_id: str, q: dict[str, Any]) -> tuple[str, str]:
    """The stored plan as ``q["format"]`` asks (vda5050, nav2 or lif): (body, media type)."""
    from pickstop.fleet import nav2

    plan, scene_doc = stored_plan(s, plan_id)
    start_yaw, goal_yaw = scene_yaws(scene_doc)
    shapes, yaw_tol = stop_tolerances(s, plan_id, plan, scene_doc, q["tolerances"])
    if q["format"] == "lif":
        return _lif(s, plan_id, q, plan, (start_yaw, goal_yaw), shapes), "application/json"
    if q["format"] == "vda5050":
        order = _vda5050(s, plan_id, q, plan, (start_yaw, goal_yaw), yaw_tol, shapes)
        return order, "application/json"
    doc = nav2.build_nav2(
        plan, q["map_id"] or "map", q["distro"], start_yaw, goal_yaw, yaw_tol, shapes
    )
    if q["nav2_format"] == "yaml":
        return nav2.dumps(doc, "yaml"), "application/yaml"
    return nav2.dumps(doc, "json"), "application/json"


def _lif(
    s: Any, plan_id: str, q: dict[str, Any], plan: Any, yaws: tuple[Any, Any], shapes: Any
) -> str:
    """The plan as a LIF layout (layoutId = the plan id), JSON."""
    from pickstop.fleet.lif import LifOptions, build_lif

    vt = vehicle_types(s).select(q["manufacturer"], q["serial_number"], None, q["vehicle_type"])
    man = q["manufacturer"]
    type_id = man if vt is None else f"{vt.manufacturer or man}.{vt.series_name or vt.name}"
    lif = LifOptions(
        vehicle_type_id=type_id,
        layout_id=plan_id,
        map_id=q["map_id"] or "map",
        start_yaw=yaws[0],
        goal_yaw=yaws[1],
        shapes=shapes,
        pick=None if vt is None else vt.pick,
    )
    return json.dumps(build_lif(plan, lif))


def _vda5050(
    s: Any,
    plan_id: str,
    q: dict[str, Any],
    plan: Any,
    yaws: tuple[Any, Any],
    yaw_tol: Any,
    shapes: Any,
) -> str:
    """The plan as a VDA 5050 order (orderId = the plan id), JSON."""
    from pickstop.fleet import order as orders
    from pickstop.fleet import vda5050 as v

    vt = vehicle_types(s).select(q["manufacturer"], q["serial_number"], None, q["vehicle_type"])
    opts = orders.OrderOptions(
        version=q["vda_version"],
        manufacturer=q["manufacturer"],
        serial_number=q["serial_number"],
        map_id=q["map_id"],
        order_id=plan_id,
        start_yaw=yaws[0],
        goal_yaw=yaws[1],
        yaw_tolerance=yaw_tol,
        shapes=shapes,
        pick=None if vt is None else vt.pick,
    )
    return json.dumps(v.dump(orders.build_order(plan, opts)))


def dispatch_job(s: Any, plan_id: str, body: DispatchRequest, order_id: str) -> DispatchJob:
    """What a dispatch job sends: the stored plan's order as ``order_id``, built once here so
    that bad options fail the request rather than the job."""
    from pickstop.fleet import order as orders
    from pickstop.fleet.dispatch_job import DispatchJob

    plan, scene_doc = stored_plan(s, plan_id)
    start_yaw, goal_yaw = scene_yaws(scene_doc)
    shapes, yaw_tol = stop_tolerances(s, plan_id, plan, scene_doc, body.tolerances)
    opts = orders.OrderOptions(
        version=body.vda_version,
        manufacturer=body.manufacturer,
        serial_number=body.serial_number,
        map_id=body.map_id,
        order_id=order_id,
        start_yaw=start_yaw,
        goal_yaw=goal_yaw,
        yaw_tolerance=yaw_tol,
        shapes=shapes,
    )
    orders.build_order(plan, opts)  # bad options fail the request, not the job
    types = vehicle_types(s)
    if body.vehicle_type is not None:
        types.select(body.manufacturer, body.serial_number, None, body.vehicle_type)
    return DispatchJob(
        build=lambda pick: orders.build_order(plan, replace(opts, pick=pick)),
        manufacturer=body.manufacturer,
        serial_number=body.serial_number,
        version=orders.version_of(body.vda_version),
        interface=body.interface_name,
        timeout=body.timeout,
        wait_vehicle=body.wait_vehicle,
        types=types,
        vehicle_type=body.vehicle_type,
        factsheet=body.check_factsheet,
    )
