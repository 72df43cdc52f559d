"""``/databases``: reachability databases (list, inspect, delete) and build jobs."""

from __future__ import annotations

from fastapi import APIRouter, Response

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.schemas import API_PREFIX, BuildRequest, DatabaseInfo, Job
from pickstop.store.reach_catalog import list_databases

router = APIRouter(tags=["databases"])


def _missing(db_id: str) -> Problem:
    return Problem(404, "Not found", f"no reachability database {db_id!r}", field="db_id")


@router.get("/databases", dependencies=[ReadKey])
def databases(service: ServiceDep, robot: str | None = None) -> list[DatabaseInfo]:
    return [DatabaseInfo.of(x) for x in list_databases(service.data_dir, robot)]


@router.get("/databases/{db_id}", dependencies=[ReadKey])
def database(service: ServiceDep, db_id: str) -> DatabaseInfo:
    for x in list_databases(service.data_dir):
        if x["id"] == db_id:
            return DatabaseInfo.of(x)
    raise _missing(db_id)


@router.delete("/databases/{db_id}", dependencies=[WriteKey], status_code=204)
def delete_database(service: ServiceDep, db_id: str) -> Response:
    if not service.delete_database(db_id):
        raise _missing(db_id)
    return Response(status_code=204)


@router.post(
    "/databases",
    dependencies=[WriteKey],
    status_code=202,
    openapi_extra=json_request("BuildRequest", "a database build: checked before it is queued"),
)
def start_build(service: ServiceDep, doc: JsonBody, response: Response) -> Job:
    job = service.submit_build(validate(BuildRequest, doc))
    response.headers["Location"] = f"{API_PREFIX}/jobs/{job['id']}"
    return Job.of(job)
