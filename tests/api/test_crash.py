"""kill -9 during bursts of writes, then restart: the records are intact and every write the
service acknowledged is there."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import threading
import time

import httpx

from pickstop.settings import hash_key
from pickstop.stack import spawn_api

from ..conftest import free_port
from .conftest import KEY
from .factories import paper

AUTH = {"Authorization": f"Bearer {KEY}"}


def test_kill_9_during_writes_loses_no_acknowledged_write(tmp_path):
    env = {**os.environ, "PICKSTOP_DATA_DIR": str(tmp_path),
           "PICKSTOP_API_KEYS": json.dumps([hash_key(KEY)])}  # fmt: skip
    acked: list[str] = []
    log = (tmp_path / "serve.log").open("w")
    for _ in range(2):
        port = free_port()
        proc = spawn_api(port, env, log, timeout=120)
        url = f"http://127.0.0.1:{port}"
        stop = threading.Event()

        def writer(url: str = url, stop: threading.Event = stop) -> None:
            with httpx.Client(base_url=url, timeout=10) as c:
                while not stop.is_set():
                    try:
                        r = c.post("/api/v1/scenes", json=paper(), headers=AUTH)
                    except httpx.HTTPError:
                        return  # the service is gone
                    if r.status_code == 201:
                        acked.append(r.json()["id"])

        threads = [threading.Thread(target=writer) for _ in range(4)]
        for t in threads:
            t.start()
        time.sleep(1.5)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        stop.set()
        for t in threads:
            t.join(timeout=15)
    log.close()
    con = sqlite3.connect(tmp_path / "catalog.sqlite")
    try:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        stored = {r[0] for r in con.execute("SELECT id FROM scenes")}
    finally:
        con.close()
    assert acked and set(acked) <= stored, (len(acked), len(set(acked) - stored))
