"""What the REST service holds for its lifetime: settings, records, planners and jobs.

Planners (robot model, reachability database, collision world, caches) are loaded once per
robot and database and shared by requests; each has a lock, since its caches are not
thread-safe. CPU-heavy work (regions, plans) runs in a thread pool off the event loop; jobs
(database builds, batch planning) run one at a time in a worker thread and report progress in
SQLite, so their state survives a restart (a job cut off by one is marked interrupted).
"""

from __future__ import annotations

import json
import logging
import queue
import shutil
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
import shapely

from pickstop.api import limits as lim
from pickstop.api import planner_process
from pickstop.api.body import type_errors
from pickstop.api.planner_process import PlannerProcess
from pickstop.api.problems import Problem
from pickstop.api.work import Cancelled, Work
from pickstop.errors import InputError, PickStopError, RobotConfigError
from pickstop.regions.planner import RegionPlanner
from pickstop.robot.config import (
    RobotConfig,
    example_robot_data_share,
    parse_config,
    preset_names,
    resolve_robot,
)
from pickstop.robot.model import RobotModel, _mesh_refs, load_robot, resolve_path
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Scene
from pickstop.sequence.plan import StopPlanner, route_points, route_yaws
from pickstop.sequence.plan_model import Plan, PlanOptions
from pickstop.sequence.rules import Rule, RuleName, cut_off, judge
from pickstop.settings import Settings, cache_dir
from pickstop.store import reach_catalog
from pickstop.store.reach_catalog import list_databases, open_database
from pickstop.store.records import ServiceStore

log = logging.getLogger("pickstop.api")


class JobCancelled(Exception):
    pass


class JobDeadline(Exception):
    pass


@dataclass
class _Slot:
    planner: StopPlanner
    lock: threading.Lock = field(default_factory=threading.Lock)


CANCEL_REQUESTED = "cancel requested"

# The default robot's database, loaded by a parent before it forks its API workers: their
# services take it from here, so the arrays are shared copy-on-write, not loaded N times.
_INHERITED: dict[tuple[str, str], Any] = {}


def load_default_database(data_dir: Path) -> None:
    """Load the default robot's database into this process for forked workers to inherit."""
    from pickstop.loader import robot_for

    robot = robot_for(*resolve_robot("tiago"))
    if any(r["robot_hash"] == robot.robot_hash and r["state"] == "complete"
           for r in list_databases(data_dir)):  # fmt: skip
        _INHERITED[(robot.robot_hash, "")] = open_database(data_dir, robot)


