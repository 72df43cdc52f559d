"""Fleet routes: a stored plan as a VDA 5050 order, a Nav2 goal or a LIF layout, and dispatch
over MQTT (the documents themselves: :mod:`pickstop.api.fleet`).

The broker is the service's (``PICKSTOP_MQTT_BROKER``), never the caller's: the API does not
connect wherever a request says.
"""

from __future__ import annotations

import json
import secrets
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request, Response
from starlette.concurrency import run_in_threadpool

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.fleet import (
    TOLERANCES,
    DispatchRequest,
    Tolerances,
    dispatch_job,
    export_document,
)
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem, from_error
from pickstop.api.work import compute
from pickstop.errors import PickStopError

# Under both headings of the API docs: these act on a stored plan.
router = APIRouter(tags=["plans", "fleet"])

LevelQuery = Annotated[str, Query(min_length=1, max_length=100, pattern=r"^[^/+#]+$")]


@router.get(
    "/plans/{plan_id}/export",
    dependencies=[ReadKey],
    responses={200: {"description": "the order or goal: JSON, or YAML for nav2_format=yaml",
                     "content": {"application/json": {"schema": {"type": "object"}},
                                 "application/yaml": {"schema": {"type": "object"}}}}},
)  # fmt: skip
async def export_plan(
    request: Request,
    service: ServiceDep,
    plan_id: str,
    format: Literal["vda5050", "nav2", "lif"] = "vda5050",
    vda_version: Literal["2.0", "2.1", "3.0"] = "2.1",
    manufacturer: LevelQuery = "pickstop",
    serial_number: LevelQuery = "sim-1",
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
    try:
        body, media = await compute(service.threads, export_document, service, plan_id, q,
                                    deadline=service.settings.request_deadline,
                                    request=request)  # fmt: skip
    except PickStopError as e:
        raise from_error(e) from None
    return Response(body, media_type=media)


@router.post(
    "/plans/{plan_id}/dispatch",
    dependencies=[WriteKey],
    status_code=202,
    openapi_extra=json_request("DispatchRequest", "the vehicle and the order's options"),
)
async def dispatch_plan(
    request: Request, service: ServiceDep, response: Response, plan_id: str, doc: JsonBody
) -> dict[str, Any]:
    """Send the plan's order to a vehicle over the service's MQTT broker, as a job whose
    record follows the order (nodes reached, picks running, finished, failed)."""
    from pickstop.fleet import mqtt
    from pickstop.fleet.dispatch_job import start_dispatch_job

    body = await run_in_threadpool(validate, DispatchRequest, doc)
    configured = service.settings.mqtt_broker
    if not configured:
        raise Problem(409, "No broker", "this service has no MQTT broker configured "
                      "(PICKSTOP_MQTT_BROKER)", field="broker")  # fmt: skip
    # Each dispatch is an order of its own: a vehicle takes the same order id again as a
    # repeat of the order it ran, and does nothing.
    order_id = f"{plan_id}-{secrets.token_hex(4)}"
    try:
        broker = mqtt.parse_broker(configured)
        job_spec = await compute(service.threads, dispatch_job, service, plan_id, body, order_id,
                                 deadline=service.settings.request_deadline,
                                 request=request)  # fmt: skip
    except PickStopError as e:
        raise from_error(e) from None
    params = {"plan_id": plan_id, **body.model_dump(), "order_id": order_id}
    job = await run_in_threadpool(service.store.add_job, "dispatch", params)
    token = service.jobs.token(job["id"])
    start_dispatch_job(service.store.set_job, job["id"], job_spec, broker,
                       lambda: token.cancelled)  # fmt: skip
    response.headers["Location"] = f"/api/v1/jobs/{job['id']}"
    return _job_record(await run_in_threadpool(service.store.job, job["id"]))


def _job_record(row: dict[str, Any]) -> dict[str, Any]:
    """A job row as ``GET /jobs/{id}`` answers it (params and result decoded)."""
    return {
        **row,
        "params": json.loads(row["params"]),
        "result": json.loads(row["result"]) if row.get("result") else None,
    }
