"""Per-robot derived data that is slow to make: disabled pairs and the self-collision screen.

Kept in memory per process and on disk per robot hash (``<cache>/robots/``), so a build, a
region planner or a worker makes them once. A cache file that does not load, or belongs to
another robot, is made again.
"""

from __future__ import annotations

import os
import pickle
import tempfile
from pathlib import Path
from typing import Any

from pickstop.robot.model import RobotModel

_FORMAT = 1
_MEMO: dict[str, tuple[Any, Any]] = {}


def self_collision(robot: RobotModel, cache_dir: Path | None) -> tuple[Any, Any]:
    """``(DisabledPairs, SphereModel)`` of ``robot``."""
    from pickstop.robot.selfcollision import SphereModel, disabled_pairs

    hit = _MEMO.get(robot.robot_hash)
    if hit is not None:
        return hit
    folder = None if cache_dir is None else Path(cache_dir) / "robots"
    path = None if folder is None else folder / f"screen-{robot.robot_hash[:24]}-v{_FORMAT}.pkl"
    disabled = disabled_pairs(robot, cache_dir=folder)
    model = None
    if path is not None and path.is_file():
        try:
            with open(path, "rb") as f:
                stored_hash, model = pickle.load(f)
            if stored_hash != robot.robot_hash or not isinstance(model, SphereModel):
                model = None
        except Exception:  # an unreadable cache is rebuilt, never trusted
            model = None
    if model is None:
        model = SphereModel.from_robot(robot, disabled)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
            with os.fdopen(fd, "wb") as f:
                pickle.dump((robot.robot_hash, model), f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, path)
    _MEMO[robot.robot_hash] = (disabled, model)
    return disabled, model
