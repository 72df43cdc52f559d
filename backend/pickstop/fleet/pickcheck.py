"""Is a tray's every part still graspable from where the base actually stopped?

The plan's own off-grid test (:func:`pickstop.regions.offgrid.feasible_near`: footprint,
IK by query, refinement seeded by the region's nearest verified cells, exact collision checks),
the one its stop centres and Monte Carlo samples pass, at the real pose instead of a sample.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import shapely

from pickstop.caching import Cache
from pickstop.errors import InputError
from pickstop.fleet.route import guaranteed_radius
from pickstop.fleet.tolerance import StopShapes, stop_shapes
from pickstop.frames import angle_gap
from pickstop.regions.cells import TrayRegion
from pickstop.regions.offgrid import feasible_near
from pickstop.scene.model import Scene
from pickstop.sequence import plan_model as pm
from pickstop.speedups.region_planner import RegionPlanner

if TYPE_CHECKING:
    from pickstop.pool import PlannerPool
    from pickstop.robot.model import RobotModel

CACHE = 4096  # results kept per checker (poses repeat across runs only by chance)


class PickChecker:
    """``checker(tray_id, x, y, yaw) -> (ok, reason)`` for one scene; thread-safe."""

    def __init__(self, planner: RegionPlanner, scene: Scene) -> None:
        self.planner, self.scene = planner, scene
        self._lock = threading.Lock()
        with self._lock:
            self.regions: dict[tuple[str, float], TrayRegion] = planner.regions(scene)
        self._cache: Cache[tuple[str, float, float, float], tuple[bool, str]] = Cache(
            "pick_checker", max_items=CACHE
        )
        self.calls = 0

    def region(self, tray_id: str, yaw: float) -> TrayRegion | None:
        """The tray's region at the scene's base yaw nearest ``yaw``."""
        mine = [(t, y) for t, y in self.regions if t == tray_id]
        if not mine:
            return None

        return self.regions[min(mine, key=lambda k: angle_gap(k[1], yaw))]

    def __call__(self, tray_id: str, x: float, y: float, yaw: float) -> tuple[bool, str]:
        key = (tray_id, round(x, 6), round(y, 6), round(yaw, 6))
        with self._lock:
            hit = self._cache.get(key)
            if hit is not None:
                return hit
            region = self.region(tray_id, yaw)
            if region is None:
                out = (False, f"tray {tray_id!r} is not in the scene")
            else:
                self.calls += 1
                ok, _, _ = feasible_near(
                    self.planner, self.scene, region, np.array([[x, y]]), yaw, seeds_first=True
                )
                out = (
                    (True, "graspable collision-free")
                    if ok[0]
                    else (False, f"no collision-free grasp of every part of tray {tray_id} "
                                 "from this base pose (exact check)")
                )  # fmt: skip
            return self._cache.put(key, out)

    def many(self, tray_id: str, xy: np.ndarray, yaw: float) -> np.ndarray:
        """The exact test of one tray at base poses ``xy: (M, 2)`` [m], ``yaw`` [rad]:
        ``ok: (M,)`` (uncached; one batch)."""
        with self._lock:
            region = self.region(tray_id, yaw)
            if region is None:
                return np.zeros(len(xy), bool)
            self.calls += len(xy)
            return feasible_near(self.planner, self.scene, region, np.asarray(xy, float), yaw)[0]

    def shapes(self, plan: pm.Plan) -> tuple[StopShapes, ...]:
        """Each stop's tolerance circle and ellipse, checked off the grid by the exact test
        (:func:`pickstop.fleet.tolerance.stop_shapes`), in stop order."""
        out = []
        for s in plan.stops:
            regions = [self.region(t, s.yaw) for t in s.trays]
            if any(r is None for r in regions) or not regions:
                raise InputError(f"stops.{s.index}: a tray of the stop is not in the scene",
                                 field=f"stops.{s.index}")  # fmt: skip
            inter = shapely.intersection_all([r.polygon for r in regions if r is not None])
            res = regions[0].grid.res  # type: ignore[union-attr]
            out.append(
                stop_shapes(self.many, s.trays, (s.x, s.y), s.yaw, inter, guaranteed_radius(s), res)
            )
        return tuple(out)


def exact_checker(
    pool: PlannerPool,
    scene: Scene,
    db_id: str | None,
    robot: RobotModel | None = None,
    scene_root: Path | None = None,
) -> PickChecker:
    """The exact checker of ``scene`` over the pool's planners of its robot and the
    database ``db_id`` (None: the robot's default): ``robot`` as loaded already, else the one
    the scene names (a config path from ``scene_root``). Its planners' caches are not
    thread-safe: where others use the same pool, hold the slot's lock while it runs."""
    slot = pool.scene_slot(scene, scene_root, db_id) if robot is None else pool.slot(robot, db_id)
    return PickChecker(slot.regions, scene)
