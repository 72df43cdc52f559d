"""The FastAPI application: resources under /api/v1, problem details for every error.

uvicorn --factory pickstop.api.app:create_app      (or: pickstop serve)
"""

from __future__ import annotations

import asyncio
import hmac
import json
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Annotated, Any, Literal

from fastapi import (
    APIRouter,
    Body,
    Depends,
    FastAPI,
    Header,
    HTTPException,
    Query,
    Request,
    Response,
)
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from pydantic import BaseModel, ConfigDict, Field, model_validator
from starlette.types import ASGIApp, Receive, Scope, Send

from pickstop import __version__
from pickstop.api.problems import Problem, install, problem_response
from pickstop.api.service import Service
from pickstop.api.store import Conflict, now
from pickstop.reach.database import list_databases
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.settings import Settings, hash_key

API = "/api/v1"
bearer = HTTPBearer(auto_error=False)

EXAMPLE_SCENE = {
    "name": "two trays",
    "floor": {"min": [-1, -1], "max": [4, 3]},
    "obstacles": [
        {
            "id": "table",
            "geometry": {"shape": "box", "size": [1.6, 0.6, 0.72]},
            "pose": {"x": 1.4, "y": 1.6},
        }
    ],
    "trays": [
        {
            "id": "tray_1",
            "pose": {"x": 0.95, "y": 1.5, "z": 0.725},
            "inner_size": [0.3, 0.2],
            "parts": [
                {"id": "bolt", "geometry": {"shape": "cylinder", "radius": 0.01, "height": 0.05}}
            ],
        }
    ],
    "base_yaw": {"fixed": 1.5707963},
    "start": {"x": 0, "y": 0},
    "goal": {"x": 3, "y": 0},
}


# -- request and response bodies ----------------------------------------------------------------
class ProblemDetails(BaseModel):
    """RFC 9457 problem details."""

    type: str
    title: str
    status: int
    detail: str
    instance: str | None = None
    field: str | None = None
    errors: list[dict[str, str]] | None = None


_PROBLEM = {"model": ProblemDetails, "content": {"application/problem+json": {}}}
PROBLEMS: dict[int | str, dict[str, Any]] = {
    code: {**_PROBLEM, "description": text}
    for code, text in [
        (401, "an API key is needed or not valid"),
        (404, "no such resource"),
        (409, "no reachability database fits the request"),
        (412, "the scene changed since it was read (If-Match)"),
        (413, "the request is too large"),
        (422, "invalid input, or an infeasible plan; the detail says which field and why"),
        (428, "If-Match is required"),
    ]
}


class SceneRecord(BaseModel):
    id: str
    name: str
    etag: str
    revision: int
    created: str
    updated: str
    scene: dict[str, Any] | None = None


class BatchItem(BaseModel):
    """A stored scene by id, or an inline scene document: exactly one of them."""

    model_config = ConfigDict(extra="forbid")
    scene_id: str | None = Field(default=None, description="a stored scene")
    scene: dict[str, Any] | None = Field(default=None, description="or an inline scene document")

    @model_validator(mode="after")
    def _one(self) -> BatchItem:
        if (self.scene_id is None) == (self.scene is None):
            raise ValueError("give exactly one of scene_id and scene")
        return self


class PlanRequest(BatchItem):
    options: PlanOptions = PlanOptions()
    database: str | None = Field(default=None, description="reachability database id")
    mode: Literal["sync", "job"] = Field(default="sync", description="'job': run as a batch job")
    store: bool = Field(
        default=True, description="keep the plan as a record (false: a preview, not stored)"
    )


class PlanRecord(BaseModel):
    id: str | None  # None for a preview that was not stored
    scene_id: str | None
    scene_revision: int | None
    created: str
    options: dict[str, Any]
    plan: Plan | None = None
    scene: dict[str, Any] | None = None


class BatchRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    scenes: list[BatchItem] = Field(min_length=1)
    options: PlanOptions = PlanOptions()
    database: str | None = None


class BuildRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    robot: str = "tiago"
    samples: int = Field(default=2_000_000, gt=0)
    resolution: float = Field(default=0.05, gt=0, le=1)
    orientation: int = Field(default=6, ge=1, le=32)
    seed: int = 0
    chunk_size: int = Field(default=250_000, ge=1000, le=5_000_000)
    thinning: float = Field(default=0.0, ge=0)


class Job(BaseModel):
    id: str
    kind: str
    state: str
    progress: float
    params: dict[str, Any]
    result: dict[str, Any] | None
    error: str | None
    created: str
    updated: str


