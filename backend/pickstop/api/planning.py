"""Plans, previews and regions for requests, on the planners of the service's pool.

Each planner's caches are not thread-safe: every use holds its slot's lock. After a plan, the
other candidates' centres are verified in the background, one at a time, so that the next
change of sigma (the 3D planner's slider) finds its stops checked.
"""

from __future__ import annotations

import json
import logging
from concurrent.futures import Executor
from typing import Any

import numpy as np
import shapely

from pickstop.api.registry import RobotRegistry
from pickstop.errors import PickStopError
from pickstop.pool import PlannerPool, PlannerSlot
from pickstop.scene.model import Scene
from pickstop.sequence.plan import route_points, route_yaws
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.sequence.rules import Rule, RuleName, cut_off, judge

log = logging.getLogger("pickstop.api")


class Planning:
    """The service's planning: a request's scene -> its robot's planners -> a plan."""

    def __init__(self, pool: PlannerPool, robots: RobotRegistry, background: Executor) -> None:
        self.pool = pool
        self.robots = robots
        self.background = background

    def slot(self, scene: Scene, db_id: str | None = None) -> PlannerSlot:
        """The planners of the scene's robot (a preset or registered) over ``db_id``."""
        return self.pool.slot(self.robots.model(scene.robot.ref), db_id)

    def preload(self) -> None:
        """Load the default robot's planners if it has a database (at start-up)."""
        try:
            self.pool.preload()
        except PickStopError as e:
            log.warning("default planner not loaded: %s", e.message)

    @property
    def loaded(self) -> list[dict[str, Any]]:
        return [{"robot": s.regions.robot.name, "database": s.regions.db.id}
                for s in self.pool.slots]  # fmt: skip

    def plan(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        slot = self.slot(scene, db_id)
        with slot.lock:
            plan = slot.planner.plan(scene, options)
        self.background.submit(self._prefetch, slot, scene)
        return plan

    def preview(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        """An unverified plan to draw while the layout is edited (``StopPlanner.preview``)."""
        slot = self.slot(scene, db_id)
        with slot.lock:
            return slot.planner.preview(scene, options)

    def _prefetch(self, slot: PlannerSlot, scene: Scene) -> None:
        try:
            slot.planner.prefetch_checks(scene, slot.lock)
        except Exception:  # a background nicety: never let it disturb a request
            log.exception("prefetching candidate checks failed")

    def regions(
        self,
        scene: Scene,
        sigma: float | None,
        db_id: str | None,
        rule: RuleName = "sigma",
        target: float = 0.95,
    ) -> dict[str, Any]:
        """Regions and intersections, each candidate judged as a plan with this rule would."""
        from pickstop.regions.geojson import region_feature

        slot = self.slot(scene, db_id)
        sigma = scene.sigma if sigma is None else sigma
        with slot.lock:
            sp = slot.planner
            regions = sp.regions.regions(scene)
            cands = sp.candidates(regions)
            points, yaws = route_points(scene, cands), route_yaws(scene, cands)
            dist = sp.paths(sp.floor(scene), points, yaws).dist
        verdicts = cut_off(
            judge(Rule(rule, sigma, scene.error_model.kind, target), cands),
            [bool(np.isfinite(dist[0, i + 2])) for i in range(len(cands))],
        )
        names = {t.id: t.name for t in scene.trays}
        return {
            "database": sp.regions.db.id,
            "sigma": sigma,
            "rule": rule,
            "target": target,
            "regions": {
                "type": "FeatureCollection",
                "features": [region_feature(r, names.get(r.tray_id, "")) for r in regions.values()],
            },
            "intersections": {
                "type": "FeatureCollection",
                "features": [
                    {
                        "type": "Feature",
                        "geometry": json.loads(shapely.to_geojson(c.polygon)),
                        "properties": {
                            "trays": sorted(c.trays),
                            "order": c.order,
                            "yaw": c.yaw,
                            "centre": list(c.centre),
                            "inscribed_radius": c.radius,
                            "area_m2": c.polygon.area,
                            "kept": v.kept,
                            "reason": v.reason,
                            "predicted_success": v.predicted,
                        },
                    }
                    for c, v in zip(cands, verdicts, strict=True)
                ],
            },
        }
