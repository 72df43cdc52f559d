"""Fleet routes: a stored plan as a VDA 5050 order, a Nav2 goal or a LIF layout, and dispatch
over MQTT.

The broker is the service's (``PICKSTOP_MQTT_BROKER``), never the caller's: the API does not
connect wherever a request says. Tolerances are the plan's proven ones by default
(``tolerances=verified``: each stop's checked circle, ellipse and yaw window, proven once per
plan, :mod:`pickstop.api.plan_proofs`), or its inscribed radius and the scene's yaw error
(``radius``).
"""

from __future__ import annotations

import json
import secrets
from dataclasses import replace
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request, Response
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem, from_error
from pickstop.api.work import compute
from pickstop.errors import PickStopError

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


def _vehicle_types(s: Any) -> Any:
    """The service's vehicle types (``PICKSTOP_VEHICLE_TYPES``), or none."""
    from pickstop.fleet.vehicle_types import VehicleTypes, load_vehicle_types

    path = s.settings.vehicle_types
    return VehicleTypes() if path is None else load_vehicle_types(path)


def _job_record(row: dict[str, Any]) -> dict[str, Any]:
    """A job row as ``GET /jobs/{id}`` answers it (params and result decoded)."""
    return {
        **row,
        "params": json.loads(row["params"]),
        "result": json.loads(row["result"]) if row.get("result") else None,
    }


def _stored(s: Any, plan_id: str) -> tuple[Any, dict[str, Any]]:
    from pickstop.fleet import route as rt

    row = s.store.plan(plan_id)
    if row is None:
        raise Problem(404, "Not found", f"no plan {plan_id!r}")
    return rt.load_plan(json.loads(row["doc"])), json.loads(row["scene_doc"])


def _tolerances(
    s: Any, plan_id: str, plan: Any, scene_doc: dict[str, Any], which: str
) -> tuple[Any, Any]:
    """(shapes, yaw tolerances) per stop as proven (``verified``), or (None, None): the plan's
    radius and the scene's yaw error."""
    if which != "verified":
        return None, None
    proof = s.proofs.proof(plan_id, plan, scene_doc)
    return proof.shapes, proof.yaw


def _yaws(scene_doc: dict[str, Any]) -> tuple[float | None, float | None]:
    def yaw(key: str) -> float | None:
        v = scene_doc.get(key) or {}
        return float(v["yaw"]) if isinstance(v, dict) and "yaw" in v else None

    return yaw("start"), yaw("goal")


def _export(s: Any, plan_id: str, q: dict[str, Any]) -> tuple[str, str]:
    from pickstop.fleet import nav2
    from pickstop.fleet import order as orders
    from pickstop.fleet import vda5050 as v

    plan, scene_doc = _stored(s, plan_id)
    start_yaw, goal_yaw = _yaws(scene_doc)
    shapes, yaw_tol = _tolerances(s, plan_id, plan, scene_doc, q["tolerances"])
    if q["format"] == "lif":
        from pickstop.fleet.lif import LifOptions, build_lif

        vt = _vehicle_types(s).select(
            q["manufacturer"], q["serial_number"], None, q["vehicle_type"]
        )
        man = q["manufacturer"]
        type_id = man if vt is None else f"{vt.manufacturer or man}.{vt.series_name or vt.name}"
        lif = LifOptions(
            vehicle_type_id=type_id,
            layout_id=plan_id,
            map_id=q["map_id"] or "map",
            start_yaw=start_yaw,
            goal_yaw=goal_yaw,
            shapes=shapes,
            pick=None if vt is None else vt.pick,
        )
        return json.dumps(build_lif(plan, lif)), "application/json"
    if q["format"] == "vda5050":
        vt = _vehicle_types(s).select(
            q["manufacturer"], q["serial_number"], None, q["vehicle_type"]
        )
        opts = orders.OrderOptions(
            version=q["vda_version"],
            manufacturer=q["manufacturer"],
            serial_number=q["serial_number"],
            map_id=q["map_id"],
            order_id=plan_id,
            start_yaw=start_yaw,
            goal_yaw=goal_yaw,
            yaw_tolerance=yaw_tol,
            shapes=shapes,
            pick=None if vt is None else vt.pick,
        )
        return json.dumps(v.dump(orders.build_order(plan, opts))), "application/json"
    doc = nav2.build_nav2(
        plan, q["map_id"] or "map", q["distro"], start_yaw, goal_yaw, yaw_tol, shapes
    )
    if q["nav2_format"] == "yaml":
        return nav2.dumps(doc, "yaml"), "application/yaml"
    return nav2.dumps(doc, "json"), "application/json"


