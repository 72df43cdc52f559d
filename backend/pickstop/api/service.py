"""What the REST service holds for its lifetime, composed of one part per concern.

- ``robots`` (:mod:`pickstop.api.registry`): presets and registered robots, files confined;
- ``scenes`` (:mod:`pickstop.api.scene_checks`): a request's scenes and options checked
  against the limits;
- ``planners`` (:class:`pickstop.pool.PlannerPool`): robot -> database -> planners, loaded
  once per robot and database and shared by requests, each with its lock;
- ``planning`` (:mod:`pickstop.api.planning`): plans, previews and regions on them;
- ``bodies`` (:mod:`pickstop.api.plan_bodies`): stored plans as the bytes the API answers;
- ``proofs`` (:mod:`pickstop.api.plan_proofs`): stored plans' proven tolerances, made once;
- ``jobs`` (:mod:`pickstop.api.jobs`): builds, batch plans and mixes
  (:mod:`pickstop.api.mixes`), one at a time, recorded in SQLite so that their state survives
  a restart.

CPU-heavy work (regions, plans) runs off the event loop: in a planner process
(:mod:`pickstop.runtime.planner_process`, the default) or in the ``threads`` pool.
"""

from __future__ import annotations

import contextlib
import shutil
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from pickstop.api import limits as lim
from pickstop.api.jobs import JobRunner, batch_job, build_job
from pickstop.api.layouts import layout_job, layout_params
from pickstop.api.mixes import mix_job, request_orders
from pickstop.api.plan_bodies import PlanBodies
from pickstop.api.plan_proofs import PlanProofs
from pickstop.api.planning import Planning
from pickstop.api.registry import RobotRegistry
from pickstop.api.scene_checks import SceneChecks
from pickstop.errors import DatabaseBusyError, InputError
from pickstop.pool import PlannerPool
from pickstop.runtime import planner_process
from pickstop.runtime.planner_process import PlannerProcess
from pickstop.settings import Settings
from pickstop.store import reach_catalog
from pickstop.store.records import ServiceStore