def _job(row: dict[str, Any]) -> Job:
    return Job(
        **{
            **row,
            "params": json.loads(row["params"]),
            "result": json.loads(row["result"]) if row["result"] else None,
        }
    )


# -- body size limit ------------------------------------------------------------------------------
class BodyLimit:
    """Refuse request bodies over ``limit`` bytes with 413, declared or streamed."""

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        too_big = Problem(
            413,
            "Request too large",
            f"the request body exceeds {self.limit} bytes",
            kind="too-large",
        )
        for k, v in scope.get("headers", []):
            if k == b"content-length" and v.isdigit() and int(v) > self.limit:
                await problem_response(too_big, scope.get("path"))(scope, receive, send)
                return
        seen = 0

        async def limited() -> Any:
            nonlocal seen
            msg = await receive()
            if msg["type"] == "http.request":
                seen += len(msg.get("body", b""))
                if seen > self.limit:
                    raise _TooLarge()
            return msg

        try:
            await self.app(scope, limited, send)
        except _TooLarge:
            await problem_response(too_big, scope.get("path"))(scope, receive, send)


class _TooLarge(Exception):
    pass


class StoredPlanFastPath:
    """``GET /api/v1/plans/{id}`` for a plan already in the service's body cache, answered
    before routing: stored plans are immutable and are the reads an MES makes most. Anything
    else (a query string, a plan not cached yet, reads that need a key) takes the normal way,
    which also fills the cache."""

    PREFIX = f"{API}/plans/"

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app, self.enabled = app, not settings.read_requires_key

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            self.enabled
            and scope["type"] == "http"
            and scope["method"] == "GET"
            and not scope.get("query_string")
            and scope["path"].startswith(self.PREFIX)
        ):
            service = getattr(scope["app"].state, "service", None)
            plan_id = scope["path"][len(self.PREFIX) :]
            body = service.cached_plan_body(plan_id) if service is not None else None
            if body is not None:
                await send({"type": "http.response.start", "status": 200, "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                    (b"cache-control", b"public, max-age=31536000, immutable"),
                ]})  # fmt: skip
                await send({"type": "http.response.body", "body": body})
                return
        await self.app(scope, receive, send)


# -- the app --------------------------------------------------------------------------------------
def create_app(settings: Settings | None = None, preload: bool = True) -> FastAPI:
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # Planning threads hold the GIL in long stretches; switching more often keeps the
        # event loop (health, reads) responsive while a plan computes.
        sys.setswitchinterval(0.001)
        svc = Service(settings)
        if preload:
            await asyncio.get_running_loop().run_in_executor(None, svc.preload)
        app.state.service = svc
        yield
        svc.close()

    app = FastAPI(
        title="PickStop",
        version=__version__,
        description="Plan the fewest, safest stops for a mobile manipulator to pick every part.",
        lifespan=lifespan,
        openapi_url=f"{API}/openapi.json",
        docs_url=f"{API}/docs",
        redoc_url=None,
    )
    install(app)
    app.add_middleware(BodyLimit, limit=settings.max_body_bytes)
    app.add_middleware(StoredPlanFastPath, settings=settings)
    app.include_router(_router(settings), prefix=API)
    return app


