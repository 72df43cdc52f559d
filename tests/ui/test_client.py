"""The planner's API client: a kept-alive connection the API closed is tried again once."""

from __future__ import annotations

import socket
import threading

import httpx
import pytest

from pickstop_ui.client import PickStopClient

OK = (
    b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: 15\r\n\r\n"
    b'{"status":"ok"}'
)


def _server(answers: list[bytes | None]) -> tuple[int, threading.Thread]:
    """A loopback server taking one connection per answer: it reads the request, then sends
    the answer and closes, or closes without a word (None)."""
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]

    def serve() -> None:
        with srv:
            for answer in answers:
                conn, _ = srv.accept()
                with conn:
                    conn.recv(65536)
                    if answer is not None:
                        conn.sendall(answer)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    return port, t


def test_a_connection_closed_without_a_response_is_tried_once_more():
    port, t = _server([None, OK])
    client = PickStopClient(f"http://127.0.0.1:{port}")
    assert client.health() == {"status": "ok"}
    t.join(5)
    client.close()


def test_without_the_retry_the_same_close_fails_and_a_second_close_still_does():
    port, t = _server([None])
    with pytest.raises(httpx.RemoteProtocolError), httpx.Client() as plain:
        plain.get(f"http://127.0.0.1:{port}/api/v1/health")
    t.join(5)
    port, t = _server([None, None])
    client = PickStopClient(f"http://127.0.0.1:{port}")
    with pytest.raises(httpx.RemoteProtocolError):
        client.health()
    t.join(5)
    client.close()
