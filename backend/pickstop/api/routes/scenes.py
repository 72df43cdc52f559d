"""``/scenes``: scene documents with ETags (If-Match on every change), and their regions."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Header, Query, Request, Response
from starlette.concurrency import run_in_threadpool

from pickstop.api.deps import JsonBody, ReadKey, SceneRow, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.schemas import API_PREFIX, PlanSummary, Regions, SceneRecord
from pickstop.api.work import compute
from pickstop.sequence.rules import RuleName
from pickstop.store.records import Conflict

router = APIRouter(tags=["scenes"])

Limit = Annotated[int, Query(ge=1, le=500)]
Offset = Annotated[int, Query(ge=0, le=10**9, description="records to skip")]
IfMatch = Annotated[
    str | None, Header(description='the ETag you read ("..."), or * for any current version')
]


def match_set(if_match: str) -> frozenset[str] | None:
    """The entity tags of an If-Match header (None for ``*``: any current version). Weak tags
    never match: If-Match compares strongly (RFC 9110)."""
    if if_match.strip() == "*":
        return None
    tags = set()
    for part in if_match.split(","):
        part = part.strip()
        if part.startswith('"') and part.endswith('"') and len(part) >= 2:
            tags.add(part[1:-1])
        elif part and not part.startswith("W/") and '"' not in part:
            tags.add(part)  # a bare tag, as curl users send it
    return frozenset(tags)


def _conflict(c: Conflict) -> Problem:
    return Problem(
        412,
        "Precondition failed",
        f'the scene changed since you read it (its ETag is now "{c.current}"); read it again '
        "and reapply your change",
        field="If-Match",
    )


def _require(if_match: str | None, what: str) -> str:
    if if_match is None or not if_match.strip():
        raise Problem(
            428,
            "Precondition required",
            f"send If-Match with the scene's ETag to {what} it, so a concurrent change is not "
            "overwritten",
            field="If-Match",
        )
    return if_match


@router.get("/scenes", dependencies=[ReadKey])
def scenes(service: ServiceDep, limit: Limit = 100, offset: Offset = 0) -> list[SceneRecord]:
    return [SceneRecord.of(x, False) for x in service.store.scenes(limit, offset)]


@router.post(
    "/scenes",
    dependencies=[WriteKey],
    status_code=201,
    openapi_extra=json_request("Scene", "a scene document (docs/scene.schema.json)"),
)
def create_scene(service: ServiceDep, doc: JsonBody, response: Response) -> SceneRecord:
    scene = service.scenes.parse(doc)
    row = service.store.create_scene(doc, scene.name)
    response.headers["ETag"] = f'"{row["etag"]}"'
    response.headers["Location"] = f"{API_PREFIX}/scenes/{row['id']}"
    return SceneRecord.of(row, True)


@router.get("/scenes/{scene_id}", dependencies=[ReadKey])
def get_scene(row: SceneRow, response: Response) -> SceneRecord:
    response.headers["ETag"] = f'"{row["etag"]}"'
    return SceneRecord.of(row, True)


@router.put(
    "/scenes/{scene_id}",
    dependencies=[WriteKey],
    openapi_extra=json_request("Scene", "the new scene document"),
)
def put_scene(
    service: ServiceDep,
    row: SceneRow,
    doc: JsonBody,
    response: Response,
    if_match: IfMatch = None,
) -> SceneRecord:
    tags = match_set(_require(if_match, "change"))
    scene = service.scenes.parse(doc)
    try:
        new = service.store.update_scene(row["id"], doc, scene.name, tags)
    except Conflict as c:
        raise _conflict(c) from None
    if new is None:
        raise Problem(404, "Not found", f"no scene {row['id']!r}", field="scene_id")
    response.headers["ETag"] = f'"{new["etag"]}"'
    return SceneRecord.of(new, True)


@router.delete("/scenes/{scene_id}", dependencies=[WriteKey], status_code=204)
def delete_scene(service: ServiceDep, row: SceneRow, if_match: IfMatch = None) -> Response:
    tags = match_set(_require(if_match, "delete"))
    try:
        gone = service.store.delete_scene(row["id"], tags)
    except Conflict as c:
        raise _conflict(c) from None
    if not gone:
        raise Problem(404, "Not found", f"no scene {row['id']!r}", field="scene_id")
    return Response(status_code=204)


@router.get("/scenes/{scene_id}/regions", dependencies=[ReadKey])
async def scene_regions(
    request: Request,
    service: ServiceDep,
    scene_id: str,
    sigma: Annotated[float | None, Query(ge=0, le=1, allow_inf_nan=False)] = None,
    database: str | None = None,
    rule: Annotated[RuleName, Query(description="judge candidates as a plan with this rule")] = (
        "sigma"
    ),
    target: Annotated[float, Query(gt=0.5, lt=1.0, description="the success rule's target")] = 0.95,
) -> Regions:
    """Base regions and intersections (GeoJSON), each intersection judged as a plan with the
    same sigma, rule and target would judge it; computed under the request deadline."""
    scene = await run_in_threadpool(service.scenes.stored_scene, scene_id)
    regions: dict[str, Any] = await compute(
        service.threads, service.planning.regions, scene, sigma, database, rule, target,
        deadline=service.settings.request_deadline, request=request,
    )  # fmt: skip
    return Regions.model_validate(regions)


@router.get("/scenes/{scene_id}/plans", dependencies=[ReadKey], tags=["plans"])
def scene_plans(
    service: ServiceDep, row: SceneRow, limit: Limit = 100, offset: Offset = 0
) -> list[PlanSummary]:
    return [PlanSummary.of(x) for x in service.store.plans(row["id"], limit, offset)]
