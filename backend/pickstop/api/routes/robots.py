"""``/robots``: presets and registered robot configs, their check reports and drawings."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import FileResponse

from pickstop.api import robot_views
from pickstop.api.deps import ConfigBody, ReadKey, RobotName, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.problems import Problem
from pickstop.api.schemas import RegisteredRobot, RobotInfo
from pickstop.api.work import compute

router = APIRouter(tags=["robots"])


@router.get("/robots", dependencies=[ReadKey])
def robots(service: ServiceDep) -> list[RobotInfo]:
    return [RobotInfo(**r) for r in service.robots.listing()]


@router.post(
    "/robots",
    dependencies=[WriteKey],
    status_code=201,
    openapi_extra=json_request(
        "RobotConfig",
        "a robot config (JSON, or YAML as application/yaml) whose files lie in robots/",
        yaml=True,
    ),
)
def register_robot(service: ServiceDep, config: ConfigBody) -> RegisteredRobot:
    robot = service.robots.register(config)
    return RegisteredRobot(name=robot.name, dof=robot.dof, robot_hash=robot.robot_hash)


@router.get("/robots/{name}/check", dependencies=[ReadKey])
async def robot_check(service: ServiceDep, request: Request, name: RobotName) -> dict[str, Any]:
    """What PickStop makes of the robot (``pickstop robot check``): the resolved tool, hand,
    footprint, self-collision pairs and their source, the screen's false rejection, and each
    step's time. Made once per config."""
    return await compute(
        service.threads,
        robot_views.check_of,
        service.robots,
        name,
        deadline=service.settings.request_deadline,
        request=request,
    )


@router.get("/robots/{name}/model", dependencies=[ReadKey])
async def robot_model(service: ServiceDep, request: Request, name: RobotName) -> dict[str, Any]:
    """The robot's URDF (mesh references ``files/<id>``), its arm joints, the values of every
    other joint (locked, or the hand's pre-grasp) and its travel posture (with the link pairs
    in contact there, none when collision-free), for drawing it."""
    return await compute(
        service.threads,
        robot_views.model_of,
        service.robots,
        name,
        deadline=service.settings.request_deadline,
        request=request,
    )


@router.get(
    "/robots/{name}/files/{file_id}",
    dependencies=[ReadKey],
    response_class=FileResponse,
    responses={200: {"description": "the mesh file's bytes", "content": {
        "application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}}},
)  # fmt: skip
def robot_file(service: ServiceDep, name: RobotName, file_id: str) -> FileResponse:
    """One mesh of the robot's model (only files its own URDF references)."""
    path = robot_views.file_of(service.robots, name, file_id)
    if path is None:
        raise Problem(404, "Not found", f"robot {name!r} has no file {file_id!r}")
    return FileResponse(path, media_type="application/octet-stream")
