"""What the API shows of a robot: its check report, and its drawing (URDF with portable mesh
references, and those files).

Only files the robot's own URDF references are served, and each is confined again when it is
opened (its real path, symlinks resolved, must lie in the allowed folders); answers never name
server paths.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pickstop.api.registry import RobotRegistry
from pickstop.robot.assets import RobotAssets, robot_assets


def assets_of(robots: RobotRegistry, name: str) -> RobotAssets:
    """The drawing assets of a preset or registered robot (made once per robot; its travel
    posture is checked exactly with its self-collision pairs, read from the cache where a
    check, a build or a plan made them)."""
    from pickstop.robot.cache import robots_folder
    from pickstop.robot.selfcollision import disabled_pairs
    from pickstop.robot.travel import travel_of
    from pickstop.settings import cache_dir

    config, root = robots.config(name)
    key = (name, config.model_dump_json())
    if key not in robots.assets:
        robot = robots.planners.robot(config, root)
        disabled = disabled_pairs(robot, cache_dir=robots_folder(cache_dir(robots.data_dir)))
        robots.assets[key] = robot_assets(robot, travel_of(robot, disabled))
    assets: RobotAssets = robots.assets[key]
    return assets


def model_of(robots: RobotRegistry, name: str) -> dict[str, Any]:
    a = assets_of(robots, name)
    return {
        "name": a.name,
        "urdf": a.urdf,
        "files": sorted(a.files),
        "arm_joints": a.arm_joints,
        "joint_values": a.joint_values,
        "hand_joints": a.hand_joints,
        "travel": a.travel,
        "travel_collisions": [list(p) for p in a.travel_collisions],
    }


def file_of(robots: RobotRegistry, name: str, file_id: str) -> Path | None:
    """The server file behind one of the robot's file ids, confined at this open (None: no
    such file, or it now leads outside the allowed folders)."""
    path = assets_of(robots, name).files.get(file_id)
    if path is None:
        return None
    real = path.resolve(strict=False)
    roots = [Path(r).resolve() for r in robots.allowed_roots()]
    if not any(real.is_relative_to(r) for r in roots) or not real.is_file():
        return None
    return real


def check_of(robots: RobotRegistry, name: str) -> dict[str, Any]:
    """``pickstop robot check`` of a preset or registered robot (file names only, no paths)."""
    from pickstop.robot.check import check_config
    from pickstop.settings import cache_dir

    config, root = robots.config(name)
    # A check takes seconds (disabled pairs, the screen and its quality): once per config.
    key = (name, config.model_dump_json())
    if key not in robots.checks:
        robots.checks[key] = check_config(config, root, name, cache_dir(robots.data_dir))
    return dict(robots.checks[key])
