"""/jobs: cancel stops the work itself; jobs have their own deadline."""

from __future__ import annotations

import time

from fastapi.testclient import TestClient

from pickstop.api.app import create_app

from ..conftest import AUTH
from ..factories import paper


def _until(c, job_id, states, timeout=60.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        job = c.get(f"/api/v1/jobs/{job_id}").json()
        if job["state"] in states:
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} still {job['state']}")


def heavy() -> dict:
    """A batch of one Monte Carlo heavy plan, seeded afresh so that nothing is cached."""
    options = {"samples": 20000, "seed": time.time_ns() % 2**31}
    return {"scenes": [{"scene": paper()}, {"scene": paper()}], "options": options}


def test_cancel_stops_a_running_job_and_the_next_plan_is_served(client):
    job = client.post("/api/v1/jobs/batch", json=heavy(), headers=AUTH).json()
    _until(client, job["id"], {"running"})
    time.sleep(0.3)
    t0 = time.perf_counter()
    got = client.post(f"/api/v1/jobs/{job['id']}/cancel", headers=AUTH).json()
    assert got["state"] == "cancelled" and "while running" in got["error"]
    assert time.perf_counter() - t0 < 5.0
    r = client.post("/api/v1/plans", json={"scene": paper(), "options": {"samples": 0},
                    "store": False}, headers=AUTH)  # fmt: skip
    assert r.status_code == 200, r.text


def test_a_job_over_its_deadline_fails_saying_so(api_settings):
    settings = api_settings.model_copy(update={"job_deadline": 0.5})
    with TestClient(create_app(settings)) as c:
        job = c.post("/api/v1/jobs/batch", json=heavy(), headers=AUTH).json()
        done = _until(c, job["id"], {"failed", "done", "cancelled"})
    assert done["state"] == "failed" and "deadline of 0.5 s" in done["error"], done