class Service:
    def __init__(self, settings: Settings, job_runner: bool = True) -> None:
        """job_runner: this process runs the jobs (one process of a worker pool does)."""
        self.settings = settings
        self.limits = lim.Limits.of(settings)
        self.key_hashes = frozenset(k.strip() for k in settings.api_keys if k.strip())
        self.data_dir = Path(settings.data_dir)
        self.data_dir.mkdir(parents=True, exist_ok=True)
        self.robot_dir = self.data_dir / "robots"
        self.robot_dir.mkdir(exist_ok=True)
        self.store = ServiceStore(self.data_dir)
        self.job_runner = job_runner
        self.interrupted = self.store.interrupt_stale_jobs() if job_runner else 0
        self.pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="pickstop-plan")
        # Plans, previews and regions run in a child process (planner_process.py) unless the
        # settings keep them on this process's threads.
        self.remote = (
            PlannerProcess(settings, f"{__name__}:planner_child")
            if settings.planner_processes > 0
            else None
        )
        self._slots: dict[tuple[str, str], _Slot] = {}
        self._slots_lock = threading.Lock()
        self._jobs: queue.Queue[str | None] = queue.Queue()
        self._cancel: set[str] = set()
        # Per robot config (name, config JSON): drawing assets and check reports, made once.
        self.robot_assets: dict[tuple[str, str], Any] = {}
        self.robot_checks: dict[tuple[str, str], dict[str, Any]] = {}
        self._running: tuple[str, Work] | None = None
        self._running_lock = threading.Lock()
        self._plan_bodies: dict[str, bytes] = {}
        self._job_thread = threading.Thread(
            target=self._job_loop, name="pickstop-jobs", daemon=True
        )
        if job_runner:
            self._job_thread.start()

    def close(self) -> None:
        if self.job_runner:
            self._jobs.put(None)
            self._job_thread.join(timeout=10)
        self.pool.shutdown(wait=False, cancel_futures=True)
        if self.remote is not None:
            self.remote.close()
        for slot in self._slots.values():
            slot.planner.regions.close()

    # -- robots ------------------------------------------------------------------------------
    def allowed_roots(self) -> list[Path]:
        return [self.robot_dir.resolve(), example_robot_data_share().resolve()]

    def robot_config(self, name: str) -> tuple[RobotConfig, Path]:
        """A preset or a registered robot, by name."""
        if name in preset_names():
            return resolve_robot(name)
        row = self.store.robot(name)
        if row is None:
            known = preset_names() + [r["name"] for r in self.store.robots()]
            raise InputError(
                f"unknown robot {name!r}; known: {', '.join(known)}", field="robot.preset"
            )
        config = parse_config(json.loads(row["config"]), f"robot {name}")
        self.confine(config)  # at every open: a file swapped for a symlink since is refused
        return config, self.robot_dir

    def register_robot(self, data: dict[str, Any]) -> RobotModel:
        """Validate a robot config whose files lie in the allowed folders, and keep it."""
        strict = type_errors(RobotConfig, data) if isinstance(data, dict) else []
        if strict:
            raise RobotConfigError("; ".join(f"{f}: {m}" for f, m in strict), field=strict[0][0])
        config = parse_config(data, "robot")
        if config.name in preset_names() or self.store.robot(config.name) is not None:
            raise InputError(f"robot {config.name!r} already exists", field="name")
        self.confine(config)
        robot = load_robot(config, self.robot_dir)
        self.store.add_robot(config.name, config.model_dump(mode="json"))
        return robot

    def confine(self, config: RobotConfig) -> None:
        """Refuse any file of the config (URDF, SRDF, meshes, package dirs) outside the allowed
        folders: relative paths start at the data folder's robots/, package:// resolves only to
        allowed roots. Real paths are compared (symlinks resolved), and a file that is missing
        gets the same answer as one outside, so the answer tells nothing about the server."""
        roots = self.allowed_roots()

        def inside(p: Path) -> bool:
            rp = p.resolve()
            return any(rp.is_relative_to(r) for r in roots)

        def refuse(what: str, ref: str, field: str) -> RobotConfigError:
            return RobotConfigError(
                f"{what} {ref!r} lies outside the allowed folders or is not a file there",
                field=field,
            )

        pkg = []
        for i, d in enumerate(config.package_dirs):
            p = (self.robot_dir / d).resolve()
            if not inside(p):
                raise refuse(f"package_dirs[{i}]", d, f"package_dirs.{i}")
            pkg.append(str(p))
        pkg.append(str(example_robot_data_share()))
        for what, ref in (("urdf", config.urdf), ("srdf", config.srdf)):
            if ref is None:
                continue
            if not ref.startswith("package://") and not inside(self.robot_dir / ref):
                raise refuse(what, ref, what)
            try:
                path = resolve_path(ref, self.robot_dir, pkg, what)
            except RobotConfigError:
                raise refuse(what, ref, what) from None
            if not inside(path):
                raise refuse(what, ref, what)
            if what == "urdf":
                for mesh in _mesh_refs(path, pkg)[1]:
                    if not inside(mesh):
                        raise RobotConfigError(
                            f"mesh {mesh.name!r} of the URDF lies outside the allowed folders",
                            field="urdf",
                        )

    def robots(self) -> list[dict[str, Any]]:
        out = [{"name": n, "kind": "preset"} for n in preset_names()]
        out += [
            {"name": r["name"], "kind": "registered", "created": r["created"]}
            for r in self.store.robots()
        ]
        return out

    # -- scenes and planners -----------------------------------------------------------------
    def parse(self, doc: Any, loc: str = "") -> Scene:
        """A scene from a request, checked in order of cost: the size limits on the raw
        document, the mesh files (only from the data folder's meshes/, their triangles
        counted), the scene model and its geometry, then the robot (a preset or registered).
        ``loc`` prefixes the fields named in errors (``scenes.2.scene.``)."""
        from pickstop.scene.model import SceneError, resolve_mesh_paths

        problems = lim.scene_problems(doc, self.limits, loc)
        if problems:
            raise SceneError(problems)
        # The model's own checks, strict as JSON, before anything walks the document.
        strict = type_errors(Scene, doc, loc) if isinstance(doc, dict) else []
        if strict:
            raise SceneError(strict)
        meshes = self.data_dir / "meshes"
        try:
            resolved = resolve_mesh_paths(doc, meshes, [meshes])
        except SceneError as e:
            raise SceneError([(loc + f, m) for f, m in e.problems]) from None
        triangles = 0
        for where, geom in lim.mesh_geometries(resolved):
            path = geom.get("path")
            if isinstance(path, str) and Path(path).is_file():  # else the model names it
                triangles += lim.mesh_triangles(Path(path))
            if triangles > self.limits.max_mesh_triangles:
                raise SceneError([(f"{loc}{where}.path", f"the scene's meshes hold {triangles} "
                                   f"triangles up to this one, over the limit of "
                                   f"{self.limits.max_mesh_triangles}")])  # fmt: skip
        try:
            scene = parse_scene(resolved, "scene")
        except SceneError as e:
            raise SceneError([(loc + f, m) for f, m in e.problems]) from None
        if scene.robot.config is not None:
            raise SceneError([(f"{loc}robot.config", "file paths are not accepted over the API; "
                               "register the robot (POST /api/v1/robots) and name it in "
                               "robot.preset")])  # fmt: skip
        try:
            self.robot_config(scene.robot.ref)  # an unknown robot is refused now, not later
        except RobotConfigError as e:
            raise SceneError([(f"{loc}robot.preset", e.message)]) from None
        except InputError as e:
            raise SceneError([(f"{loc}{e.field or 'robot.preset'}", e.message)]) from None
        return scene

    def check_options(self, options: PlanOptions, loc: str = "options.") -> None:
        if options.samples > self.limits.max_mc_samples:
            raise InputError(
                f"{loc}samples: {options.samples} Monte Carlo samples per stop exceed the limit "
                f"of {self.limits.max_mc_samples}",
                field=f"{loc}samples",
            )

    def scene_doc(self, scene_id: str | None, doc: Any, loc: str = "") -> tuple[Any, int | None]:
        """The document of a stored scene (and its revision), or the inline ``doc``."""
        if scene_id is None:
            return doc, None
        row = self.store.scene(scene_id)
        if row is None:
            raise InputError(f"scene {scene_id} does not exist", field=f"{loc}scene_id")
        return json.loads(row["doc"]), row["revision"]

    def stored_scene(self, scene_id: str) -> Scene:
        row = self.store.scene(scene_id)
        if row is None:
            raise Problem(404, "Not found", f"no scene {scene_id!r}", field="scene_id")
        return self.parse(json.loads(row["doc"]))

    def prepare(self, item: Any, loc: str = "") -> tuple[Any, int | None, Scene]:
        """A plan request's scene (stored or inline) checked as a synchronous plan checks
        it: (document, revision or None, scene)."""
        doc, revision = self.scene_doc(item.scene_id, item.scene, loc)
        scene = self.parse(doc, f"{loc}scene." if item.scene is not None else loc)
        options = getattr(item, "options", None)
        if options is not None:
            self.check_options(options)
        return doc, revision, scene

    # -- submissions: every check a job would meet, made before it is queued -----------------
    def submit_plan_job(self, body: Any) -> dict[str, Any]:
        self.prepare(body)
        item = {"scene_id": body.scene_id, "scene": body.scene}
        return self.submit("batch", {"scenes": [item], "options": body.options.model_dump(),
                                     "database": body.database})  # fmt: skip

    def precheck(self, doc: Any) -> None:
        """The size limits of a plan or batch request's raw inline scenes, before the request
        model copies and validates them."""
        if not isinstance(doc, dict):
            return
        problems = lim.scene_problems(doc.get("scene"), self.limits, "scene.")
        scenes = doc.get("scenes")
        for i, item in enumerate(scenes if isinstance(scenes, list) else []):
            if isinstance(item, dict):
                problems += lim.scene_problems(item.get("scene"), self.limits, f"scenes.{i}.scene.")
        if problems:
            from pickstop.scene.model import SceneError

            raise SceneError(problems)

    def check_batch_size(self, doc: Any) -> None:
        scenes = doc.get("scenes") if isinstance(doc, dict) else None
        if isinstance(scenes, list) and len(scenes) > self.limits.max_batch:
            raise Problem(413, "Request too large", f"{len(scenes)} scenes exceed the batch "
                          f"limit of {self.limits.max_batch}", kind="too-large",
                          field="scenes")  # fmt: skip

    def submit_batch(self, body: Any) -> dict[str, Any]:
        self.check_options(body.options)
        for i, item in enumerate(body.scenes):  # a bad scene is a 422 now, not a failed job
            self.prepare(item, f"scenes.{i}.")
        return self.submit("batch", body.model_dump())

    def submit_build(self, body: Any) -> dict[str, Any]:
        from pickstop.reach.build import BuildParams

        if body.samples > self.settings.max_samples:
            raise InputError(f"samples {body.samples} exceeds the limit of "
                             f"{self.settings.max_samples}", field="samples")  # fmt: skip
        try:
            self.robot_config(body.robot)  # unknown robot: 422 now, not a failed job later
        except InputError as e:
            raise InputError(e.message, field="robot") from None
        params = body.model_dump()
        BuildParams(**{k: v for k, v in params.items() if k != "robot"}).validate()
        return self.submit("build", params)

    def slot(self, scene: Scene, db_id: str | None = None) -> _Slot:
        from pickstop.loader import robot_for

        config, root = self.robot_config(scene.robot.ref)
        robot = robot_for(config, root)
        key = (robot.robot_hash, db_id or "")
        with self._slots_lock:
            slot = self._slots.get(key)
            if slot is None:
                db = _INHERITED.get(key) or open_database(self.data_dir, robot, db_id)
                rp = RegionPlanner(robot, db, cache_dir=cache_dir(self.data_dir))
                slot = self._slots[key] = _Slot(StopPlanner(rp))
            return slot

    def preload(self) -> None:
        """Load the default robot's planner if it has a database (at start-up); with a
        planner process, start it (it loads the planner itself)."""
        if self.remote is not None:
            self.remote.start()
            return
        try:
            from pickstop.loader import robot_for

            config, root = resolve_robot("tiago")
            robot = robot_for(config, root)
            if any(
                r["robot_hash"] == robot.robot_hash and r["state"] == "complete"
                for r in list_databases(self.data_dir)
            ):
                key = (robot.robot_hash, "")
                db = _INHERITED.get(key) or open_database(self.data_dir, robot)
                rp = RegionPlanner(robot, db, cache_dir=cache_dir(self.data_dir))
                self._slots[key] = _Slot(StopPlanner(rp))
        except PickStopError as e:
            log.warning("default planner not loaded: %s", e.message)

    @property
    def loaded(self) -> list[dict[str, Any]]:
        if self.remote is not None:
            return self.remote.loaded
        return [
            {"robot": s.planner.regions.robot.name, "database": s.planner.regions.db.id}
            for s in self._slots.values()
        ]

    def cached_plan_body(self, plan_id: str) -> bytes | None:
        """A stored plan's body if it is in memory already (no database access)."""
        return self._plan_bodies.get(plan_id)

    def plan_body(self, plan_id: str, with_scene: bool = False) -> bytes | None:
        """A stored plan record as JSON bytes (``with_scene``: plus the exact scene it was
        planned from); plans are immutable, so their bodies are cached."""
        hit = self._plan_bodies.get(plan_id)
        if hit is not None and not with_scene:
            return hit
        row = self.store.plan(plan_id)
        if row is None:
            return None
        body = (
            f'{{"id":"{row["id"]}","scene_id":{json.dumps(row["scene_id"])},'
            f'"scene_revision":{json.dumps(row["scene_revision"])},"created":"{row["created"]}",'
            f'"options":{row["options"]},"plan":{row["doc"]}}}'
        ).encode()
        if len(self._plan_bodies) >= 512:
            with suppress(StopIteration, KeyError, RuntimeError):  # another thread's turn
                self._plan_bodies.pop(next(iter(self._plan_bodies)))
        self._plan_bodies[plan_id] = body
        if with_scene:
            return body[:-1] + b',"scene":' + row["scene_doc"].encode() + b"}"
        return body

    def plan(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        if self.remote is not None:
            return cast(Plan, self.remote.call("plan", scene, options, db_id))
        slot = self.slot(scene, db_id)
        with slot.lock:
            plan = slot.planner.plan(scene, options)
        # Verify the other candidates' centres in the background, one at a time, so the next
        # change of sigma (the 3D planner's slider) finds its stops checked.
        self.pool.submit(self._prefetch, slot, scene)
        return plan

    def preview(self, scene: Scene, options: PlanOptions, db_id: str | None = None) -> Plan:
        """An unverified plan to draw while the layout is edited (``StopPlanner.preview``)."""
        if self.remote is not None:
            return cast(Plan, self.remote.call("preview", scene, options, db_id))
        slot = self.slot(scene, db_id)
        with slot.lock:
            return slot.planner.preview(scene, options)

    def _prefetch(self, slot: _Slot, scene: Scene) -> None:
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
        if self.remote is not None:
            out = self.remote.call("regions", scene, sigma, db_id, rule, target)
            return cast(dict[str, Any], out)
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

    # -- jobs --------------------------------------------------------------------------------
    def submit(self, kind: str, params: dict[str, Any]) -> dict[str, Any]:
        job = self.store.add_job(kind, params)
        self._jobs.put(job["id"])
        return job

    def cancel(self, job_id: str) -> dict[str, Any] | None:
        """Cancel a job: a queued one never starts; a running one is stopped where it is."""
        job = self.store.job(job_id)
        if job is None:
            return None
        if job["state"] == "queued":
            self.store.set_job(job_id, state="cancelled", error="cancelled before it started")
        elif job["state"] == "running":
            self._cancel.add(job_id)
            with self._running_lock:
                here = self._running is not None and self._running[0] == job_id
                if here:
                    self._running[1].stop()  # type: ignore[index]
            if not here:  # another worker process runs it: tell it through the record
                self.store.set_job(job_id, error=CANCEL_REQUESTED)
            for _ in range(100):  # the record says so once the work has unwound
                job = self.store.job(job_id)
                if job is None or job["state"] != "running":
                    break
                threading.Event().wait(0.05)
        return self.store.job(job_id)

    def _job_loop(self) -> None:
        while True:
            try:
                job_id = self._jobs.get(timeout=1.0)
            except queue.Empty:  # jobs other worker processes queued
                job_id = self.store.next_queued_job()
                if job_id is None:
                    continue
            if job_id is None:
                return
            job = self.store.job(job_id)
            if job is None or job["state"] != "queued":
                continue
            self.store.set_job(job_id, state="running")
            work = Work()
            with self._running_lock:
                self._running = (job_id, work)
            timer = threading.Timer(self.settings.job_deadline, work.stop)
            timer.daemon = True
            timer.start()
            finished = threading.Event()
            threading.Thread(target=self._watch, args=(job_id, work, finished), daemon=True,
                             name="pickstop-job-watch").start()  # fmt: skip
            try:
                params = json.loads(job["params"])
                run = self._run_build if job["kind"] == "build" else self._run_batch
                result = work.run(run, job_id, params)
                self.store.set_job(job_id, state="done", progress=1.0, result=result, error=None)
            except (JobCancelled, Cancelled):
                if job_id in self._cancel:
                    self.store.set_job(job_id, state="cancelled", error="cancelled while running")
                else:
                    self.store.set_job(job_id, state="failed", error="the job passed its "
                                       f"deadline of {self.settings.job_deadline:g} s")  # fmt: skip
            except PickStopError as e:
                self.store.set_job(job_id, state="failed", error=e.message)
            except Exception as e:  # a job must never stay 'running'
                log.exception("job %s failed", job_id)
                self.store.set_job(job_id, state="failed", error=f"{type(e).__name__}: {e}")
            finally:
                finished.set()
                timer.cancel()
                with self._running_lock:
                    self._running = None
                self._cancel.discard(job_id)

    def _watch(self, job_id: str, work: Work, finished: threading.Event) -> None:
        """Stop the running job when a cancel reached another worker process."""
        while not finished.wait(0.5):
            row = self.store.job(job_id)
            if row is not None and row["error"] == CANCEL_REQUESTED:
                self._cancel.add(job_id)
                work.stop()
                return

    def _check_cancel(self, job_id: str) -> None:
        if job_id in self._cancel:
            raise JobCancelled(job_id)

    def _run_build(self, job_id: str, params: dict[str, Any]) -> dict[str, Any]:
        from pickstop.reach.build import BuildParams
        from pickstop.store.reach_build import build

        config, root = self.robot_config(params.pop("robot"))
        robot = load_robot(config, root)
        bp = BuildParams(**params)
        bp.validate()
        last = [0.0]

        def progress(done: int, total: int) -> None:
            self._check_cancel(job_id)
            frac = done / total if total else 1.0
            if frac - last[0] >= 0.01 or done == total:
                last[0] = frac
                self.store.set_job(job_id, progress=frac)

        # Two worker processes at lower priority: interactive requests come first.
        row = build(robot, bp, self.data_dir, workers=2, progress=progress, nice=10)
        return {"database": row["id"], "robot": robot.name, "samples": row["samples"]}

    def _run_batch(self, job_id: str, params: dict[str, Any]) -> dict[str, Any]:
        options = PlanOptions(**params.get("options", {}))
        items = params["scenes"]
        results = []
        for k, item in enumerate(items):
            self._check_cancel(job_id)
            scene_id, doc = item.get("scene_id"), item.get("scene")
            revision = None
            try:
                if scene_id is not None:
                    row = self.store.scene(scene_id)
                    if row is None:
                        raise InputError(f"scene {scene_id} does not exist", field="scene_id")
                    doc, revision = json.loads(row["doc"]), row["revision"]
                scene = self.parse(doc)
                plan = self.plan(scene, options, params.get("database"))
                rec = self.store.add_plan(
                    scene_id, revision, doc, options.model_dump(), plan.model_dump(mode="json")
                )
                results.append(
                    {
                        "index": k,
                        "scene_id": scene_id,
                        "plan_id": rec["id"],
                        "stops": plan.totals.stops,
                        "time": plan.totals.time.total,
                    }
                )
            except PickStopError as e:
                results.append({"index": k, "scene_id": scene_id, "error": e.message})
            self.store.set_job(job_id, progress=(k + 1) / len(items))
        return {
            "plans": results,
            "planned": sum("plan_id" in r for r in results),
            "failed": sum("error" in r for r in results),
        }

    def delete_database(self, db_id: str) -> bool:
        cat = self.store.catalog
        if reach_catalog.database_row(cat, db_id) is None:
            return False
        for key, db in list(_INHERITED.items()):
            if db.id == db_id:
                del _INHERITED[key]
        with self._slots_lock:
            for key, slot in list(self._slots.items()):
                if slot.planner.regions.db.id == db_id:
                    slot.planner.regions.close()
                    del self._slots[key]
        reach_catalog.delete_database(cat, db_id)
        shutil.rmtree(self.data_dir / "reach" / db_id, ignore_errors=True)
        return True


def planner_child(fd: int) -> None:
    """The planner process (api/planner_process.py): a service of its own, without jobs or
    children, answering the parent's calls on the socket ``fd``."""
    settings = planner_process.child_settings().model_copy(update={"planner_processes": 0})
    planner_process.serve(fd, Service(settings, job_runner=False))
