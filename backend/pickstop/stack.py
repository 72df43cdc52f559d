"""The API (uvicorn) and the 3D planner (viser) together in one process.

The planner talks to the API over HTTP like any other client. It gets a key made for this run
(its hash is added to the accepted keys in memory, the key itself is never stored or printed),
so an engineer in the browser can save scenes; both listen on 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import json
import secrets
import socket
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pickstop.errors import PickStopError
from pickstop.settings import Settings, hash_key

EXAMPLE_SCENE = (
    Path(__file__).resolve().parents[2] / "examples" / "scenes" / "paper_experiment.json"
)


class PortInUse(PickStopError):
    """The configured port is taken by another program; the service does not move."""


def listen(host: str, port: int) -> socket.socket:
    """A listening socket on ``host:port`` with SO_REUSEADDR, as uvicorn binds: a socket left
    in TIME_WAIT by a crashed run does not count as busy, one that really listens does."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    # proto given: asyncio sets TCP_NODELAY only on IPPROTO_TCP sockets (else Nagle and
    # delayed ACKs add 40 ms to every small answer).
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(2048)
    except OSError as e:
        sock.close()
        raise PortInUse(
            f"port {port} on {host} is not available ({e.strerror}); stop the program using "
            f"it, or choose another with --port or PICKSTOP_PORT"
        ) from None
    sock.set_inheritable(True)
    return sock


def port_free(host: str, port: int) -> bool:
    try:
        listen(host, port).close()
    except PortInUse:
        return False
    return True


def free_port(host: str) -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def spawn_api(port: int, env: dict[str, str], log: Any, timeout: float = 180.0) -> Any:
    """``pickstop serve --no-ui`` as a subprocess on 127.0.0.1:``port``, returned once its
    health check answers (its output goes to the file ``log``). Tests and benchmarks use it."""
    import subprocess

    import httpx

    proc = subprocess.Popen(
        [sys.executable, "-m", "pickstop.cli", "serve", "--host", "127.0.0.1", "--port",
         str(port), "--log-level", "warning", "--no-ui"],
        env=env, stdout=log, stderr=subprocess.STDOUT,
    )  # fmt: skip
    url = f"http://127.0.0.1:{port}/api/v1/health"
    t0 = time.time()
    while True:
        try:
            if httpx.get(url, timeout=2).status_code == 200:
                return proc
        except httpx.HTTPError:
            pass
        if proc.poll() is not None or time.time() - t0 > timeout:
            proc.kill()
            raise PickStopError(f"the API did not start on port {port}; see {log.name}")
        time.sleep(0.3)


@dataclass
class Stack:
    api_url: str
    ui_url: str | None
    scene_id: str | None
    server: Any
    ui: Any

    def wait(self) -> None:
        """Block until interrupted (Ctrl-C) or the API stops."""
        try:
            while not self.server.should_exit:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self) -> None:
        if self.ui is not None:
            self.ui.close()
        self.server.should_exit = True


def start(
    settings: Settings,
    *,
    ui: bool = True,
    scene_id: str | None = None,
    scene_file: Path | None = None,
    log_level: str = "warning",
    move_if_busy: bool = False,
) -> Stack:
    """Start the API in a thread, then (``ui``) the planner on a stored or example scene.

    The API listens on the configured port or not at all (:class:`PortInUse`): an MES
    configured for it must find it there. ``move_if_busy`` (the demo): take a free port and
    say so."""
    import uvicorn

    from pickstop.api.app import create_app

    host = settings.host
    port, sock = _bind_api(settings, move_if_busy)
    if ui and not move_if_busy and not port_free(host, settings.ui_port):
        sock.close()
        raise PortInUse(f"port {settings.ui_port} on {host} (the 3D planner's) is not "
                        "available; choose another with --ui-port or PICKSTOP_UI_PORT")  # fmt: skip
    ui_key = secrets.token_urlsafe(24) if ui else None
    keys = list(settings.api_keys) + ([hash_key(ui_key)] if ui_key else [])
    settings = settings.model_copy(update={"port": port, "api_keys": keys})
    api_url = f"http://{host}:{port}"
    server: Any
    if settings.workers > 1:
        server = _worker_pool(settings, sock, api_url, log_level)
    else:
        from pickstop.runtime.servers import SERVER_OPTIONS

        config = uvicorn.Config(
            create_app(settings), host=host, port=port, log_level=log_level, **SERVER_OPTIONS
        )
        server = uvicorn.Server(config)
        _run_in_thread(server, sock, host, port)
    if not ui:
        return Stack(api_url, None, None, server, None)

    from pickstop_ui.app import PlannerApp
    from pickstop_ui.client import PickStopClient

    client = PickStopClient(api_url, ui_key)
    if scene_id is None:
        scene_id = _planner_scene(client, scene_file)
    app = PlannerApp(client, scene_id, host=host, port=settings.ui_port)
    return Stack(api_url, f"http://{host}:{app.port}/", scene_id, server, app)


def _bind_api(settings: Settings, move_if_busy: bool) -> tuple[int, socket.socket]:
    """The API's port and its listening socket: the configured port, or (``move_if_busy``)
    a free one, said on stderr."""
    host, port = settings.host, settings.port
    try:
        sock = listen(host, port)
    except PortInUse:
        if not move_if_busy:
            raise
        new = free_port(host)
        print(f"pickstop: port {port} is busy; the demo's API takes {new}", file=sys.stderr)
        port, sock = new, listen(host, new)
    return port, sock


def _worker_pool(settings: Settings, sock: socket.socket, api_url: str, log_level: str) -> Any:
    """``settings.workers`` API processes sharing ``sock``, returned once ``api_url`` answers."""
    from pickstop.runtime.servers import WorkerPool, wait_healthy

    server = WorkerPool(sock, settings, log_level)
    sock.close()  # the workers hold it
    wait_healthy(api_url, server)
    return server


def _run_in_thread(server: Any, sock: socket.socket, host: str, port: int) -> None:
    """Run the uvicorn ``server`` on ``sock`` in a daemon thread; return once it has started
    (:class:`PickStopError` if its thread dies or it takes over 300 s)."""
    thread = threading.Thread(
        target=server.run, kwargs={"sockets": [sock]}, name="pickstop-api", daemon=True
    )
    thread.start()
    t0 = time.time()
    while not server.started:
        if not thread.is_alive() or time.time() - t0 > 300:
            raise PickStopError(f"the API did not start on {host}:{port}")
        time.sleep(0.1)


def _planner_scene(client: Any, scene_file: Path | None) -> str:
    """The id of the scene the planner opens: ``scene_file`` stored anew, else the newest
    stored scene, else the example scene stored anew."""
    if scene_file is not None:
        doc = json.loads(Path(scene_file).read_text(encoding="utf-8"))
        return client.create_scene(doc).id
    stored = client.http.get("/api/v1/scenes", params={"limit": 1}).json()
    if stored:
        return stored[0]["id"]
    doc = json.loads(EXAMPLE_SCENE.read_text(encoding="utf-8"))
    return client.create_scene(doc).id
