"""``/plans``: plan a stored or inline scene (synchronously, as a job, or as a preview), or
every order of a mix on it, and read stored plans (immutable)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response
from starlette.concurrency import run_in_threadpool

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.mixes import request_orders, store_mix
from pickstop.api.openapi import json_request
from pickstop.api.plan_bodies import record_body
from pickstop.api.problems import Problem
from pickstop.api.schemas import (
    API_PREFIX,
    Job,
    MixRecord,
    PlanRecord,
    PlanRequest,
    PlanSummary,
)
from pickstop.api.work import compute
from pickstop.store.records import now

router = APIRouter(tags=["plans"])

IMMUTABLE = {"Cache-Control": "public, max-age=31536000, immutable"}


@router.post(
    "/plans",
    dependencies=[WriteKey],
    status_code=201,
    openapi_extra=json_request("PlanRequest", "what to plan, and how"),
    responses={
        200: {"model": PlanRecord, "description": "a preview (store: false)"},
        201: {
            "model": PlanRecord | MixRecord,
            "description": "the stored plan, or with "
            "orders the stored mix (each order's plan stored as a plan)",
        },
        202: {"model": Job, "description": "queued as a job (mode: job)"},
    },
)
async def create_plan(
    request: Request, service: ServiceDep, doc: JsonBody, response: Response
) -> Any:
    body, prepared = await run_in_threadpool(_accept, service, doc)
    if body.orders is not None:
        return await _create_mix(request, service, body, prepared, response)
    if prepared is None:
        job = await run_in_threadpool(service.submit_plan_job, body)
        response.status_code = 202
        response.headers["Location"] = f"{API_PREFIX}/jobs/{job['id']}"
        return Job.of(job)
    scene_doc, revision, scene = prepared
    # The plan comes as its JSON, serialised once where it was made; the record around it is
    # assembled off the event loop.
    work = service.planning.preview_json if body.mode == "preview" else service.planning.plan_json
    plan_json = await compute(service.threads, work, scene, body.options, body.database,
                              deadline=service.settings.request_deadline,
                              request=request)  # fmt: skip
    options = body.options.model_dump()
    if not body.store:
        record = PlanRecord(id=None, scene_id=body.scene_id, scene_revision=revision,
                            created=now(), options=options)  # fmt: skip
        # (a few hundred bytes serialised and one copy of the plan's: no hop for that)
        return Response(record_body(record, plan_json), status_code=200,
                        media_type="application/json")  # fmt: skip
    rec = await run_in_threadpool(service.store.add_plan, body.scene_id, revision, scene_doc,
                                  options, plan_json)  # fmt: skip
    record = PlanRecord(id=rec["id"], scene_id=body.scene_id, scene_revision=revision,
                        created=rec["created"], options=options)  # fmt: skip
    return Response(record_body(record, plan_json), status_code=201, media_type="application/json",
                    headers={"Location": f"{API_PREFIX}/plans/{rec['id']}"})  # fmt: skip


def _accept(service: Any, doc: Any) -> tuple[PlanRequest, tuple[Any, int | None, Any] | None]:
    """The request checked in one go (one hop off the event loop): its size limits, its
    model, then (unless it is a job, checked when submitted) its scene and options."""
    service.scenes.precheck(doc)
    orders = doc.get("orders") if isinstance(doc, dict) else None
    limit = service.limits.max_orders
    if isinstance(orders, list) and len(orders) > limit:  # before validating 10,000 orders
        raise Problem(413, "Request too large", f"{len(orders)} orders exceed the limit of "
                      f"{limit}", kind="too-large", field="orders")  # fmt: skip
    body = validate(PlanRequest, doc)
    if body.mode == "job":
        return body, None
    if body.mode == "preview" and body.orders is not None:
        raise Problem(422, "Invalid request", "a mix is planned exactly: send mode 'sync' or "
                      "'job' with orders", field="mode")  # fmt: skip
    if body.mode == "preview" and body.store:
        raise Problem(422, "Invalid request", "a preview is never stored: send store: false "
                      "with mode: preview", field="store")  # fmt: skip
    return body, service.scenes.prepare(body)


async def _create_mix(
    request: Request,
    service: Any,
    body: PlanRequest,
    prepared: tuple[Any, int | None, Any] | None,
    response: Response,
) -> Any:
    """Every order of the request's mix planned (or queued as a job), stored unless
    ``store`` is false: a mix record."""
    if prepared is None:
        job = await run_in_threadpool(service.submit_mix_job, body)
        response.status_code = 202
        response.headers["Location"] = f"{API_PREFIX}/jobs/{job['id']}"
        return Job.of(job)
    scene_doc, revision, scene = prepared
    orders = await run_in_threadpool(request_orders, body.orders, scene, service.limits)
    mix = await compute(service.threads, service.planning.plan_mix, scene, orders, body.options,
                        body.database, deadline=service.settings.request_deadline,
                        request=request)  # fmt: skip
    record = await run_in_threadpool(store_mix, service.store, body.scene_id, revision,
                                     scene_doc, mix, body.store)  # fmt: skip
    out = MixRecord.model_validate(record)
    if record["id"] is None:
        return Response(out.model_dump_json(), status_code=200, media_type="application/json")
    return Response(out.model_dump_json(), status_code=201, media_type="application/json",
                    headers={"Location": f"{API_PREFIX}/mixes/{record['id']}"})  # fmt: skip


@router.get("/plans", dependencies=[ReadKey])
def plans(
    service: ServiceDep,
    scene_id: str | None = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
    offset: Annotated[int, Query(ge=0, le=10**9, description="records to skip")] = 0,
) -> list[PlanSummary]:
    return [PlanSummary.of(x) for x in service.store.plans(scene_id, limit, offset)]


@router.get(
    "/plans/{plan_id}",
    dependencies=[ReadKey],
    response_model=PlanRecord,
    responses={200: {"content": {"application/json": {}}}},
)
def get_plan(service: ServiceDep, plan_id: str, include_scene: bool = False) -> Response:
    body = service.bodies.body(plan_id, with_scene=include_scene)
    if body is None:
        raise Problem(404, "Not found", f"no plan {plan_id!r}", field="plan_id")
    return Response(body, media_type="application/json", headers=IMMUTABLE)
