"""The regions of a scene from scratch: the region pipeline, nothing remembered.

:class:`PureRegions` answers what a plan asks of its regions
(:class:`~pickstop.sequence.steps.RegionSteps`) by running
:func:`~pickstop.regions.pipeline.compute_tray_region` for every tray and yaw, with no reuse
of refinements or cell answers and a kit whose memos of scenes start empty
(:meth:`~pickstop.regions.kit.RegionKit.scratch`). It is the algorithm the region planner
(:mod:`pickstop.speedups.region_planner`) speeds up with its caches, its reuse across layouts
and its workers.
"""

from __future__ import annotations

from dataclasses import dataclass

from pickstop.reach.database import ReachDatabase
from pickstop.regions.cells import TrayRegion
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import compute_tray_region, own_key
from pickstop.robot.model import RobotModel
from pickstop.scene.model import Scene


def tray_region(kit: RegionKit, scene: Scene, tray_id: str, yaw: float) -> TrayRegion:
    """The region of tray ``tray_id`` at base ``yaw`` [rad], computed from scratch."""
    tray = scene.tray(tray_id)
    return compute_tray_region(kit, scene, tray, yaw, own_key(kit, scene, tray, yaw))


def regions(kit: RegionKit, scene: Scene) -> dict[tuple[str, float], TrayRegion]:
    """The region of every task tray at every yaw of the scene's policy, from scratch."""
    return {
        (t, y): tray_region(kit, scene, t, y) for t in scene.task_trays for y in scene.base_yaw.yaws
    }


@dataclass(frozen=True)
class PureRegions:
    """:class:`~pickstop.sequence.steps.RegionSteps` from scratch over ``kit`` (a scratch kit:
    :meth:`~pickstop.regions.kit.RegionKit.scratch`)."""

    kit: RegionKit

    @property
    def robot(self) -> RobotModel:
        return self.kit.robot

    @property
    def db(self) -> ReachDatabase:
        return self.kit.db

    def regions(self, scene: Scene) -> dict[tuple[str, float], TrayRegion]:
        return regions(self.kit, scene)

    def tray_region(self, scene: Scene, tray_id: str, yaw: float | None = None) -> TrayRegion:
        yaw = scene.base_yaw.yaws[0] if yaw is None else yaw
        return tray_region(self.kit, scene, tray_id, yaw)

    def known_regions(
        self, scene: Scene, pairs: list[tuple[str, float]]
    ) -> dict[tuple[str, float], TrayRegion]:
        """Nothing is known from before: a preview computes every region exactly."""
        return {}
