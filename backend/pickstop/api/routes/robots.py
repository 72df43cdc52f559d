"""``/robots``: presets and registered robot configs."""

from __future__ import annotations

from fastapi import APIRouter

from pickstop.api.deps import JsonBody, ReadKey, ServiceDep, WriteKey
from pickstop.api.openapi import json_request
from pickstop.api.schemas import RegisteredRobot, RobotInfo

router = APIRouter(tags=["robots"])


@router.get("/robots", dependencies=[ReadKey])
def robots(service: ServiceDep) -> list[RobotInfo]:
    return [RobotInfo(**r) for r in service.robots()]


@router.post(
    "/robots",
    dependencies=[WriteKey],
    status_code=201,
    openapi_extra=json_request("RobotConfig", "a robot config whose files lie in robots/"),
)
def register_robot(service: ServiceDep, config: JsonBody) -> RegisteredRobot:
    robot = service.register_robot(config)
    return RegisteredRobot(name=robot.name, dof=robot.dof, robot_hash=robot.robot_hash)
