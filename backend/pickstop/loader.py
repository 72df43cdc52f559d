"""Load the heavy things a scene needs once: its robot, a database and a region planner."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from pickstop.regions.planner import RegionPlanner
from pickstop.robot.config import RobotConfig, load_config, resolve_robot
from pickstop.robot.model import RobotModel, load_robot
from pickstop.scene.model import Scene
from pickstop.settings import cache_dir
from pickstop.store.reach_catalog import open_database

if TYPE_CHECKING:  # the stop planner (and its solver, ortools) loads only when a plan is made
    from pickstop.sequence.plan import StopPlanner

_ROBOTS: dict[tuple[str, str], RobotModel] = {}
_PLANNERS: dict[tuple[str, str, str], RegionPlanner] = {}


def robot_for(config: RobotConfig, root: Path) -> RobotModel:
    """The robot model of ``config`` (paths from ``root``), built once per process: parsing
    the URDF and meshes takes about 50 ms, too much for every request."""
    key = (config.model_dump_json(), str(root))
    robot = _ROBOTS.get(key)
    if robot is None:
        robot = _ROBOTS[key] = load_robot(config, root)
    return robot


_STOP_PLANNERS: dict[int, StopPlanner] = {}


def planner_for(
    scene: Scene, scene_root: Path | None, data_dir: Path, db_id: str | None = None
) -> RegionPlanner:
    """The region planner of the scene's robot (kept per robot and database in this process)."""
    ref = scene.robot
    if ref.config is not None:
        path = Path(ref.config)
        if not path.is_absolute() and scene_root is not None:
            path = scene_root / path
        config, root = load_config(path)
    else:
        config, root = resolve_robot(ref.ref)
    robot = robot_for(config, root)
    key = (robot.robot_hash, db_id or "", str(data_dir))
    hit = _PLANNERS.get(key)
    if hit is not None:
        return hit
    db = open_database(data_dir, robot, db_id)
    planner = RegionPlanner(robot, db, cache_dir=cache_dir(data_dir))
    _PLANNERS[key] = planner
    return planner


def stop_planner_for(
    scene: Scene, scene_root: Path | None, data_dir: Path, db_id: str | None = None
) -> StopPlanner:
    """The stop planner (with its caches) over the scene's region planner."""
    from pickstop.sequence.plan import StopPlanner

    regions = planner_for(scene, scene_root, data_dir, db_id)
    sp = _STOP_PLANNERS.get(id(regions))
    if sp is None or sp.regions is not regions:
        sp = _STOP_PLANNERS[id(regions)] = StopPlanner(regions)
    return sp
