"""Stored plans' tolerances proven by the exact check, made once per plan and kept.

The first export or dispatch that asks for a plan's proven tolerances makes them on the
service's planning (the planner process by default) over the plan's own scene, robot and
database, and keeps them in the records (``plan_proofs``); every later one reads them. A plan
never changes and a proof is a fact about its poses and the robot's geometry, so a kept proof
stays valid even once the database it was made over is deleted.
"""

from __future__ import annotations

import threading
from typing import Any

from pickstop.api.problems import Problem
from pickstop.api.registry import RobotRegistry
from pickstop.api.scene_checks import SceneChecks
from pickstop.fleet.proof import PROVER, PlanProof
from pickstop.sequence import plan_model as pm
from pickstop.store import reach_catalog
from pickstop.store.records import ServiceStore

POLL = 0.05  # [s] between tries for the lock (a stopped request's thread leaves within one)


class PlanProofs:
    """``proof(plan_id, plan, scene_doc)``: the plan's :class:`PlanProof`, made at most once."""

    def __init__(
        self, store: ServiceStore, robots: RobotRegistry, scenes: SceneChecks, planning: Any
    ) -> None:
        """planning: the service's (its ``prove(scene, plan)``)."""
        self.store, self.robots, self.scenes, self.planning = store, robots, scenes, planning
        self._lock = threading.Lock()  # one proof made at a time: a second asker reads it
        self.made = 0  # proofs made by this service (the others were read)

    def kept(self, plan_id: str) -> PlanProof | None:
        doc = self.store.plan_proof(plan_id, PROVER)
        return None if doc is None else PlanProof.of_json(doc)

    def proof(self, plan_id: str, plan: pm.Plan, scene_doc: dict[str, Any]) -> PlanProof:
        """The kept proof, else one made now (seconds: thousands of exact tests per stop,
        for at most ``max_trays`` stops) and kept."""
        hit = self.kept(plan_id)
        if hit is not None:
            return hit
        while not self._lock.acquire(timeout=POLL):
            pass
        try:
            hit = self.kept(plan_id)  # made while this request waited
            if hit is not None:
                return hit
            scene = self._inputs(plan_id, plan, scene_doc)
            proof: PlanProof = self.planning.prove(scene, plan)
            self.made += 1
            self.store.add_plan_proof(plan_id, PROVER, proof.to_json())
            return proof
        finally:
            self._lock.release()

    def _inputs(self, plan_id: str, plan: pm.Plan, scene_doc: dict[str, Any]) -> Any:
        """The plan's scene, once its robot and database are known to be here and its stops
        within the limit; else a 409 or 422 naming what is missing."""
        if not self.robots.exists(plan.robot):
            raise Problem(409, "Robot missing", f"plan {plan_id} was made for robot "
                          f"{plan.robot!r}, which this service does not know (neither a preset "
                          "nor registered): its tolerances cannot be proven; register the "
                          "robot, or ask for tolerances=radius", kind="robot-missing",
                          field="robot")  # fmt: skip
        row = reach_catalog.database_row(self.store.catalog, plan.database)
        if row is None or row["state"] != "complete":
            what = "is gone" if row is None else f"is {row['state']}, not complete"
            raise Problem(409, "Database missing", f"plan {plan_id} was made over reachability "
                          f"database {plan.database}, which {what}: its tolerances cannot be "
                          "proven; ask for tolerances=radius (the plan's own radius and the "
                          "scene's yaw error)", kind="database-missing",
                          field="database")  # fmt: skip
        limit = self.scenes.limits.max_trays
        if len(plan.stops) > limit:  # a stop picks one tray at least: never for a plan stored
            raise Problem(422, "Too many stops", f"plan {plan_id} has {len(plan.stops)} stops, "
                          f"more than the {limit} whose tolerances are proven (max_trays)",
                          kind="validation", field="stops")  # fmt: skip
        return self.scenes.parse(scene_doc)
