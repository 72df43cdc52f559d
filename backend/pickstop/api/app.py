"""The FastAPI application: resources under /api/v1, problem details for every error.

uvicorn --factory pickstop.api.app:create_app      (or: pickstop serve)

The event loop only routes and answers: handlers that touch SQLite or validate are plain
functions (FastAPI runs them in its thread pool) and plans and regions run on the service's
planner threads under a deadline (:mod:`pickstop.api.work`), so ``/health`` answers at once
while any of them is in flight.
"""

from __future__ import annotations

import asyncio
import gc
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI

from pickstop import __version__
from pickstop.api import openapi
from pickstop.api.fleet import DispatchRequest
from pickstop.api.limits import Limits
from pickstop.api.middleware import API, BodyLimit, ErrorGuard, Head, StoredPlanFastPath
from pickstop.api.problems import install, server_roots
from pickstop.api.routes import (
    databases,
    errors,
    fleet,
    guidance,
    health,
    jobs,
    layouts,
    mixes,
    placements,
    plans,
    reports,
    robots,
    scenes,
)
from pickstop.api.routes.errors import FitRequest
from pickstop.api.schemas import (
    BatchRequest,
    BuildRequest,
    CopyRequest,
    GuidanceRequest,
    LayoutRequest,
    PlacementRequest,
    PlanRequest,
    ProblemDetails,
)
from pickstop.api.service import Service
from pickstop.pool import PlannerPool
from pickstop.settings import Settings

ROUTERS = (health.router, robots.router, databases.router, scenes.router, plans.router,
           fleet.router, reports.router, jobs.router, errors.router, placements.router,
           mixes.router, guidance.router, layouts.router)  # fmt: skip


def create_app(
    settings: Settings | None = None,
    preload: bool = True,
    job_runner: bool = True,
    planners: PlannerPool | None = None,
) -> FastAPI:
    """The app; ``job_runner``: this process runs the jobs (worker 0 of ``--workers N``);
    ``planners``: a pool loaded already (a forked worker's, inherited from its parent)."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # Planning threads hold the GIL in long stretches; switching more often keeps the
        # event loop (health, reads) responsive while a plan computes.
        sys.setswitchinterval(0.001)
        svc = await asyncio.to_thread(Service, settings, job_runner, planners)
        if preload:
            await asyncio.to_thread(svc.planning.preload)
        app.state.service = svc
        # What start-up made lives as long as the service: out of the cyclic collector's
        # sight, a full collection (after a request that made many objects, a large body's)
        # scans only what requests made since, in milliseconds rather than a tenth of a second.
        gc.collect()
        gc.freeze()
        yield
        gc.unfreeze()
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
    from pickstop.robot.config import RobotConfig, example_robot_data_share
    from pickstop.scene.model import Scene

    server_roots(settings.data_dir, example_robot_data_share())
    install(app)
    app.add_middleware(BodyLimit, limit=settings.max_body_bytes)
    app.add_middleware(StoredPlanFastPath, settings=settings)
    app.add_middleware(ErrorGuard)
    app.add_middleware(Head)
    for router in ROUTERS:
        app.include_router(router, prefix=API)
    openapi.install(app, settings, {
        "Scene": Scene, "RobotConfig": RobotConfig, "PlanRequest": PlanRequest,
        "BatchRequest": BatchRequest, "BuildRequest": BuildRequest,
        "ProblemDetails": ProblemDetails, "Limits": Limits, "DispatchRequest": DispatchRequest,
        "FitRequest": FitRequest,
        "PlacementRequest": PlacementRequest, "CopyRequest": CopyRequest,
        "GuidanceRequest": GuidanceRequest, "LayoutRequest": LayoutRequest,
    })  # fmt: skip
    return app
