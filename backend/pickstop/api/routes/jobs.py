"""``/jobs``: batch planning and database builds, with progress, result and cancel."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.schemas import API_PREFIX, BatchRequest, Job

router = APIRouter(tags=["jobs"])


def _missing(job_id: str) -> Problem:
    return Problem(404, "Not found", f"no job {job_id!r}", field="job_id")


@router.post(
    "/jobs/batch",
    dependencies=[WriteKey],
    status_code=202,
    openapi_extra=json_request("BatchRequest", "scenes to plan; each is checked before queueing"),
)
def batch(service: ServiceDep, doc: JsonBody, response: Response) -> Job:
    service.scenes.check_batch_size(doc)  # before validating 10,000 items
    service.scenes.precheck(doc)
    job = service.submit_batch(validate(BatchRequest, doc))
    response.headers["Location"] = f"{API_PREFIX}/jobs/{job['id']}"
    return Job.of(job)


@router.get("/jobs", dependencies=[ReadKey])
def jobs(
    service: ServiceDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
    offset: Annotated[int, Query(ge=0, le=10**9, description="records to skip")] = 0,
) -> list[Job]:
    return [Job.of(x) for x in service.store.jobs(limit, offset)]


@router.get("/jobs/{job_id}", dependencies=[ReadKey])
def job(service: ServiceDep, job_id: str) -> Job:
    row = service.store.job(job_id)
    if row is None:
        raise _missing(job_id)
    return Job.of(row)


@router.post("/jobs/{job_id}/cancel", dependencies=[WriteKey])
def cancel(service: ServiceDep, job_id: str) -> Job:
    """Cancel a job: a queued one never runs, a running one is stopped where it is."""
    row = service.jobs.cancel(job_id)
    if row is None:
        raise _missing(job_id)
    return Job.of(row)
