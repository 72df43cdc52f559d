"""``/health`` and ``/limits``: answered on the event loop, never behind a computation."""

from __future__ import annotations

import os

from fastapi import APIRouter

from pickstop import __version__
from pickstop.api.deps import ServiceDep
from pickstop.api.limits import Limits
from pickstop.api.schemas import Health, LoadedPlanner

router = APIRouter(tags=["service"])


@router.get("/health")
async def health(service: ServiceDep) -> Health:
    """Liveness, the loaded planners and the limits; never waits for a computation."""
    return Health(
        status="ok",
        version=__version__,
        process=os.getpid(),
        loaded=[LoadedPlanner(**x) for x in service.planning.loaded],
        interrupted_jobs_at_start=service.jobs.interrupted,
        limits=service.limits,
    )


@router.get("/limits")
async def limits(service: ServiceDep) -> Limits:
    """What one request may ask for; larger requests are refused before any work."""
    return service.limits
