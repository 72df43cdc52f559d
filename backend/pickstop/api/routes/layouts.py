"""``/layouts``: suggested moves of trays for a mix, searched as a job."""

from __future__ import annotations

from fastapi import APIRouter, Response
from starlette.concurrency import run_in_threadpool

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.schemas import API_PREFIX, Job, LayoutRequest

router = APIRouter(tags=["jobs"])


@router.post(
    "/layouts",
    dependencies=[WriteKey],
    status_code=202,
    openapi_extra=json_request("LayoutRequest", "the scene, its mix and the trays that may move"),
)
async def create_layout(service: ServiceDep, doc: JsonBody, response: Response) -> Job:
    """Queue a layout search (checked first): its job reports progress, can be cancelled, and
    its result is the layout document, every suggestion's figures from exact verified plans."""
    body = await run_in_threadpool(validate, LayoutRequest, doc)
    job = await run_in_threadpool(service.submit_layout, body)
    response.headers["Location"] = f"{API_PREFIX}/jobs/{job['id']}"
    return Job.of(job)
