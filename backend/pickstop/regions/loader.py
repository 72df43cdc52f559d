"""Load the heavy things a scene needs once: its robot, a database and a region planner."""

from __future__ import annotations

from pathlib import Path

from pickstop.reach.database import open_database
from pickstop.regions.base_region import RegionPlanner
from pickstop.robot.config import load_config, resolve_robot
from pickstop.robot.model import load_robot
from pickstop.scene.model import Scene
from pickstop.sequence.plan import StopPlanner
from pickstop.settings import cache_dir

_PLANNERS: dict[tuple[str, str, str], RegionPlanner] = {}
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
    robot = load_robot(config, root)
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
    regions = planner_for(scene, scene_root, data_dir, db_id)
    sp = _STOP_PLANNERS.get(id(regions))
    if sp is None or sp.regions is not regions:
        sp = _STOP_PLANNERS[id(regions)] = StopPlanner(regions)
    return sp
