"""What every request meets before routing: HEAD as GET, an unexpected error answered without
dropping the connection, a body over the limit answered with ``Connection: close``."""

from __future__ import annotations

import socket
import threading
import time

import pytest
import uvicorn
from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.settings import Settings, hash_key

from .conftest import AUTH, KEY


@pytest.fixture(scope="module")
def bare_settings(tmp_path_factory):
    """A service without a database or planner process: only HTTP matters here."""
    folder = tmp_path_factory.mktemp("http")
    return Settings(data_dir=folder, api_keys=[hash_key(KEY)], planner_processes=0,
                    max_body_bytes=4096)  # fmt: skip


@pytest.fixture(scope="module")
def server(bare_settings):
    """The app under uvicorn with httptools (as ``pickstop serve``), with a route that fails."""
    from tests.conftest import free_port

    app = create_app(bare_settings, preload=False)

    def boom() -> None:
        raise RuntimeError("a bug")

    app.add_api_route("/api/v1/boom", boom)
    port = free_port()
    config = uvicorn.Config(app, host="127.0.0.1", port=port, http="httptools",
                            log_level="critical")  # fmt: skip
    srv = uvicorn.Server(config)
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    while not srv.started:
        time.sleep(0.05)
    yield port
    srv.should_exit = True
    thread.join(timeout=10)


def _exchange(sock: socket.socket, request: bytes) -> tuple[int, dict[str, str]]:
    """Send ``request``, read one answer: (status, headers)."""
    sock.sendall(request)
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(65536)
        assert chunk, "the server closed the connection"
        data += chunk
    head, rest = data.split(b"\r\n\r\n", 1)
    lines = head.decode().split("\r\n")
    headers = {k.strip().lower(): v.strip() for k, v in (x.split(":", 1) for x in lines[1:])}
    for _ in range(100):
        if len(rest) >= int(headers.get("content-length", 0)):
            break
        rest += sock.recv(65536)
    return int(lines[0].split()[1]), headers


def _get(path: str) -> bytes:
    return f"GET {path} HTTP/1.1\r\nHost: test\r\n\r\n".encode()


def test_the_connection_stays_usable_after_an_unexpected_error(server):
    with socket.create_connection(("127.0.0.1", server), timeout=10) as sock:
        status, headers = _exchange(sock, _get("/api/v1/boom"))
        assert status == 500 and headers["content-type"] == "application/problem+json"
        assert _exchange(sock, _get("/api/v1/health"))[0] == 200
        assert _exchange(sock, _get("/api/v1/boom"))[0] == 500
        assert _exchange(sock, _get("/api/v1/limits"))[0] == 200


def test_a_body_over_the_limit_closes_the_connection_and_says_so(server):
    with socket.create_connection(("127.0.0.1", server), timeout=10) as sock:
        request = (f"POST /api/v1/scenes HTTP/1.1\r\nHost: test\r\nAuthorization: Bearer "
                   f"{KEY}\r\nContent-Type: application/json\r\nContent-Length: 100000"
                   "\r\n\r\n")  # fmt: skip
        status, headers = _exchange(sock, request.encode())
        assert status == 413 and headers["connection"] == "close"


def test_head_is_answered_wherever_allow_lists_it(bare_settings):
    with TestClient(create_app(bare_settings, preload=False)) as c:
        get = c.get("/api/v1/limits")
        head = c.head("/api/v1/limits")
        assert head.status_code == 200 and head.content == b""
        assert head.headers["content-length"] == get.headers["content-length"]
        assert c.head("/api/v1/scenes/nope").status_code == 404
        r = c.patch("/api/v1/scenes", headers=AUTH)
        assert r.status_code == 405 and "HEAD" in r.headers["allow"]
        assert c.head("/api/v1/scenes").status_code == 200
        r = c.head("/api/v1/jobs/batch/cancel")  # POST only: no HEAD in Allow either
        assert r.status_code == 405 and "HEAD" not in r.headers["allow"]


def test_a_server_folder_in_an_answer_is_named_not_shown():
    from pickstop.api import problems
    from pickstop.api.problems import scrub, server_roots

    kept = list(problems._ROOTS)
    server_roots("/srv/pickstop-data")
    try:
        assert scrub("no database in /srv/pickstop-data") == "no database in the server's folder"
        assert scrub("in /srv/pickstop-data.") == "in the server's folder."
        assert scrub("file /srv/pickstop-data/robots/x.urdf") == "file robots/x.urdf"
        assert scrub("/srv/pickstop-data2/x") == "/srv/pickstop-data2/x"  # not under it
    finally:
        problems._ROOTS[:] = kept
