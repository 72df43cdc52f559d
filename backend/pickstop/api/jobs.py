"""The job runner: database builds and batch plans, one at a time, off the request path.

Jobs are records in SQLite (queued, running, done, failed, cancelled, interrupted), so their
state survives a restart: a job cut off by one is marked interrupted when the next runner
starts. One process of a worker pool runs the jobs; it takes those other processes queued from
the records, and a cancel that reaches another process is passed on through the job's record.
Every job has a deadline (``job_deadline``); a job runs as the computation of a
:class:`~pickstop.runtime.cancel.Work`, whose token (:mod:`pickstop.runtime.cancel`) a cancel,
the deadline or the runner's close cancels, with that reason: the job stops at its next
checkpoint, or where it is. A build runs in a process group of its own
(:mod:`pickstop.runtime.build_process`), ended with the job and with the runner; a cancelled
build leaves no database behind.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pickstop.api.registry import RobotRegistry
from pickstop.errors import InputError, PickStopError
from pickstop.runtime.build_process import BuildProcess, error_of
from pickstop.runtime.cancel import Cancelled, Token, Work, checkpoint
from pickstop.settings import Settings
from pickstop.store.records import ServiceStore

log = logging.getLogger("pickstop.api")

CANCEL_REQUESTED = "cancel requested"

#: A kind of job: ``(runner, job id, params) -> result``.
JobKind = Callable[["JobRunner", str, dict[str, Any]], dict[str, Any]]


class JobRunner:
    """Runs queued jobs in a thread of its own, one at a time (``start``: this process runs
    the jobs; others only queue and cancel them)."""

    def __init__(
        self, store: ServiceStore, settings: Settings, kinds: dict[str, JobKind], start: bool
    ) -> None:
        self.store = store
        self.settings = settings
        self.kinds = kinds
        self.runs_jobs = start
        self.interrupted = store.interrupt_stale_jobs() if start else 0
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._tokens: dict[str, Token] = {}  # the jobs running in this process
        self._running: tuple[str, Work] | None = None
        self._running_lock = threading.Lock()
        self._children: dict[str, BuildProcess] = {}  # job id -> its build's process group
        self._closing = False
        self._thread = threading.Thread(target=self._loop, name="pickstop-jobs", daemon=True)
        if start:
            self._thread.start()

    def close(self) -> None:
        """Stop the running job (it is recorded interrupted) and every process it started,
        then the runner."""
        if not self.runs_jobs:
            return
        self._closing = True
        self._queue.put(None)
        with self._running_lock:
            if self._running is not None:
                self._running[1].stop("closing")
            children = list(self._children.values())
        for child in children:
            child.stop()
        self._thread.join(timeout=10)

    def adopt(self, job_id: str, child: BuildProcess) -> None:
        """``child`` runs the job ``job_id``: :meth:`close` ends it if the job has not."""
        with self._running_lock:
            self._children[job_id] = child

    def disown(self, job_id: str) -> None:
        with self._running_lock:
            self._children.pop(job_id, None)

    def submit(self, kind: str, params: dict[str, Any]) -> dict[str, Any]:
        job = self.store.add_job(kind, params)
        self._queue.put(job["id"])
        return job

    def token(self, job_id: str) -> Token:
        """The token of a job running in this process outside the runner (a dispatch): a
        cancel of the job cancels it."""
        with self._running_lock:
            if len(self._tokens) > 1024:  # long finished ones (a dispatch runs for minutes)
                for k in [k for k, t in self._tokens.items() if t.cancelled][:512]:
                    del self._tokens[k]
            return self._tokens.setdefault(job_id, Token())

    def cancelled(self, job_id: str) -> bool:
        """Whether a cancel of the job reached this process."""
        token = self._tokens.get(job_id)
        return token is not None and token.reason == "cancelled"

    def cancel(self, job_id: str) -> dict[str, Any] | None:
        """Cancel a job: a queued one never starts; a running one is stopped where it is."""
        job = self.store.job(job_id)
        if job is None:
            return None
        if job["state"] == "queued":
            self.store.set_job(job_id, state="cancelled", error="cancelled before it started")
        elif job["state"] == "running":
            with self._running_lock:
                token = self._tokens.get(job_id)
            if token is not None:
                token.cancel("cancelled")
            else:  # another worker process runs it: tell it through the record
                self.store.set_job(job_id, error=CANCEL_REQUESTED)
            for _ in range(100):  # the record says so once the work has unwound
                job = self.store.job(job_id)
                if job is None or job["state"] != "running":
                    break
                threading.Event().wait(0.05)
        return self.store.job(job_id)

    def _loop(self) -> None:
        while True:
            try:
                job_id = self._queue.get(timeout=1.0)
            except queue.Empty:  # jobs other worker processes queued
                job_id = self.store.next_queued_job()
                if job_id is None:
                    continue
            if job_id is None:
                return
            job = self.store.job(job_id)
            if job is None or job["state"] != "queued":
                continue
            self._run(job_id, job)

    def _run(self, job_id: str, job: dict[str, Any]) -> None:
        self.store.set_job(job_id, state="running")
        work = Work()
        with self._running_lock:
            self._running = (job_id, work)
            self._tokens[job_id] = work.token
        timer = threading.Timer(self.settings.job_deadline, work.stop, args=("deadline",))
        timer.daemon = True
        timer.start()
        finished = threading.Event()
        threading.Thread(target=self._watch, args=(job_id, work, finished), daemon=True,
                         name="pickstop-job-watch").start()  # fmt: skip
        try:
            params = json.loads(job["params"])
            kind = self.kinds.get(job["kind"])
            if kind is None:
                raise PickStopError(f"this service runs no {job['kind']!r} jobs")
            result = work.run(kind, self, job_id, params)
            self.store.set_job(job_id, state="done", progress=1.0, result=result, error=None)
        except Cancelled:
            if work.token.reason == "cancelled":
                self.store.set_job(job_id, state="cancelled", error="cancelled while running")
            elif work.token.reason == "closing" or self._closing:
                self.store.set_job(job_id, state="interrupted", error="the service stopped "
                                   "while it ran; submit it again to resume it")  # fmt: skip
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
                self._tokens.pop(job_id, None)

    def _watch(self, job_id: str, work: Work, finished: threading.Event) -> None:
        """Stop the running job when a cancel reached another worker process."""
        while not finished.wait(0.5):
            row = self.store.job(job_id)
            if row is not None and row["error"] == CANCEL_REQUESTED:
                work.stop("cancelled")
                return


# -- the kinds of job ----------------------------------------------------------------------
def build_job(
    robots: RobotRegistry, data_dir: Path, after: Callable[[str | None, bool], object]
) -> JobKind:
    """A database build: ``{"robot", **BuildParams}`` -> the new database's id and size,
    built in a process group of its own; ``after(db_id, cancelled)`` tidies up once it ends
    (a cancelled build's database is removed)."""

    def run(runner: JobRunner, job_id: str, params: dict[str, Any]) -> dict[str, Any]:
        from pickstop.reach.build import BuildParams

        config, root = robots.config(params.pop("robot"))
        bp = BuildParams(**params)
        bp.validate()
        child = BuildProcess(config, root, bp, data_dir)
        runner.adopt(job_id, child)
        db_id, last = None, 0.0
        try:
            for msg in child.messages():
                if "database" in msg:
                    db_id = msg["database"]
                elif "progress" in msg:
                    checkpoint()
                    done, total = msg["progress"]
                    frac = done / total if total else 1.0
                    if frac - last >= 0.01 or done == total:
                        last = frac
                        runner.store.set_job(job_id, progress=frac)
                elif "result" in msg:
                    result: dict[str, Any] = msg["result"]
                    return result
                elif "error" in msg:
                    raise error_of(msg)
            raise PickStopError(f"the build stopped (exit code {child.proc.poll()})")
        finally:
            _cleanup(lambda: (child.stop(), runner.disown(job_id),
                              after(db_id, runner.cancelled(job_id))))  # fmt: skip

    return run


def _cleanup(fn: Callable[[], object]) -> None:
    """Run ``fn`` (idempotent cleanup) to its end: a job's cancellation that lands inside it
    (it is raised in the job's thread once, at any bytecode) runs it again, whole, and is
    raised after."""
    try:
        fn()
    except Cancelled:
        fn()
        raise


def batch_job(parse: Callable[[Any], Any], plan: Callable[[Any, Any, str | None], Any]) -> JobKind:
    """Plans of several scenes: ``{"scenes": [{"scene_id" | "scene"}], "options",
    "database"}`` -> per scene its stored plan's id (or why it failed), and the counts."""

    def run(runner: JobRunner, job_id: str, params: dict[str, Any]) -> dict[str, Any]:
        from pickstop.sequence.plan_model import PlanOptions

        store = runner.store
        options = PlanOptions(**params.get("options", {}))
        items = params["scenes"]
        results = []
        for k, item in enumerate(items):
            checkpoint()
            scene_id, doc = item.get("scene_id"), item.get("scene")
            revision = None
            try:
                if scene_id is not None:
                    row = store.scene(scene_id)
                    if row is None:
                        raise InputError(f"scene {scene_id} does not exist", field="scene_id")
                    doc, revision = json.loads(row["doc"]), row["revision"]
                scene = parse(doc)
                result = plan(scene, options, params.get("database"))
                rec = store.add_plan(
                    scene_id, revision, doc, options.model_dump(), result.model_dump(mode="json")
                )
                results.append(
                    {
                        "index": k,
                        "scene_id": scene_id,
                        "plan_id": rec["id"],
                        "stops": result.totals.stops,
                        "time": result.totals.time.total,
                    }
                )
            except PickStopError as e:
                results.append({"index": k, "scene_id": scene_id, "error": e.message})
            store.set_job(job_id, progress=(k + 1) / len(items))
        return {
            "plans": results,
            "planned": sum("plan_id" in r for r in results),
            "failed": sum("error" in r for r in results),
        }

    return run
