"""Builds in a process group of their own: a cancel ends every process of the build and
removes its database; no process outlives the service, however many builds it ran."""

from __future__ import annotations

import os
import random
import signal
import time

import httpx
import psutil
from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.settings import Settings, hash_key
from tests.api.factories import wait_job

from .conftest import AUTH, KEY


def _alive(procs: list[psutil.Process]) -> list[psutil.Process]:
    out = []
    for p in procs:
        try:
            if p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


def _wait_gone(procs: list[psutil.Process], seconds: float) -> list[psutil.Process]:
    end = time.monotonic() + seconds
    while _alive(procs) and time.monotonic() < end:
        time.sleep(0.1)
    return _alive(procs)


def _start_build(c, seed: int) -> str:
    r = c.post("/api/v1/databases", json={"samples": 40_000, "chunk_size": 1000, "seed": seed},
               headers=AUTH)  # fmt: skip
    assert r.status_code == 202, r.text
    return str(r.json()["id"])


def _until_progress(c, job_id: str) -> dict:
    for _ in range(600):
        job = c.get(f"/api/v1/jobs/{job_id}").json()
        if job["state"] != "queued" and (job["state"] != "running" or job["progress"] > 0):
            return dict(job)
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} made no progress")


def test_cancelled_builds_leave_no_process_and_no_database(tmp_path):
    """Cancels at random moments of ten builds (starting, screening, chunking): every process
    of each build ends, and no database of a cancelled build remains."""
    settings = Settings(data_dir=tmp_path, api_keys=[hash_key(KEY)], planner_processes=0)
    me = psutil.Process()
    rng = random.Random(7)
    with TestClient(create_app(settings, preload=False)) as c:
        before = {p.pid for p in me.children(recursive=True)}
        for k in range(10):
            job_id = _start_build(c, 100 + k)
            if k % 2:  # while its pool computes chunks
                _until_progress(c, job_id)
            time.sleep(rng.uniform(0.0, 2.0))
            state = c.post(f"/api/v1/jobs/{job_id}/cancel", headers=AUTH).json()["state"]
            if state == "running":  # the cancel is under way
                state = wait_job(c, job_id)["state"]
            assert state in ("cancelled", "done"), state
            left = [p for p in me.children(recursive=True) if p.pid not in before]
            assert not _wait_gone(left, 10.0), [p.cmdline()[-1][:60] for p in _alive(left)]
        rows = c.get("/api/v1/databases").json()
        done = [j for j in c.get("/api/v1/jobs").json() if j["state"] == "done"]
        assert {r["id"] for r in rows} == {j["result"]["database"] for j in done}
        reach = tmp_path / "reach"
        folders = {p.name for p in reach.iterdir()} if reach.exists() else set()
        assert folders <= {r["id"] for r in rows}


def test_no_process_outlives_the_service(tmp_path):
    """``pickstop serve`` stopped in the middle of a build (and after a plan request started
    its planner process): every process it started ends with it."""
    from pickstop.stack import spawn_api
    from tests.conftest import free_port

    port = free_port()
    env = {**os.environ, "PICKSTOP_DATA_DIR": str(tmp_path),
           "PICKSTOP_API_KEYS": f'["{hash_key(KEY)}"]'}  # fmt: skip
    with (tmp_path / "serve.log").open("w") as log:
        proc = spawn_api(port, env, log, timeout=120)
        try:
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60) as c:
                job = _until_progress(c, _start_build(c, 7))
                assert job["state"] == "running", job
            tree = psutil.Process(proc.pid).children(recursive=True)
            assert len(tree) >= 3, [p.cmdline()[-1][:60] for p in tree]  # planner, build, pool
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    left = _wait_gone(tree, 10.0)
    for p in left:  # not to disturb what runs next
        p.kill()
    assert not left, [" ".join(p.cmdline())[-80:] for p in left]
