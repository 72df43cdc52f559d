"""Several API processes on one listening socket (``pickstop serve --workers N``).

The parent binds the port once (:func:`pickstop.stack.listen`), loads the default robot's
planners (its reachability database among them) into a planner pool and forks N processes that
inherit both; the kernel spreads connections
over them, so a reader is never queued behind another process's plan. Worker 0 alone runs
jobs: it marks jobs a previous run left ``interrupted`` at start and picks up the jobs any
worker queued from SQLite; a cancel that reaches another worker is passed on through the
job's record.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import threading
import time
from pathlib import Path
from typing import Any

from pickstop.settings import Settings

# The event loop and HTTP parser the API is served with: uvloop and httptools (both C) answer
# a stored plan in about a third of the CPU time of asyncio's loop and the pure-Python h11.
SERVER_OPTIONS: dict[str, Any] = {"loop": "uvloop", "http": "httptools"}


def settings_env(settings: Settings) -> dict[str, str]:
    """``settings`` as the ``PICKSTOP_*`` variables a worker process reads them from."""
    env = {}
    for name, value in settings.model_dump(mode="json").items():
        if value is None:
            continue
        text = value if isinstance(value, str) else json.dumps(value)
        env[f"PICKSTOP_{name.upper()}"] = text
    return env


class WorkerPool:
    """The worker processes of one socket, forked once the default robot's planners (its
    reachability database among them) are loaded into a pool, so that the workers share its
    arrays (copy-on-write: nothing writes them) instead of loading one copy each; each worker's
    service takes that pool as its own. ``should_exit = True`` stops them."""

    def __init__(self, sock: socket.socket, settings: Settings, log_level: str) -> None:
        from contextlib import suppress

        from pickstop.errors import PickStopError
        from pickstop.pool import PlannerPool

        # With planner processes, each worker's child loads its own planners (the database is
        # memory-mapped, so shared all the same); without, the workers inherit the parent's.
        planners = PlannerPool(
            Path(settings.data_dir), settings.region_processes, settings.default_databases
        )
        if settings.planner_processes == 0:
            with suppress(PickStopError):  # each worker's start-up says why (serving without)
                planners.preload()
        self.pids: list[int] = []
        for i in range(settings.workers):
            pid = os.fork()
            if pid == 0:  # the worker: serve until told to stop, never return into the parent
                code = 1
                try:
                    die_with_parent()
                    code = serve(sock, settings, i, log_level, planners)
                finally:
                    os._exit(code)
            self.pids.append(pid)
        self._stopped = False
        self._exited: set[int] = set()
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, self._terminated)

    def _terminated(self, signum: int, frame: Any) -> None:
        """SIGTERM to the parent stops the workers first."""
        self.should_exit = True
        raise SystemExit(0)

    @property
    def started(self) -> bool:
        return True

    def _reap(self) -> None:
        for pid in self.pids:
            if pid not in self._exited and os.waitpid(pid, os.WNOHANG)[0] == pid:
                self._exited.add(pid)

    @property
    def should_exit(self) -> bool:
        self._reap()
        return self._stopped or len(self._exited) == len(self.pids)

    @should_exit.setter
    def should_exit(self, value: bool) -> None:
        if not value or self._stopped:
            return
        self._stopped = True
        self._reap()
        for pid in self.pids:
            if pid not in self._exited:
                os.kill(pid, signal.SIGTERM)
        t0 = time.time()
        while len(self._exited) < len(self.pids) and time.time() - t0 < 20:
            time.sleep(0.1)
            self._reap()
        for pid in set(self.pids) - self._exited:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)

    def alive(self) -> bool:
        self._reap()
        return not self._exited


def wait_healthy(url: str, pool: WorkerPool, timeout: float = 300.0) -> None:
    import httpx

    from pickstop.errors import PickStopError

    t0 = time.time()
    while time.time() - t0 < timeout:
        if not pool.alive():
            pool.should_exit = True
            raise PickStopError("an API worker process exited while starting")
        try:
            if httpx.get(f"{url}/api/v1/health", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.3)
    pool.should_exit = True
    raise PickStopError(f"the API workers did not answer at {url} within {timeout:g} s")


def die_with_parent() -> None:
    """Linux: the kernel sends this process SIGTERM if the parent dies (even by kill -9)."""
    import ctypes
    from contextlib import suppress

    with suppress(OSError):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


def serve(
    sock: socket.socket, settings: Settings, index: int, log_level: str, planners: Any = None
) -> int:
    """One worker: the app on the inherited socket, its planners from ``planners`` (the
    parent's pool, inherited); worker 0 runs the jobs."""
    import uvicorn

    from pickstop.api.app import create_app

    app: Any = create_app(settings, job_runner=index == 0, planners=planners)
    uvicorn.Server(uvicorn.Config(app, log_level=log_level, **SERVER_OPTIONS)).run(sockets=[sock])
    return 0
