"""Plans, previews and regions computed in a child process, so the API's event loop never
shares an interpreter lock with a planner.

A plan is mostly Python and numpy holding the GIL: computed on a thread of the API process,
it takes turns with the event loop every switch interval, and under load a reader waits for
the planner and the planner for the readers. The service therefore hands each computation to
:class:`PlannerProcess`: one child process (a fresh interpreter, never a fork of a threaded
server) that runs its own :class:`~pickstop.api.service.Service` without a job runner or
children of its own, and so the same robot registry, confinement, planners, caches and
background centre checks. The reachability database is memory-mapped, so the child and the
API share its pages instead of holding two copies.

Calls block the calling thread (one of the service's planner threads) and wait in short
polls, checking the thread's token (:mod:`pickstop.runtime.cancel`), so a deadline or a
disconnect reaches it within a poll; the call then tells the child, which stops the
computation the same way (:class:`~pickstop.runtime.cancel.Work`), and waits for its word before
returning, so the next request is served at once. The child computes one request at a time,
in order of arrival, as one planner lock did before. If the child dies, the calls waiting on
it fail with a clear error and the next call starts a new child.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import queue
import socket
import subprocess
import sys
import threading
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from multiprocessing.connection import Connection
from typing import Any

from pickstop.errors import UnavailableError, dump_error, load_error
from pickstop.runtime.cancel import Cancelled, Work, checkpoint
from pickstop.settings import Settings

log = logging.getLogger("pickstop.api")

POLL = 0.05  # seconds between checks for a Cancelled while waiting on the child
ACK_WAIT = 30.0  # seconds a stopped computation may take to unwind before the child restarts
KINDS = ("plan", "preview", "plan_json", "preview_json", "regions", "plan_mix", "guidance",
         "layout", "prove")  # fmt: skip
#: Calls that report progress: the child passes them a ``progress(fraction, message)`` that
#: sends it to the parent, where the caller's own ``progress`` gets it.
PROGRESS = ("layout",)
SETTINGS_ENV = "PICKSTOP_CHILD_SETTINGS"
#: The child's lower priority: when the API process needs a core to answer a read, the
#: planner yields it (a nice-3 process weighs half of a nice-0 one); alone, it plans at
#: full speed.
NICE = 3


class PlannerProcessError(UnavailableError):
    """The planner process stopped or could not be started."""


class PlannerProcess:
    """The child that computes for one service (see the module docstring)."""

    def __init__(self, settings: Settings, entry: str) -> None:
        """entry: ``module:function`` the child runs with the socket's descriptor; it builds
        the service that answers and hands it to :func:`serve`."""
        self.settings = settings
        self.entry = entry
        self._lock = threading.Lock()  # guards the child handle, the pending calls and sends
        self._ids = itertools.count(1)
        # each waiting call's future, with the connection of the child computing it
        self._pending: dict[int, tuple[Connection, Future[Any]]] = {}
        self._progress: dict[int, Callable[[float, str], None]] = {}  # by call, if it reports
        self._proc: Any = None
        self._conn: Connection | None = None
        self._closed = False
        #: what the child has loaded (``Service.loaded``), as it last said
        self.loaded: list[dict[str, Any]] = []

    # -- the parent side ----------------------------------------------------------------------
    def start(self) -> None:
        """Start the child now (it loads the default planner), instead of at the first call."""
        with self._lock:
            self._ensure()

    def _ensure(self) -> Connection:
        if self._closed:
            raise PlannerProcessError("the service is shutting down")
        if self._proc is not None and self._proc.poll() is None and self._conn is not None:
            return self._conn
        # A fresh interpreter (never a fork of a threaded server), given one end of a socket
        # pair; it does not import the parent's main module, whatever started the service.
        module, fn = self.entry.split(":")
        ours, theirs = socket.socketpair()
        env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
        proc = subprocess.Popen(
            [sys.executable, "-c", f"from {module} import {fn}; {fn}({theirs.fileno()})"],
            pass_fds=[theirs.fileno()],
            env={**env, SETTINGS_ENV: self.settings.model_dump_json()},
        )  # fmt: skip
        theirs.close()
        parent = Connection(ours.detach())
        self._proc, self._conn = proc, parent
        threading.Thread(target=self._read, args=(parent, proc), name="pickstop-planner-reader",
                         daemon=True).start()  # fmt: skip
        log.info("planner process %d started", proc.pid)
        return parent

    def _read(self, conn: Connection, proc: Any) -> None:
        """Hand each answer of the child to the call waiting for it; fail them all if it dies."""
        while True:
            try:
                rid, status, payload = conn.recv()
            except (EOFError, OSError):
                break
            if status == "loaded":
                self.loaded = payload
                continue
            if status == "progress":
                report = self._progress.get(rid)
                if report is not None:
                    with contextlib.suppress(Exception):  # a report never stops the work
                        report(*payload)
                continue
            with self._lock:
                entry = self._pending.pop(rid, None)
            if entry is None:
                continue
            fut = entry[1]
            if status == "ok":
                fut.set_result(payload)
            elif status == "cancelled":
                fut.set_exception(Cancelled())
            else:
                fut.set_exception(
                    load_error(
                        payload,
                        PlannerProcessError,
                        "the planner failed with an error that could not be passed on",
                    )
                )
        with self._lock:  # this child's calls fail; a newer child's are its own
            if self._conn is conn:
                self._proc, self._conn = None, None
            orphans = [rid for rid, (c, _) in self._pending.items() if c is conn]
            futures = [self._pending.pop(rid)[1] for rid in orphans]
        code = proc.poll()
        for fut in futures:
            if not fut.done():
                fut.set_exception(PlannerProcessError(
                    f"the planner process stopped (exit code {code}) during the computation; "
                    "it is restarted for the next request"))  # fmt: skip
        if not self._closed:
            log.warning("planner process %s stopped (exit code %s)", proc.pid, code)

    def call(
        self, kind: str, *args: Any, progress: Callable[[float, str], None] | None = None
    ) -> Any:
        """``Planning.<kind>(*args)`` computed in the child; blocks this thread until done.
        progress: gets what a call of :data:`PROGRESS` reports, as it comes."""
        if kind not in KINDS:
            raise ValueError(f"unknown planner call {kind!r}")
        fut: Future[Any] = Future()
        with self._lock:
            conn = self._ensure()
            rid = next(self._ids)
            self._pending[rid] = (conn, fut)
            if progress is not None:
                self._progress[rid] = progress
            conn.send(("run", rid, kind, args))
        try:
            while True:
                try:
                    return fut.result(timeout=POLL)
                except FutureTimeout:
                    checkpoint()  # this thread's token: the request's deadline or client
        except Cancelled:
            self._stop(rid, fut)
            raise
        finally:
            self._progress.pop(rid, None)

    def _stop(self, rid: int, fut: Future[Any]) -> None:
        """Stop request ``rid`` in the child and wait until it has let go of its planner."""
        with self._lock:
            conn = self._conn
            if conn is not None and not fut.done():
                with contextlib.suppress(OSError, ValueError):
                    conn.send(("cancel", rid, None, None))
        try:
            fut.exception(timeout=ACK_WAIT)
        except FutureTimeout:  # stuck in one native call: start afresh rather than queue behind
            log.warning("planner process did not stop request %d in %g s; restarting it", rid,
                        ACK_WAIT)  # fmt: skip
            self._restart()

    def _restart(self) -> None:
        with self._lock:
            proc = self._proc
        if proc is not None:
            proc.kill()
            proc.wait(timeout=10)

    def close(self) -> None:
        with self._lock:
            self._closed = True
            conn, proc = self._conn, self._proc
            self._conn = self._proc = None
        if conn is not None:
            with contextlib.suppress(OSError, ValueError):
                conn.send(("stop", 0, None, None))
        if proc is not None:
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=5)

    # -- the planning interface (as :class:`pickstop.api.planning.Planning`) -----------------
    def plan(self, scene: Any, options: Any, db_id: str | None = None) -> Any:
        return self.call("plan", scene, options, db_id)

    def preview(self, scene: Any, options: Any, db_id: str | None = None) -> Any:
        return self.call("preview", scene, options, db_id)

    def plan_json(self, scene: Any, options: Any, db_id: str | None = None) -> bytes:
        return self.call("plan_json", scene, options, db_id)

    def preview_json(self, scene: Any, options: Any, db_id: str | None = None) -> bytes:
        return self.call("preview_json", scene, options, db_id)

    def plan_mix(
        self, scene: Any, orders: Any, options: Any, db_id: str | None = None, prepare: Any = None
    ) -> Any:
        return self.call("plan_mix", scene, orders, options, db_id, prepare)

    def guidance(
        self, scene: Any, tray: str, order: str | None = None, mix: bool = False,
        sigma: float | None = None, db_id: str | None = None,
    ) -> Any:  # fmt: skip
        return self.call("guidance", scene, tray, order, mix, sigma, db_id)

    def layout(
        self, scene: Any, orders: Any, movable: Any, options: Any, settings: Any,
        db_id: str | None = None, progress: Callable[[float, str], None] | None = None,
    ) -> Any:  # fmt: skip
        return self.call("layout", scene, orders, movable, options, settings, db_id,
                         progress=progress)  # fmt: skip

    def regions(
        self, scene: Any, sigma: float | None, db_id: str | None, rule: str = "sigma",
        target: float = 0.95,
    ) -> Any:  # fmt: skip
        return self.call("regions", scene, sigma, db_id, rule, target)

    def prove(self, scene: Any, plan: Any) -> Any:
        return self.call("prove", scene, plan)

    def preload(self) -> None:
        """Start the child (it loads the default planners) now rather than at the first call."""
        self.start()

    @property
    def pid(self) -> int | None:
        proc = self._proc
        return proc.pid if proc is not None else None


# -- the child side --------------------------------------------------------------------------
def child_settings() -> Settings:
    """In the child: the parent's settings, as it passed them."""
    return Settings.model_validate_json(os.environ.pop(SETTINGS_ENV))