class Service:
    def __init__(
        self, settings: Settings, job_runner: bool = True, planners: PlannerPool | None = None
    ) -> None:
        """job_runner: this process runs the jobs (one process of a worker pool does);
        planners: a pool loaded already (by the parent of forked workers), else a new one."""
        self.settings = settings
        self.limits = lim.Limits.of(settings)
        self.key_hashes = frozenset(k.strip() for k in settings.api_keys if k.strip())
        self.data_dir = Path(settings.data_dir)
        self.data_dir.mkdir(parents=True, exist_ok=True)
        self.store = ServiceStore(self.data_dir)
        self.threads = ThreadPoolExecutor(max_workers=2, thread_name_prefix="pickstop-plan")
        self.planners = (
            planners
            if planners is not None
            else PlannerPool(self.data_dir, settings.region_processes, settings.default_databases)
        )
        self.robots = RobotRegistry(self.store, self.data_dir, self.planners)
        self.scenes = SceneChecks(self.limits, self.data_dir, self.store, self.robots)
        # Plans, previews and regions run in a child process (planner_process.py) unless the
        # settings keep them on this process's threads.
        self.planning: Planning | PlannerProcess = (
            PlannerProcess(settings, f"{__name__}:planner_child")
            if settings.planner_processes > 0
            else Planning(self.planners, self.robots, self.threads)
        )
        self.bodies = PlanBodies(self.store)
        self.proofs = PlanProofs(self.store, self.robots, self.scenes, self.planning)
        kinds = {
            "build": build_job(self.robots, self.data_dir, self.after_build),
            "batch": batch_job(self.scenes.parse, self.planning.plan),
            "mix": mix_job(self.scenes.parse, self.planning.plan_mix, self.limits),
            "layout": layout_job(self.scenes.parse, self.planning.layout),
        }
        self.jobs = JobRunner(self.store, settings, kinds, start=job_runner)
        if job_runner:
            self.purge_interrupted()

    def close(self) -> None:
        self.jobs.close()
        self.threads.shutdown(wait=False, cancel_futures=True)
        if isinstance(self.planning, PlannerProcess):
            self.planning.close()
        self.planners.close()

    # -- submissions: every check a job would meet, made before it is queued -----------------
    def submit_plan_job(self, body: Any) -> dict[str, Any]:
        self.scenes.prepare(body)
        item = {"scene_id": body.scene_id, "scene": body.scene}
        return self.jobs.submit("batch", {"scenes": [item], "options": body.options.model_dump(),
                                          "database": body.database})  # fmt: skip

    def submit_mix_job(self, body: Any) -> dict[str, Any]:
        """A mix as a job, its scene, options and orders checked first."""
        _, _, scene = self.scenes.prepare(body)
        request_orders(body.orders, scene, self.limits)
        orders = body.orders if body.orders == "scene" else [o.model_dump() for o in body.orders]
        return self.jobs.submit("mix", {"scene_id": body.scene_id, "scene": body.scene,
                                        "orders": orders, "options": body.options.model_dump(),
                                        "database": body.database})  # fmt: skip

    def submit_layout(self, body: Any) -> dict[str, Any]:
        """A layout search as a job, its scene, options, orders and movable trays checked."""
        _, _, scene = self.scenes.prepare(body)
        return self.jobs.submit("layout", layout_params(body, scene, self.limits))

    def submit_batch(self, body: Any) -> dict[str, Any]:
        self.scenes.check_options(body.options)
        for i, item in enumerate(body.scenes):  # a bad scene is a 422 now, not a failed job
            self.scenes.prepare(item, f"scenes.{i}.")
        return self.jobs.submit("batch", body.model_dump())

    def submit_build(self, body: Any) -> dict[str, Any]:
        from pickstop.reach.build import BuildParams

        if "samples" not in body.model_fields_set:  # the default, within this server's limit
            body = body.model_copy(update={"samples": min(body.samples, self.settings.max_samples)})
        if body.samples > self.settings.max_samples:
            raise InputError(f"samples {body.samples} exceeds the limit of "
                             f"{self.settings.max_samples}", field="samples")  # fmt: skip
        try:
            self.robots.config(body.robot)  # unknown robot: 422 now, not a failed job later
        except InputError as e:
            raise InputError(e.message, field="robot") from None
        params = body.model_dump()
        BuildParams(**{k: v for k, v in params.items() if k != "robot"}).validate()
        return self.jobs.submit("build", params)

    def delete_database(self, db_id: str) -> bool:
        """Delete a reachability database: its planners, its catalog rows and its files;
        False if there is none. One being built is refused (cancel its build first)."""
        cat = self.store.catalog
        if not reach_catalog.delete_database(cat, db_id):  # refused while being built
            return False
        self.planners.drop_database(db_id)
        shutil.rmtree(self.data_dir / "reach" / db_id, ignore_errors=True)
        return True

    def after_build(self, db_id: str | None, cancelled: bool) -> None:
        """Once a build job ends: a cancelled build's unfinished database is removed, and so is
        any database left interrupted for longer than the retention."""
        if cancelled and db_id is not None:
            row = reach_catalog.database_row(self.store.catalog, db_id)
            if row is not None and row["state"] != "complete":
                with contextlib.suppress(DatabaseBusyError):
                    self.delete_database(db_id)
        self.purge_interrupted()

    def purge_interrupted(self) -> list[str]:
        """Delete the databases whose build was interrupted (a restart, a stopped command) more
        than ``interrupted_retention`` seconds after it began; their ids."""
        from datetime import UTC, datetime

        now = datetime.now(UTC)
        gone = []
        for row in reach_catalog.list_databases(self.data_dir):
            if row["state"] != "interrupted" or not row.get("created"):
                continue
            age = (now - datetime.fromisoformat(row["created"])).total_seconds()
            if age >= self.settings.interrupted_retention:
                with contextlib.suppress(DatabaseBusyError):
                    if self.delete_database(row["id"]):
                        gone.append(row["id"])
        return gone


def planner_child(fd: int) -> None:
    """The planner process (runtime/planner_process.py): a service of its own, without jobs or
    children, whose planning answers the parent's calls on the socket ``fd``."""
    settings = planner_process.child_settings().model_copy(update={"planner_processes": 0})
    service = Service(settings, job_runner=False)
    planner_process.serve(fd, service.planning, service.close)