def _router(settings: Settings) -> APIRouter:
    r = APIRouter(responses=PROBLEMS)
    keys = {k.strip() for k in settings.api_keys if k.strip()}

    def _authorised(cred: HTTPAuthorizationCredentials | None) -> bool:
        if cred is None:
            return False
        h = hash_key(cred.credentials)
        return any(hmac.compare_digest(h, k) for k in keys)

    def write_key(
        cred: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
    ) -> None:
        if not _authorised(cred):
            raise Problem(
                401,
                "Unauthorized",
                "writes need an API key: Authorization: Bearer <key>"
                if cred is None
                else "the API key is not valid",
                headers={"WWW-Authenticate": "Bearer"},
            )

    def read_key(
        cred: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
    ) -> None:
        if settings.read_requires_key:
            write_key(cred)

    W = [Depends(write_key)]
    R = [Depends(read_key)]

    def svc(request: Request) -> Service:
        return request.app.state.service

    @r.get("/health", tags=["service"])
    async def health(request: Request) -> dict[str, Any]:
        s = svc(request)
        return {
            "status": "ok",
            "version": __version__,
            "loaded": s.loaded,
            "interrupted_jobs_at_start": s.interrupted,
        }

    # robots ------------------------------------------------------------------------------------
    @r.get("/robots", tags=["robots"], dependencies=R)
    async def robots(request: Request) -> list[dict[str, Any]]:
        return svc(request).robots()

    @r.post("/robots", tags=["robots"], dependencies=W, status_code=201)
    async def register_robot(
        request: Request,
        config: Annotated[dict[str, Any], Body(description="a robot config (see docs)")],
    ) -> dict[str, Any]:
        s = svc(request)
        robot = await asyncio.get_running_loop().run_in_executor(s.pool, s.register_robot, config)
        return {
            "name": robot.name,
            "kind": "registered",
            "dof": robot.dof,
            "robot_hash": robot.robot_hash,
        }

    @r.get("/robots/{name}/check", tags=["robots"], dependencies=R)
    async def robot_check(request: Request, name: str) -> dict[str, Any]:
        """What PickStop makes of the robot (``pickstop robot check``): the resolved tool,
        hand, footprint, self-collision pairs and their source, the screen's false rejection,
        and each step's time."""
        from pickstop.api.robot_views import check_of

        s = svc(request)
        return await asyncio.get_running_loop().run_in_executor(s.pool, check_of, s, name)

    @r.get("/robots/{name}/model", tags=["robots"], dependencies=R)
    async def robot_model(request: Request, name: str) -> dict[str, Any]:
        """The robot's URDF (mesh references ``files/<id>``), its arm joints and the values
        of every other joint (locked, or the hand's pre-grasp), for drawing it."""
        from pickstop.api.robot_views import model_of

        s = svc(request)
        return await asyncio.get_running_loop().run_in_executor(s.pool, model_of, s, name)

    @r.get("/robots/{name}/files/{file_id}", tags=["robots"], dependencies=R)
    async def robot_file(request: Request, name: str, file_id: str) -> Any:
        """One mesh of the robot's model."""
        from fastapi.responses import FileResponse

        from pickstop.api.robot_views import file_of

        s = svc(request)
        path = await asyncio.get_running_loop().run_in_executor(s.pool, file_of, s, name, file_id)
        if path is None:
            raise HTTPException(404, f"robot {name!r} has no file {file_id!r}")
        return FileResponse(path, media_type="application/octet-stream")

    # databases ---------------------------------------------------------------------------------
    @r.get("/databases", tags=["databases"], dependencies=R)
    async def databases(request: Request, robot: str | None = None) -> list[dict[str, Any]]:
        from pickstop.cli import _db_summary

        rows = list_databases(svc(request).data_dir, robot)
        return [_db_summary(x) for x in rows]

    @r.get("/databases/{db_id}", tags=["databases"], dependencies=R)
    async def database(request: Request, db_id: str) -> dict[str, Any]:
        from pickstop.cli import _db_summary

        for x in list_databases(svc(request).data_dir):
            if x["id"] == db_id:
                return _db_summary(x)
        raise Problem(404, "Not found", f"no reachability database {db_id!r}")

    @r.delete("/databases/{db_id}", tags=["databases"], dependencies=W, status_code=204)
    async def delete_database(request: Request, db_id: str) -> Response:
        if not svc(request).delete_database(db_id):
            raise Problem(404, "Not found", f"no reachability database {db_id!r}")
        return Response(status_code=204)

    @r.post("/databases", tags=["databases"], dependencies=W, status_code=202)
    async def start_build(request: Request, body: BuildRequest) -> Job:
        s = svc(request)
        if body.samples > settings.max_samples:
            raise Problem(
                422,
                "Invalid input",
                f"samples {body.samples} exceeds the limit of {settings.max_samples}",
                kind="validation",
                field="samples",
            )
        s.robot_config(body.robot)  # unknown robot: 422 now, not a failed job later
        return _job(s.submit("build", body.model_dump()))

    # scenes ------------------------------------------------------------------------------------
    def _scene_record(row: dict[str, Any], with_doc: bool) -> SceneRecord:
        return SceneRecord(
            **{k: row[k] for k in SceneRecord.model_fields if k in row and k != "scene"},
            scene=json.loads(row["doc"]) if with_doc else None,
        )

    @r.get("/scenes", tags=["scenes"], dependencies=R)
    async def scenes(
        request: Request,
        limit: Annotated[int, Query(ge=1, le=500)] = 100,
        offset: Annotated[int, Query(ge=0)] = 0,
    ) -> list[SceneRecord]:
        return [_scene_record(x, False) for x in svc(request).store.scenes(limit, offset)]

    @r.post("/scenes", tags=["scenes"], dependencies=W, status_code=201)
    async def create_scene(
        request: Request,
        response: Response,
        doc: Annotated[dict[str, Any], Body(examples=[EXAMPLE_SCENE])],
    ) -> SceneRecord:
        s = svc(request)
        scene = s.parse(doc)
        row = s.store.create_scene(doc, scene.name)
        response.headers["ETag"] = f'"{row["etag"]}"'
        response.headers["Location"] = f"{API}/scenes/{row['id']}"
        return _scene_record(row, True)

    @r.get("/scenes/{scene_id}", tags=["scenes"], dependencies=R)
    async def get_scene(request: Request, response: Response, scene_id: str) -> SceneRecord:
        row = svc(request).store.scene(scene_id)
        if row is None:
            raise Problem(404, "Not found", f"no scene {scene_id!r}")
        response.headers["ETag"] = f'"{row["etag"]}"'
        return _scene_record(row, True)

    def _etag(value: str | None) -> str | None:
        return value.strip().removeprefix("W/").strip('"') if value else None

    @r.put("/scenes/{scene_id}", tags=["scenes"], dependencies=W)
    async def put_scene(
        request: Request,
        response: Response,
        scene_id: str,
        doc: Annotated[dict[str, Any], Body(examples=[EXAMPLE_SCENE])],
        if_match: Annotated[str | None, Header(description="the ETag you read")] = None,
    ) -> SceneRecord:
        s = svc(request)
        if if_match is None:
            if s.store.scene(scene_id) is None:
                raise Problem(404, "Not found", f"no scene {scene_id!r}")
            raise Problem(
                428,
                "Precondition required",
                "send If-Match with the scene's ETag, so a concurrent change is not overwritten",
                field="If-Match",
            )
        scene = s.parse(doc)
        try:
            row = s.store.update_scene(scene_id, doc, scene.name, _etag(if_match) or "")
        except Conflict as c:
            raise Problem(
                412,
                "Precondition failed",
                f"the scene changed since you read it "
                f'(its ETag is now "{c.current}"); read it again and reapply your '
                "change",
                field="If-Match",
            ) from None
        if row is None:
            raise Problem(404, "Not found", f"no scene {scene_id!r}")
        response.headers["ETag"] = f'"{row["etag"]}"'
        return _scene_record(row, True)

    @r.delete("/scenes/{scene_id}", tags=["scenes"], dependencies=W, status_code=204)
    async def delete_scene(
        request: Request, scene_id: str, if_match: Annotated[str | None, Header()] = None
    ) -> Response:
        try:
            gone = svc(request).store.delete_scene(scene_id, _etag(if_match))
        except Conflict as c:
            raise Problem(
                412,
                "Precondition failed",
                f'the scene changed since you read it (its ETag is now "{c.current}")',
                field="If-Match",
            ) from None
        if not gone:
            raise Problem(404, "Not found", f"no scene {scene_id!r}")
        return Response(status_code=204)

    @r.get("/scenes/{scene_id}/regions", tags=["scenes"], dependencies=R)
    async def scene_regions(
        request: Request,
        scene_id: str,
        sigma: Annotated[float | None, Query(ge=0, le=1)] = None,
        database: str | None = None,
    ) -> dict[str, Any]:
        s = svc(request)
        row = s.store.scene(scene_id)
        if row is None:
            raise Problem(404, "Not found", f"no scene {scene_id!r}")
        scene = s.parse(json.loads(row["doc"]))
        return await asyncio.get_running_loop().run_in_executor(
            s.pool, s.regions, scene, sigma, database
        )

    @r.get("/scenes/{scene_id}/plans", tags=["plans"], dependencies=R)
    async def scene_plans(
        request: Request,
        scene_id: str,
        limit: Annotated[int, Query(ge=1, le=500)] = 100,
        offset: Annotated[int, Query(ge=0)] = 0,
    ) -> list[dict[str, Any]]:
        s = svc(request)
        if s.store.scene(scene_id) is None:
            raise Problem(404, "Not found", f"no scene {scene_id!r}")
        return _plan_rows(s.store.plans(scene_id, limit, offset))

    # plans -------------------------------------------------------------------------------------
    def _plan_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
        return [{**x, "options": json.loads(x["options"])} for x in rows]

    @r.post("/plans", tags=["plans"], dependencies=W, status_code=201)
    async def create_plan(request: Request, response: Response, body: PlanRequest) -> Any:
        s = svc(request)
        if body.mode == "job":
            item = {"scene_id": body.scene_id, "scene": body.scene}
            job = s.submit(
                "batch",
                {"scenes": [item], "options": body.options.model_dump(), "database": body.database},
            )
            response.status_code = 202
            response.headers["Location"] = f"{API}/jobs/{job['id']}"
            return _job(job)
        revision = None
        if body.scene_id is not None:
            row = s.store.scene(body.scene_id)
            if row is None:
                raise Problem(
                    422,
                    "Invalid input",
                    f"scene {body.scene_id} does not exist",
                    kind="validation",
                    field="scene_id",
                )
            doc, revision = json.loads(row["doc"]), row["revision"]
        else:
            doc = body.scene or {}
        scene = s.parse(doc)
        plan = await asyncio.get_running_loop().run_in_executor(
            s.pool, s.plan, scene, body.options, body.database
        )
        if not body.store:
            response.status_code = 200
            return PlanRecord(
                id=None,
                scene_id=body.scene_id,
                scene_revision=revision,
                created=now(),
                options=body.options.model_dump(),
                plan=plan,
            )
        rec = s.store.add_plan(
            body.scene_id, revision, doc, body.options.model_dump(), plan.model_dump(mode="json")
        )
        response.headers["Location"] = f"{API}/plans/{rec['id']}"
        return PlanRecord(
            id=rec["id"],
            scene_id=body.scene_id,
            scene_revision=revision,
            created=rec["created"],
            options=body.options.model_dump(),
            plan=plan,
        )

    @r.get("/plans", tags=["plans"], dependencies=R)
    async def plans(
        request: Request,
        scene_id: str | None = None,
        limit: Annotated[int, Query(ge=1, le=500)] = 100,
        offset: Annotated[int, Query(ge=0)] = 0,
    ) -> list[dict[str, Any]]:
        return _plan_rows(svc(request).store.plans(scene_id, limit, offset))

    @r.get("/plans/{plan_id}", tags=["plans"], dependencies=R)
    async def get_plan(request: Request, plan_id: str, include_scene: bool = False) -> Response:
        s = svc(request)
        headers = {"Cache-Control": "public, max-age=31536000, immutable"}
        if include_scene:
            row = s.store.plan(plan_id)
            body = s.plan_body(plan_id, row) if row is not None else None
            if row is None or body is None:
                raise Problem(404, "Not found", f"no plan {plan_id!r}")
            full = body[:-1] + b',"scene":' + row["scene_doc"].encode() + b"}"
            return Response(full, media_type="application/json", headers=headers)
        cached = s.plan_body(plan_id)
        if cached is None:
            raise Problem(404, "Not found", f"no plan {plan_id!r}")
        return Response(cached, media_type="application/json", headers=headers)

    # jobs --------------------------------------------------------------------------------------
    @r.post("/jobs/batch", tags=["jobs"], dependencies=W, status_code=202)
    async def batch(request: Request, response: Response, body: BatchRequest) -> Job:
        if len(body.scenes) > settings.max_batch:
            raise Problem(
                413,
                "Request too large",
                f"{len(body.scenes)} scenes exceed the batch limit of {settings.max_batch}",
                kind="too-large",
                field="scenes",
            )
        s = svc(request)
        for i, item in enumerate(body.scenes):  # validate now: a bad scene is a 422, not a job
            if item.scene is not None:
                try:
                    s.parse(item.scene)
                except Exception as e:
                    msg = getattr(e, "message", str(e))
                    raise Problem(
                        422,
                        "Invalid input",
                        f"scenes[{i}]: {msg}",
                        kind="validation",
                        field=f"scenes.{i}.scene",
                    ) from None
            elif s.store.scene(item.scene_id or "") is None:
                raise Problem(
                    422,
                    "Invalid input",
                    f"scenes[{i}]: scene {item.scene_id} does not exist",
                    kind="validation",
                    field=f"scenes.{i}.scene_id",
                )
        job = s.submit("batch", body.model_dump())
        response.headers["Location"] = f"{API}/jobs/{job['id']}"
        return _job(job)

    @r.get("/jobs", tags=["jobs"], dependencies=R)
    async def jobs(
        request: Request,
        limit: Annotated[int, Query(ge=1, le=500)] = 100,
        offset: Annotated[int, Query(ge=0)] = 0,
    ) -> list[Job]:
        return [_job(x) for x in svc(request).store.jobs(limit, offset)]

    @r.get("/jobs/{job_id}", tags=["jobs"], dependencies=R)
    async def job(request: Request, job_id: str) -> Job:
        row = svc(request).store.job(job_id)
        if row is None:
            raise Problem(404, "Not found", f"no job {job_id!r}")
        return _job(row)

    @r.post("/jobs/{job_id}/cancel", tags=["jobs"], dependencies=W)
    async def cancel(request: Request, job_id: str) -> Job:
        row = svc(request).cancel(job_id)
        if row is None:
            raise Problem(404, "Not found", f"no job {job_id!r}")
        return _job(row)

    from pickstop.api.fleet import add_fleet_routes

    add_fleet_routes(r, W, R)
    return r
