"""Several API processes on one listening socket (``pickstop serve --workers N``).

The parent binds the port once (:func:`pickstop.stack.listen`) and starts N processes that
inherit the socket; the kernel spreads connections over them, so a reader is never queued
behind another process's plan. Worker 0 alone runs jobs: it marks jobs a previous run left
``interrupted`` at start and picks up the jobs any worker queued from SQLite; a cancel that
reaches another worker is passed on through the job's record.

    python -m pickstop.api.workers FD INDEX LOG_LEVEL     (started by the parent, not by hand)
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from typing import Any

from pickstop.settings import Settings


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
    """The worker processes of one socket; ``should_exit = True`` stops them."""

    def __init__(self, sock: socket.socket, settings: Settings, log_level: str) -> None:
        env = {**os.environ, **settings_env(settings)}
        self.procs = [
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "pickstop.api.workers",
                    str(sock.fileno()),
                    str(i),
                    log_level,
                ],
                env=env,
                pass_fds=(sock.fileno(),),
            )
            for i in range(settings.workers)
        ]
        self._stopped = False

    @property
    def started(self) -> bool:
        return True

    @property
    def should_exit(self) -> bool:
        return self._stopped or all(p.poll() is not None for p in self.procs)

    @should_exit.setter
    def should_exit(self, value: bool) -> None:
        if value and not self._stopped:
            self._stopped = True
            for p in self.procs:
                p.terminate()
            for p in self.procs:
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()

    def alive(self) -> bool:
        return all(p.poll() is None for p in self.procs)


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


def main(argv: list[str]) -> int:
    import uvicorn

    from pickstop.api.app import create_app

    fd, index, log_level = int(argv[0]), int(argv[1]), argv[2]
    sock = socket.socket(fileno=fd)
    app: Any = create_app(Settings(), job_runner=index == 0)
    server = uvicorn.Server(uvicorn.Config(app, log_level=log_level))
    server.run(sockets=[sock])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
