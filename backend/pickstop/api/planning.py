"""Plans, previews and regions for requests, on the planners of the service's pool.

Each planner's caches are not thread-safe: every use holds its slot's lock, a request's ahead
of the background work that :mod:`pickstop.runtime.plan_ahead` schedules after plans and
previews.
"""

from __future__ import annotations

import contextlib
import json
import logging
from collections.abc import Callable
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

from pickstop.api.registry import RobotRegistry
from pickstop.errors import PickStopError
from pickstop.pool import PlannerPool, PlannerSlot
from pickstop.runtime.plan_ahead import PlanAhead
from pickstop.scene.model import Order, Scene
from pickstop.sequence.mix import MixPlans, plan_mix
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.sequence.request import route_points, route_yaws
from pickstop.sequence.rules import Rule, RuleName, cut_off, judge

if TYPE_CHECKING:
    from pickstop.fleet.proof import PlanProof

log = logging.getLogger("pickstop.api")


class Planning:
    """The service's planning: a request's scene -> its robot's planners -> a plan."""

    def __init__(self, pool: PlannerPool, robots: RobotRegistry, background: Executor) -> None:
        self.pool = pool
        self.robots = robots
        self.ahead = PlanAhead(background)

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

    def _locked(self, slot: PlannerSlot) -> contextlib.AbstractContextManager[None]:
        """Hold the slot's lock for a request, ahead of any background work waiting for it."""
        return self.ahead.request(slot.lock)

    def plan(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        slot = self.slot(scene, db_id)
        with self._locked(slot):
            plan = slot.planner.plan(scene, options)
        self.ahead.after_plan(slot.planner, slot.lock, scene, options)
        return plan

    def preview(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        """An unverified plan to draw while the layout is edited (``StopPlanner.preview``);
        once no request has come for a moment, the layout's exact plan is made in the
        background (:meth:`~pickstop.runtime.plan_ahead.PlanAhead.after_preview`)."""
        slot = self.slot(scene, db_id)
        with self._locked(slot):
            plan = slot.planner.preview(scene, options)
        self.ahead.after_preview(slot.planner, slot.lock, scene, options)
        return plan

    def plan_mix(
        self,
        scene: Scene,
        orders: list[Order],
        options: PlanOptions,
        db_id: str | None = None,
        prepare: list[Order] | None = None,
    ) -> MixPlans:
        """Every order's plan on the scene's layout (:func:`pickstop.sequence.mix.plan_mix`;
        ``prepare``: the orders whose regions to compute first). Nothing is planned ahead."""
        slot = self.slot(scene, db_id)
        with self._locked(slot):
            return plan_mix(slot.planner, scene, orders, options, prepare=prepare)

    def guidance(
        self,
        scene: Scene,
        tray: str,
        order: str | None = None,
        mix: bool = False,
        sigma: float | None = None,
        db_id: str | None = None,
    ) -> dict[str, Any]:
        """Placement guidance for ``tray`` (:func:`pickstop.layout.guidance.guidance`) as
        GeoJSON: with the partners of the order ``order``, of every order (``mix``), or of
        the task."""
        from pickstop.layout.guidance import guidance, guidance_geojson, partner_groups

        slot = self.slot(scene, db_id)
        groups = partner_groups(scene, tray, order, mix)
        with self._locked(slot):
            g = guidance(slot.regions, scene, tray, groups, sigma)
        return guidance_geojson(g)

    def layout(
        self,
        scene: Scene,
        orders: list[Order],
        movable: list[str],
        options: PlanOptions,
        settings: Any,
        db_id: str | None = None,
        progress: Callable[[float, str], None] | None = None,
    ) -> dict[str, Any]:
        """Suggested layouts (:func:`pickstop.layout.search.suggest`) as the layout document;
        the planners are held while the search runs."""
        from pickstop.layout.search import suggest
        from pickstop.layout.verify import LocalEvaluator

        slot = self.slot(scene, db_id)
        with self._locked(slot):
            evaluator = LocalEvaluator(slot.planner, orders, options)
            try:
                doc = suggest(slot.regions, evaluator, scene, orders, movable, options, settings,
                              progress)  # fmt: skip
            finally:
                evaluator.close()
        return doc.model_dump(mode="json")

    def prove(self, scene: Scene, plan: Plan) -> PlanProof:
        """The plan's tolerances proven by the exact check over its own database
        (:func:`pickstop.fleet.proof.prove_plan`), its planners held meanwhile."""
        from pickstop.fleet.pickcheck import exact_checker
        from pickstop.fleet.proof import prove_plan

        robot = self.robots.model(scene.robot.ref)
        slot = self.pool.slot(robot, plan.database)
        with self._locked(slot):
            return prove_plan(exact_checker(self.pool, scene, plan.database, robot), plan)

    def plan_json(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> bytes:
        """:meth:`plan` as the JSON the API answers with, serialised once where it is made
        (a planner process then sends bytes, not a model to pickle and serialise again)."""
        return self.plan(scene, options, db_id).model_dump_json().encode()

    def preview_json(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> bytes:
        """:meth:`preview` as JSON (see :meth:`plan_json`)."""
        return self.preview(scene, options, db_id).model_dump_json().encode()

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
        from pickstop.scene.positioning import of_scene

        slot = self.slot(scene, db_id)
        sigma = scene.sigma if sigma is None else sigma
        with self._locked(slot):
            sp = slot.planner
            regions = sp.regions.regions(scene)
            cands = sp.candidates(regions)
            points, yaws = route_points(scene, cands), route_yaws(scene, cands)
            dist = sp.paths(sp.floor(scene), points, yaws).dist
        verdicts = cut_off(
            judge(
                Rule(rule, sigma, scene.error_model.kind, target, 0, of_scene(scene, sigma)), cands
            ),
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
