"""Stable addresses: `pickstop serve` binds its port with SO_REUSEADDR or exits naming it."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time

import pytest

from pickstop.stack import PortInUse, listen

from .conftest import free_port


def _time_wait_port() -> int:
    """A port whose last connection the server side closed first: it lingers in TIME_WAIT,
    as the connections of a crashed `pickstop serve` do (uvicorn listens with SO_REUSEADDR)."""
    srv = socket.socket()
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    port = srv.getsockname()[1]
    cli = socket.create_connection(("127.0.0.1", port))
    conn, _ = srv.accept()
    conn.close()  # the server closes first: its side of the connection enters TIME_WAIT
    cli.recv(1)
    cli.close()
    srv.close()
    time.sleep(0.3)  # the client's FIN arrives: FIN_WAIT2 becomes TIME_WAIT
    return int(port)


def test_a_port_in_time_wait_is_not_busy():
    port = _time_wait_port()
    plain = socket.socket()
    try:
        with pytest.raises(OSError):
            plain.bind(("127.0.0.1", port))  # what the old probe did: 'busy'
    finally:
        plain.close()
    listen("127.0.0.1", port).close()


def test_a_port_really_taken_is_an_error_naming_it():
    taken = listen("127.0.0.1", free_port())
    port = taken.getsockname()[1]
    try:
        with pytest.raises(PortInUse, match=f"port {port}"):
            listen("127.0.0.1", port)
        proc = subprocess.run(
            [sys.executable, "-m", "pickstop.cli", "serve", "--no-ui", "--port", str(port)],
            env=dict(os.environ), capture_output=True, text=True,
            timeout=120,
        )  # fmt: skip
    finally:
        taken.close()
    assert proc.returncode != 0
    assert f"port {port}" in proc.stderr and "takes" not in proc.stderr


def test_the_listening_socket_lets_asyncio_disable_nagle():
    """asyncio sets TCP_NODELAY only on IPPROTO_TCP sockets; without it every small answer
    waits 40 ms for a delayed ACK."""
    sock = listen("127.0.0.1", 0)
    try:
        assert sock.proto == socket.IPPROTO_TCP
    finally:
        sock.close()
