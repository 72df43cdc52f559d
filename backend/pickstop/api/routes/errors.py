"""``/errors``: error models fitted to recorded arrivals (a dispatch job's, or given), and the
arrivals a dispatch job recorded (``/jobs/{id}/arrivals``, JSON lines)."""

from __future__ import annotations

import json
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Header, Response
from pydantic import BaseModel, ConfigDict, Field, model_validator

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.routes.scenes import _conflict, match_set
from pickstop.api.schemas import SceneRecord
from pickstop.errors import InputError, PickStopError
from pickstop.store.records import Conflict

router = APIRouter(tags=["fleet"])

MAX_ARRIVALS = 100_000


class FitRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    arrivals: list[dict[str, Any]] = Field(
        default_factory=list, max_length=MAX_ARRIVALS, description="pickstop.arrival records"
    )
    jobs: list[Annotated[str, Field(min_length=1, max_length=64)]] = Field(
        default_factory=list, max_length=200, description="dispatch jobs whose arrivals to add"
    )
    scene_id: str | None = Field(
        default=None, description="group by this stored scene's stations (else by tray group)"
    )
    frame: Literal["base", "map"] = "base"
    min_arrivals: int = Field(default=20, ge=3, le=MAX_ARRIVALS)
    write: bool = Field(
        default=False,
        description="write the fitted models into the scene (needs scene_id and If-Match)",
    )

    @model_validator(mode="after")
    def _scene(self) -> FitRequest:
        if self.write and self.scene_id is None:
            raise ValueError("write needs scene_id (the scene to write the fits into)")
        return self


def _job_arrivals(service: Any, job_id: str) -> list[dict[str, Any]]:
    row = service.store.job(job_id)
    if row is None or row["kind"] != "dispatch":
        raise Problem(404, "Not found", f"no dispatch job {job_id!r}", field="jobs")
    result = json.loads(row["result"]) if row.get("result") else {}
    return list(result.get("arrivals") or [])


def _problem(e: PickStopError) -> Problem:
    return Problem(422, "Invalid input", e.message, kind="validation", field=e.field)


@router.get(
    "/jobs/{job_id}/arrivals",
    dependencies=[ReadKey],
    response_class=Response,
    responses={200: {"content": {"application/x-ndjson": {"schema": {"type": "string"}}},
                     "description": "one pickstop.arrival record a line"}},
)  # fmt: skip
def job_arrivals(service: ServiceDep, job_id: str) -> Response:
    """Every arrival a dispatch job recorded, as JSON lines (``pickstop.arrival``)."""
    lines = [json.dumps(a) for a in _job_arrivals(service, job_id)]
    return Response("".join(f"{x}\n" for x in lines), media_type="application/x-ndjson")


@router.post(
    "/errors/fit",
    dependencies=[WriteKey],
    openapi_extra=json_request("FitRequest", "arrivals (or dispatch jobs) and the scene"),
)
def fit_errors(
    service: ServiceDep,
    doc: JsonBody,
    response: Response,
    if_match: Annotated[str | None, Header()] = None,
) -> dict[str, Any]:
    """Per-station error models with 95% intervals and arrival counts, as an error model file
    (``pickstop.error_model``); with ``write``, also written into the stored scene."""
    from pickstop.fleet import arrivals as ar
    from pickstop.fleet import fit as ft
    from pickstop.scene.positioning import of_scene

    req = validate(FitRequest, doc)
    records = list(req.arrivals)
    for j in req.jobs:
        records += _job_arrivals(service, j)
    if len(records) > MAX_ARRIVALS:
        raise Problem(422, "Invalid input", f"more than {MAX_ARRIVALS} arrivals", field="jobs")
    row = scene = None
    if req.scene_id is not None:
        row = service.store.scene(req.scene_id)
        if row is None:
            raise Problem(404, "Not found", f"no scene {req.scene_id!r}", field="scene_id")
    if req.write and if_match is None:
        raise Problem(428, "Precondition required", "send If-Match with the scene's ETag to "
                      "write the fits into it", field="If-Match")  # fmt: skip
    try:
        arrivals = [ar.parse(a, f"arrivals.{k}") for k, a in enumerate(records)]
        if not arrivals:
            raise InputError("no arrivals to fit", field="arrivals")
        scene_doc = None if row is None else json.loads(row["doc"])
        scene = None if scene_doc is None else service.scenes.parse(scene_doc)
        fits, notes = ft.fit(arrivals, None if scene is None else of_scene(scene), req.frame)
        out = ft.document(fits, notes, scene_doc, req.min_arrivals)
        if req.write and row is not None and scene_doc is not None:
            new_doc = {**scene_doc, "error_model": out["error_model"]}
            new = service.scenes.parse(new_doc)
            updated = service.store.update_scene(row["id"], new_doc, new.name,
                                                 match_set(if_match or ""))  # fmt: skip
            if updated is None:
                raise Problem(404, "Not found", f"no scene {row['id']!r}", field="scene_id")
            response.headers["ETag"] = f'"{updated["etag"]}"'
            out["scene"] = SceneRecord.of(updated, False).model_dump()
    except Conflict as c:
        raise _conflict(c) from None
    except PickStopError as e:
        raise _problem(e) from None
    return out
