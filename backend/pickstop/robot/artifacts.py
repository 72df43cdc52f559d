"""Per-robot derived data that is slow to make: disabled pairs, the self-collision screen and
other geometry derived from the robot alone (:func:`derived`).

Kept in memory with the loaded robot (``RobotModel.derived``) and on disk per robot hash in the
one cache every data folder and process shares (:mod:`pickstop.robot.cache`), so a check, a
build, a region planner or a worker makes them once. A cache file that does not load, or
belongs to another robot, is made again.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

from pickstop.progress import Steps, step
from pickstop.robot.cache import COMPUTED, making, robots_folder, write_atomic
from pickstop.robot.cache import derived as derived  # where callers have found it
from pickstop.robot.model import RobotModel

_FORMAT = 2


def self_collision(
    robot: RobotModel, cache_dir: Path | None, steps: Steps | None = None
) -> tuple[Any, Any]:
    """``(DisabledPairs, SphereModel)`` of ``robot``; ``steps``: told how making them goes
    (:mod:`pickstop.progress`)."""
    from pickstop.robot.selfcollision import disabled_pairs

    hit = robot.derived.screen
    if hit is not None:
        return hit[0], hit[1]
    folder = robots_folder(cache_dir)
    path = None if folder is None else folder / f"screen-{robot.robot_hash[:24]}-v{_FORMAT}.pkl"
    disabled = disabled_pairs(robot, cache_dir=folder, steps=steps)
    kept = _read_screen(path, robot)
    if kept is None:
        with making(path):  # another process making it: wait, then read it
            kept = _read_screen(path, robot)
            if kept is None:
                kept = tightened_screen(robot, disabled, steps)
                COMPUTED["screen"] += 1
                if path is not None:
                    write_atomic(path, pickle.dumps((robot.robot_hash, *kept), protocol=5))
    robot.derived.screen = (disabled, *kept)
    return disabled, kept[0]


def _read_screen(path: Path | None, robot: RobotModel) -> tuple[Any, dict[str, float]] | None:
    """The cached ``(SphereModel, quality)`` of ``robot`` (None: none, or not trusted)."""
    from pickstop.robot.selfcollision import SphereModel

    if path is None or not path.is_file():
        return None
    try:
        with open(path, "rb") as f:
            stored_hash, model, quality = pickle.load(f)
    except Exception:  # an unreadable cache is rebuilt, never trusted
        return None
    if stored_hash != robot.robot_hash or not isinstance(model, SphereModel):
        return None
    return model, quality


def tightened_screen(
    robot: RobotModel, disabled: Any, steps: Steps | None = None
) -> tuple[Any, dict[str, float]]:
    """The sphere screen of ``robot`` and its measured quality: while it falsely rejects more
    than :data:`FALSE_REJECTION_BOUND` of valid configurations, the links nearest to contact
    in the falsely rejected ones get spheres half as far out and every distance grid a finer
    step (at most :data:`MAX_ROUNDS` rounds). ``quality["bound"]`` is the bound it was held
    to: a screen still above it says so (:func:`bound_missed`)."""
    from pickstop.robot.exact import rescreened, responsible_links, screen_trial
    from pickstop.robot.selfcollision import SphereModel

    excess: dict[str, float] = {}
    rounds, grid = 0, 0.01
    trial = None
    while True:
        what = "self-collision screen" + (f", tightening round {rounds}" if rounds else "")
        step(steps, f"{what}: covering the links")
        model = SphereModel.from_robot(robot, disabled, step=grid, link_excess=excess)
        # One trial per round on the same configurations: its figures, and (if they fall
        # short) the links to refine. Coal's verdicts on them are made once.
        if trial is None:
            trial = screen_trial(
                robot, disabled, model, QUALITY_SAMPLES, seed=7, steps=steps, what=what
            )
        else:
            trial = rescreened(robot, trial, model)
        quality = trial.figures()
        quality["rounds"] = float(rounds)
        quality["bound"] = FALSE_REJECTION_BOUND
        if quality["false_rejection"] <= FALSE_REJECTION_BOUND or rounds == MAX_ROUNDS:
            return model, quality
        rounds += 1
        grid *= 0.8  # and finer distance grids (their Lipschitz slack)
        step(steps, f"{what}: the links that reject valid configurations")
        for link in responsible_links(robot, disabled, trial):
            excess[link] = excess.get(link, model.excess) / 2


#: The screen may drop at most this fraction of valid configurations; a robot's screen that
#: drops more is tightened (finer spheres on the links responsible) until it does not.
FALSE_REJECTION_BOUND = 0.05
QUALITY_SAMPLES = 4000
MAX_ROUNDS = 3


def screen_quality(
    robot: RobotModel, cache_dir: Path | None, steps: Steps | None = None
) -> dict[str, float]:
    """The screen's figures against exact coal checks on random configurations (cached with
    the screen): ``false_rejection``, ``flagged``, ``colliding``, ``n``, ``rounds``,
    ``bound``."""
    self_collision(robot, cache_dir, steps)
    quality: dict[str, float] = robot.derived.screen[2]
    return quality


def bound_missed(quality: dict[str, float]) -> str | None:
    """What to say of a screen above its false-rejection bound (None: it meets it)."""
    bound = quality.get("bound", FALSE_REJECTION_BOUND)
    fr = quality["false_rejection"]
    if fr <= bound:
        return None
    rounds = quality.get("rounds")
    after = "" if rounds is None else f" after {int(rounds)} tightening rounds"
    return (
        f"the self-collision screen drops {100 * fr:.1f}% of valid configurations, over its "
        f"{100 * bound:g}% bound{after}: a database of this robot lacks that share of its "
        "reachable configurations (regions are smaller than they could be; nothing reported "
        "reachable collides)"
    )
