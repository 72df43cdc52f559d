"""`pickstop serve --workers 2`: two processes on one port, one job runner, one truth."""

from __future__ import annotations

import json
import os
import subprocess
import time

import httpx
import pytest

from pickstop.settings import hash_key
from pickstop.stack import spawn_api
from tests.api.factories import paper

from ..conftest import free_port
from .conftest import AUTH, KEY


@pytest.fixture(scope="module")
def two_workers(region_db, tmp_path_factory):
    folder, _ = region_db
    port = free_port()
    env = {**os.environ, "PICKSTOP_DATA_DIR": str(folder), "PICKSTOP_WORKERS": "2",
           "PICKSTOP_API_KEYS": json.dumps([hash_key(KEY)])}  # fmt: skip
    log = (tmp_path_factory.mktemp("workers") / "serve.log").open("w")
    proc = spawn_api(port, env, log, timeout=180)
    yield f"http://127.0.0.1:{port}"
    proc.terminate()
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
    log.close()
    for pid in SEEN:  # the workers stop with the parent
        t0 = time.time()
        while time.time() - t0 < 15:
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
        else:
            raise AssertionError(f"worker {pid} outlived the parent")


SEEN: set[int] = set()


def test_two_processes_answer_and_share_the_records(two_workers):
    for _ in range(60):
        SEEN.add(httpx.get(f"{two_workers}/api/v1/health", timeout=10).json()["process"])
        if len(SEEN) == 2:
            break
    assert len(SEEN) == 2, SEEN
    with httpx.Client(base_url=two_workers, timeout=60) as c:
        sid = c.post("/api/v1/scenes", json=paper(), headers=AUTH).json()["id"]
    for _ in range(10):  # a fresh connection each time: either process answers
        assert httpx.get(f"{two_workers}/api/v1/scenes/{sid}", timeout=10).status_code == 200


def _until(url, job_id, states, timeout=120.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        job = httpx.get(f"{url}/api/v1/jobs/{job_id}", timeout=10).json()
        if job["state"] in states:
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} still {job['state']}")


def test_jobs_run_once_and_cancel_reaches_the_runner(two_workers):
    quick = {"scenes": [{"scene": paper()}], "options": {"samples": 0}}
    ids = [httpx.post(f"{two_workers}/api/v1/jobs/batch", json=quick, headers=AUTH,
                      timeout=60).json()["id"] for _ in range(4)]  # fmt: skip
    for job_id in ids:
        assert _until(two_workers, job_id, {"done", "failed"})["state"] == "done"
    heavy = {"scenes": [{"scene": paper()}] * 2,
             "options": {"samples": 20000, "seed": time.time_ns() % 2**31}}  # fmt: skip
    job_id = httpx.post(f"{two_workers}/api/v1/jobs/batch", json=heavy, headers=AUTH,
                        timeout=60).json()["id"]  # fmt: skip
    _until(two_workers, job_id, {"running"})
    for _ in range(4):  # from whichever process answers, more than once
        got = httpx.post(f"{two_workers}/api/v1/jobs/{job_id}/cancel", headers=AUTH, timeout=60)
        if got.json()["state"] == "cancelled":
            break
    assert _until(two_workers, job_id, {"cancelled", "done", "failed"}, 20)["state"] == "cancelled"
