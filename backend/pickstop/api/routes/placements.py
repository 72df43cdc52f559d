"""``/placements``: where a tray would stand (drag-follow), and a copy on a free spot."""

from __future__ import annotations

import json
from dataclasses import asdict

from fastapi import APIRouter

from pickstop.api.body import validate
from pickstop.api.deps import JsonBody, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.schemas import CopyAnswer, CopyRequest, PlacementAnswer, PlacementRequest
from pickstop.scene.model import Scene
from pickstop.scene.supports import place_tray, tray_copy

router = APIRouter(tags=["scenes"])


def _tray(scene: Scene, tray_id: str) -> None:
    if tray_id not in {t.id for t in scene.trays}:
        raise Problem(422, "Invalid input", f"no tray {tray_id!r} in the scene", field="tray")


@router.post(
    "/placements",
    dependencies=[WriteKey],
    openapi_extra=json_request("PlacementRequest", "a tray and where its footprint would go"),
)
def placement(service: ServiceDep, doc: JsonBody) -> PlacementAnswer:
    """The support under a tray's footprint at ``(x, y, yaw)``, the height that rests it
    there and whether it stands free: what a dragged tray follows (milliseconds)."""
    body = validate(PlacementRequest, doc)
    _, _, scene = service.scenes.prepare(body)
    _tray(scene, body.tray)
    p = place_tray(scene, body.tray, body.x, body.y, body.yaw, body.z_hint)
    return PlacementAnswer(**asdict(p))


@router.post(
    "/placements/copy",
    dependencies=[WriteKey],
    openapi_extra=json_request("CopyRequest", "the tray to copy"),
)
def copy(service: ServiceDep, doc: JsonBody) -> CopyAnswer:
    """A copy of the tray on the nearest free spot of the support it stands on."""
    body = validate(CopyRequest, doc)
    _, _, scene = service.scenes.prepare(body)
    _tray(scene, body.tray)
    new = tray_copy(scene, body.tray)
    return CopyAnswer(tray=None if new is None else json.loads(new.model_dump_json()))