def serve(fd: int, planning: Any, close: Any) -> None:
    """In the child: answer the parent's calls on the socket ``fd`` with ``planning`` (a
    :class:`~pickstop.api.planning.Planning`: its ``plan``, ``preview``, their ``_json``
    forms, ``regions``,
    ``preload`` and ``loaded``) until the parent says stop or goes away; then ``close()``."""
    # No parent-death signal: Linux sends it when the thread that started the child ends, not
    # the process. The child ends with the parent all the same: its socket's end reads EOF.
    os.nice(NICE)
    conn = Connection(fd)
    code = 1
    try:
        planning.preload()
        _serve(conn, planning)
        code = 0
    finally:
        close()
        os._exit(code)  # without waiting for a background centre check to finish


def _serve(conn: Connection, service: Any) -> None:
    todo: queue.Queue[tuple[int, str, tuple[Any, ...]] | None] = queue.Queue()
    dropped: set[int] = set()
    current: list[Any] = [None, None]  # [request id, Work] being computed
    state = threading.Lock()
    send_lock = threading.Lock()

    def send(msg: tuple[Any, ...]) -> None:
        with send_lock, contextlib.suppress(OSError, ValueError):
            conn.send(msg)

    def compute() -> None:
        while (item := todo.get()) is not None:
            rid, kind, args = item
            work = Work()
            with state:
                if rid in dropped:
                    dropped.discard(rid)
                    send((rid, "cancelled", None))
                    continue
                current[:] = [rid, work]
            if kind in PROGRESS:  # the call's reports go to the parent as they come
                args = (*args, lambda f, msg, rid=rid: send((rid, "progress", (f, msg))))
            try:
                out = work.run(getattr(service, kind), *args)
                send((rid, "ok", out))
            except Cancelled:
                send((rid, "cancelled", None))
            except BaseException as e:
                send((rid, "error", dump_error(e)))
            finally:
                with state:
                    current[:] = [None, None]
                send((0, "loaded", service.loaded))

    send((0, "loaded", service.loaded))
    worker = threading.Thread(target=compute, name="pickstop-planner-compute", daemon=True)
    worker.start()
    while True:
        try:
            op, rid, kind, args = conn.recv()
        except (EOFError, OSError):
            break
        if op == "run":
            todo.put((rid, kind, args))
        elif op == "cancel":
            with state:
                if current[0] == rid:
                    current[1].stop()
                else:  # not started yet (or already answered: then the id is never seen)
                    if len(dropped) > 1024:
                        dropped.clear()
                    dropped.add(rid)
        elif op == "stop":
            break
    with state:
        if current[1] is not None:
            current[1].stop("closing")
    todo.put(None)
    worker.join(timeout=5)
