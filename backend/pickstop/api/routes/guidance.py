"""``/guidance``: where a tray could go and what that does to its order's stops (zones)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from starlette.concurrency import run_in_threadpool

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.schemas import Guidance, GuidanceRequest
from pickstop.api.work import compute
from pickstop.scene.model import Scene

router = APIRouter(tags=["scenes"])


def _check(scene: Scene, tray: str, order: str | None) -> None:
    """The tray is the scene's, and the order (if named) is the scene's and needs it."""
    if tray not in {t.id for t in scene.trays}:
        raise Problem(422, "Invalid input", f"no tray {tray!r} in the scene", field="tray")
    if order is not None:
        found = next((o for o in scene.orders or [] if o.id == order), None)
        if found is None:
            raise Problem(422, "Invalid input", f"no order {order!r} in the scene", field="order")
        if tray not in scene.order_trays(found):
            raise Problem(422, "Invalid input", f"order {order!r} does not need tray {tray!r}",
                          field="order")  # fmt: skip


async def _guidance(
    request: Request, service: Any, scene: Scene, tray: str, order: str | None, mix: bool,
    sigma: float | None, database: str | None,
) -> Guidance:  # fmt: skip
    _check(scene, tray, order)
    doc: dict[str, Any] = await compute(
        service.threads, service.planning.guidance, scene, tray, order, mix, sigma, database,
        deadline=service.settings.request_deadline, request=request,
    )  # fmt: skip
    return Guidance.model_validate(doc)


@router.get("/scenes/{scene_id}/guidance", dependencies=[ReadKey])
async def scene_guidance(
    request: Request,
    service: ServiceDep,
    scene_id: str,
    tray: str,
    order: str | None = None,
    mix: bool = False,
    sigma: Annotated[float | None, Query(ge=0, le=1, allow_inf_nan=False)] = None,
    database: str | None = None,
) -> Guidance:
    """Zones where ``tray`` of a stored scene could go (GeoJSON; see :class:`Guidance`), from
    the regions known (computed once if the scene was never planned)."""
    scene = await run_in_threadpool(service.scenes.stored_scene, scene_id)
    return await _guidance(request, service, scene, tray, order, mix, sigma, database)


@router.post(
    "/guidance",
    dependencies=[WriteKey],
    openapi_extra=json_request("GuidanceRequest", "a scene (stored or inline) and a tray"),
)
async def guidance(request: Request, service: ServiceDep, doc: JsonBody) -> Guidance:
    """:func:`scene_guidance` of an inline scene (a layout being edited) or a stored one."""
    body = await run_in_threadpool(validate, GuidanceRequest, doc)
    _, _, scene = await run_in_threadpool(service.scenes.prepare, body)
    return await _guidance(request, service, scene, body.tray, body.order, body.mix, body.sigma,
                           body.database)  # fmt: skip