def add_fleet_routes(r: APIRouter, W: list[Any], R: list[Any]) -> None:
    """Add the fleet routes to ``r``; ``W`` / ``R``: the write and read key dependencies."""

    def svc(request: Request) -> Any:
        return request.app.state.service

    @r.get(
        "/plans/{plan_id}/export",
        tags=["fleet"],
        dependencies=R,
        responses={200: {"description": "the order or goal: JSON, or YAML for nav2_format=yaml",
                         "content": {"application/json": {"schema": {"type": "object"}},
                                     "application/yaml": {"schema": {"type": "object"}}}}},
    )  # fmt: skip
    async def export_plan(
        request: Request,
        plan_id: str,
        format: Literal["vda5050", "nav2", "lif"] = "vda5050",
        vda_version: Literal["2.0", "2.1", "3.0"] = "2.1",
        manufacturer: Annotated[
            str, Query(min_length=1, max_length=100, pattern=r"^[^/+#]+$")
        ] = "pickstop",
        serial_number: Annotated[
            str, Query(min_length=1, max_length=100, pattern=r"^[^/+#]+$")
        ] = "sim-1",
        map_id: Annotated[str | None, Query(min_length=1, max_length=100)] = None,
        nav2_format: Literal["json", "yaml"] = "json",
        distro: Literal["humble", "jazzy", "kilted"] = "jazzy",
        vehicle_type: Annotated[str | None, Query(min_length=1, max_length=100)] = None,
        tolerances: Annotated[Tolerances, Query(description=TOLERANCES)] = "verified",
    ) -> Response:
        """The plan as a VDA 5050 order (orderId = the plan id), a Nav2 goal or a LIF 2.0
        layout (layoutId = the plan id, a station per stop); the pick as the vehicle type
        names it (``vehicle_type``, or the first matching the vehicle); the stops'
        tolerances proven (``tolerances=verified``) or the plan's radius."""
        q = dict(format=format, vda_version=vda_version, manufacturer=manufacturer,
                 serial_number=serial_number, map_id=map_id, nav2_format=nav2_format,
                 distro=distro, vehicle_type=vehicle_type, tolerances=tolerances)  # fmt: skip
        s = svc(request)
        try:
            deadline = s.settings.request_deadline
            body, media = await compute(
                s.threads, _export, s, plan_id, q, deadline=deadline, request=request
            )
        except PickStopError as e:
            raise from_error(e) from None
        return Response(body, media_type=media)

    @r.post(
        "/plans/{plan_id}/dispatch",
        tags=["fleet"],
        dependencies=W,
        status_code=202,
        openapi_extra=json_request("DispatchRequest", "the vehicle and the order's options"),
    )
    async def dispatch_plan(
        request: Request, response: Response, plan_id: str, doc: JsonBody
    ) -> dict[str, Any]:
        """Send the plan's order to a vehicle over the service's MQTT broker, as a job whose
        record follows the order (nodes reached, picks running, finished, failed)."""
        from pickstop.fleet import mqtt
        from pickstop.fleet import order as orders
        from pickstop.fleet.dispatch_job import DispatchJob, start_dispatch_job

        body = await run_in_threadpool(validate, DispatchRequest, doc)
        s = svc(request)
        configured = s.settings.mqtt_broker
        if not configured:
            raise Problem(
                409,
                "No broker",
                "this service has no MQTT broker configured (PICKSTOP_MQTT_BROKER)",
                field="broker",
            )

        # Each dispatch is an order of its own: a vehicle takes the same order id again as a
        # repeat of the order it ran, and does nothing.
        order_id = f"{plan_id}-{secrets.token_hex(4)}"

        def prepare() -> DispatchJob:
            plan, scene_doc = _stored(s, plan_id)
            start_yaw, goal_yaw = _yaws(scene_doc)
            shapes, yaw_tol = _tolerances(s, plan_id, plan, scene_doc, body.tolerances)
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
            types = _vehicle_types(s)
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

        try:
            broker = mqtt.parse_broker(configured)
            job_spec = await compute(s.threads, prepare, deadline=s.settings.request_deadline,
                                     request=request)  # fmt: skip
        except PickStopError as e:
            raise from_error(e) from None
        params = {"plan_id": plan_id, **body.model_dump(), "order_id": order_id}
        job = await run_in_threadpool(s.store.add_job, "dispatch", params)
        start_dispatch_job(
            s.store.set_job, job["id"], job_spec, broker, lambda: s.jobs.cancelled(job["id"])
        )
        response.headers["Location"] = f"/api/v1/jobs/{job['id']}"
        return _job_record(await run_in_threadpool(s.store.job, job["id"]))
