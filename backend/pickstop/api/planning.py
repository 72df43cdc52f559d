"""Plans, previews and regions for requests, on the planners of the service's pool.

Each planner's caches are not thread-safe: every use holds its slot's lock. After a plan, the
plans of the neighbouring sigma bands and of the other objective are made in the background
(their stop selections kept), then the other candidates' centres are verified, one at a time,
so that the next change of sigma (the 3D planner's slider) finds its selection made and its
stops checked.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

from pickstop.api.registry import RobotRegistry
from pickstop.errors import PickStopError
from pickstop.pool import PlannerPool, PlannerSlot
from pickstop.scene.model import Order, Scene
from pickstop.sequence.mix import MixPlans, plan_mix
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.sequence.request import route_points, route_yaws
from pickstop.sequence.rules import Rule, RuleName, cut_off, judge

if TYPE_CHECKING:
    from pickstop.fleet.proof import PlanProof

log = logging.getLogger("pickstop.api")

QUIET = 0.1  # [s] without a new plan before the last one's are planned ahead
# [s] without a newer request before a previewed layout's exact plan is made ahead: a drag
# asks for previews several times a second; holding still for this long is a pause.
HOLD = 0.25


class _Yielding:
    """A slot's lock as background work takes it: only while no request waits for it, so a
    request waits at most for the one background step under way."""

    def __init__(self, lock: Any, waiting: Any) -> None:
        self.lock, self.waiting = lock, waiting

    def acquire(self) -> bool:
        while True:
            while self.waiting():
                time.sleep(0.002)
            self.lock.acquire()
            if not self.waiting():
                return True
            self.lock.release()

    def release(self) -> None:
        self.lock.release()

    def __enter__(self) -> _Yielding:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


class Planning:
    """The service's planning: a request's scene -> its robot's planners -> a plan."""

    def __init__(self, pool: PlannerPool, robots: RobotRegistry, background: Executor) -> None:
        self.pool = pool
        self.robots = robots
        self.background = background
        self._generation = 0  # plans made: a prefetch of an older one stops early
        self._waiting = 0  # requests waiting for a slot's lock (background work gives way)
        self._count = threading.Lock()

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

    @contextlib.contextmanager
    def _locked(self, slot: PlannerSlot) -> Iterator[None]:
        """Hold the slot's lock for a request, ahead of any background work waiting for it."""
        with self._count:
            self._waiting += 1
        try:
            slot.lock.acquire()
        finally:
            with self._count:
                self._waiting -= 1
        try:
            yield
        finally:
            slot.lock.release()

    def plan(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        slot = self.slot(scene, db_id)
        with self._locked(slot):
            plan = slot.planner.plan(scene, options)
        self._generation += 1
        self.background.submit(self._prefetch, slot, scene, options, self._generation)
        return plan

    def preview(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        """An unverified plan to draw while the layout is edited (``StopPlanner.preview``);
        once no request has come for :data:`HOLD` seconds, the layout's exact plan is made
        in the background (:meth:`_plan_ahead`)."""
        slot = self.slot(scene, db_id)
        with self._locked(slot):
            plan = slot.planner.preview(scene, options)
        self._generation += 1
        self.background.submit(self._plan_ahead, slot, scene, options, self._generation)
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

    def _prefetch(
        self, slot: PlannerSlot, scene: Scene, options: PlanOptions, generation: int
    ) -> None:
        """The plans of the neighbouring sigma bands and the other objective (what the 3D
        planner's slider and switch ask next), then every candidate's centre check; begun
        once no plan has been asked for in :data:`QUIET` seconds (a slider gesture's steps
        are not slowed by work for the steps it has already left)."""

        def work(lock: _Yielding, stale: Callable[[], bool]) -> None:
            slot.planner.prefetch_selections(scene, options, lock, stale=stale)
            slot.planner.prefetch_checks(scene, lock, stale=stale)

        self._when_quiet(slot, generation, QUIET, work)

    def _plan_ahead(
        self, slot: PlannerSlot, scene: Scene, options: PlanOptions, generation: int
    ) -> None:
        """The exact plan of a previewed layout (``StopPlanner.plan_ahead``), begun once
        nothing newer has been asked for in :data:`HOLD` seconds (the editor paused its
        drag)."""
        self._when_quiet(
            slot,
            generation,
            HOLD,
            lambda lock, stale: slot.planner.plan_ahead(scene, options, lock, stale=stale),
        )

    def _when_quiet(
        self,
        slot: PlannerSlot,
        generation: int,
        quiet: float,
        work: Callable[[_Yielding, Callable[[], bool]], object],
    ) -> None:
        """``work(lock, stale)`` in the background once no request has come for ``quiet``
        seconds since the one of ``generation``: under the slot's lock as background work
        takes it (it gives way to any request), given up once ``stale()`` (a newer request
        came). Never lets an error disturb a request: a layout without a plan is left for a
        request to explain, anything else is logged."""

        def stale() -> bool:
            return self._generation != generation

        end = time.monotonic() + quiet
        while not stale() and time.monotonic() < end:
            time.sleep(0.01)
        if stale():
            return
        try:
            work(_Yielding(slot.lock, lambda: self._waiting > 0), stale)
        except PickStopError:
            pass
        except Exception:
            log.exception("planning ahead failed")

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
