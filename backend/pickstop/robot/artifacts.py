"""Per-robot derived data that is slow to make: disabled pairs, the self-collision screen and
other geometry derived from the robot alone (:func:`derived`).

Kept in memory with the loaded robot (``RobotModel.memo``) and on disk per robot hash
(``<cache>/robots/``), so a build, a region planner or a worker makes them once. A cache file
that does not load, or belongs to another robot, is made again.
"""

from __future__ import annotations

import os
import pickle
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from pickstop.robot.model import RobotModel

T = TypeVar("T")

_FORMAT = 2
_SCREEN = "self_collision"  # robot.memo entry: (DisabledPairs, SphereModel, quality figures)


def self_collision(robot: RobotModel, cache_dir: Path | None) -> tuple[Any, Any]:
    """``(DisabledPairs, SphereModel)`` of ``robot``."""
    from pickstop.robot.selfcollision import SphereModel, disabled_pairs

    hit = robot.memo.get(_SCREEN)
    if hit is not None:
        return hit[0], hit[1]
    folder = None if cache_dir is None else Path(cache_dir) / "robots"
    path = None if folder is None else folder / f"screen-{robot.robot_hash[:24]}-v{_FORMAT}.pkl"
    disabled = disabled_pairs(robot, cache_dir=folder)
    model, quality = None, {}
    if path is not None and path.is_file():
        try:
            with open(path, "rb") as f:
                stored_hash, model, quality = pickle.load(f)
            if stored_hash != robot.robot_hash or not isinstance(model, SphereModel):
                model = None
        except Exception:  # an unreadable cache is rebuilt, never trusted
            model = None
    if model is None:
        model, quality = tightened_screen(robot, disabled)
        if path is not None:
            _write(path, (robot.robot_hash, model, quality))
    robot.memo[_SCREEN] = (disabled, model, quality)
    return disabled, model


def derived(robot: RobotModel, cache_dir: Path | None, name: str, make: Callable[[], T]) -> T:
    """``make()``, a value that depends on nothing but ``robot`` (and ``name``, which says what
    and how it is made), kept on disk per robot hash in ``<cache>/robots/``; a cache file that
    does not load, or belongs to another robot or kind, is made again."""
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / "robots" / f"{name}-{robot.robot_hash[:24]}-v{_FORMAT}.pkl"
        if path.is_file():
            try:
                with open(path, "rb") as f:
                    stored_hash, stored_name, value = pickle.load(f)
                if stored_hash == robot.robot_hash and stored_name == name:
                    return value
            except Exception:  # an unreadable cache is rebuilt, never trusted
                pass
    value = make()
    if path is not None:
        _write(path, (robot.robot_hash, name, value))
    return value


def _write(path: Path, payload: Any) -> None:
    """Pickle ``payload`` to ``path`` atomically (temporary file, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "wb") as f:
        pickle.dump(payload, f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)


def tightened_screen(robot: RobotModel, disabled: Any) -> tuple[Any, dict[str, float]]:
    """The sphere screen of ``robot`` and its measured quality: while it falsely rejects more
    than :data:`FALSE_REJECTION_BOUND` of valid configurations, the links nearest to contact
    in the falsely rejected ones get spheres half as far out and every distance grid a finer
    step (at most three rounds)."""
    from pickstop.robot.exact import responsible_links, screen_trial
    from pickstop.robot.selfcollision import SphereModel

    excess: dict[str, float] = {}
    rounds, step = 0, 0.01
    while True:
        model = SphereModel.from_robot(robot, disabled, step=step, link_excess=excess)
        # One trial per round: its figures, and (if they fall short) the links to refine.
        trial = screen_trial(robot, disabled, model, QUALITY_SAMPLES, seed=7)
        quality = trial.figures()
        quality["rounds"] = float(rounds)
        if quality["false_rejection"] <= FALSE_REJECTION_BOUND or rounds == 3:
            return model, quality
        rounds += 1
        step *= 0.8  # and finer distance grids (their Lipschitz slack)
        for link in responsible_links(robot, disabled, trial):
            excess[link] = excess.get(link, model.excess) / 2


#: The screen may drop at most this fraction of valid configurations; a robot's screen that
#: drops more is tightened (finer spheres on the links responsible) until it does not.
FALSE_REJECTION_BOUND = 0.05
QUALITY_SAMPLES = 4000


def screen_quality(robot: RobotModel, cache_dir: Path | None) -> dict[str, float]:
    """The screen's figures against exact coal checks on random configurations (cached with
    the screen): ``false_rejection``, ``flagged``, ``colliding``, ``n``, ``rounds``."""
    self_collision(robot, cache_dir)
    quality: dict[str, float] = robot.memo[_SCREEN][2]
    return quality
