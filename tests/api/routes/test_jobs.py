"""/jobs: cancel stops the work itself; jobs have their own deadline."""

from __future__ import annotations

import copy
import time

from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.settings import Settings
from pickstop.store.records import ServiceStore

from ..conftest import AUTH
from ..factories import paper, titled_problem, wait_job


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


def test_batch_job_plans_every_scene(client, paper_doc):
    sid = client.post("/api/v1/scenes", json=paper_doc, headers=AUTH).json()["id"]
    wide = copy.deepcopy(paper_doc)
    wide["sigma"] = 0.6
    r = client.post(
        "/api/v1/jobs/batch",
        json={"scenes": [{"scene_id": sid}, {"scene": wide}], "options": {"samples": 0}},
        headers=AUTH,
    )
    assert r.status_code == 202
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "done" and job["progress"] == 1.0
    res = job["result"]
    assert res["planned"] == 1 and res["failed"] == 1
    assert "no plan with sigma" in res["plans"][1]["error"]
    pid = res["plans"][0]["plan_id"]
    assert client.get(f"/api/v1/plans/{pid}").json()["scene_id"] == sid


def test_batch_limits_and_bad_items(client, paper_doc):
    titled_problem(client.post("/api/v1/jobs/batch", json={"scenes": [{"scene_id": "nope"}]},
             headers=AUTH), 422)  # fmt: skip
    many = {"scenes": [{"scene_id": "x"}] * 201}
    titled_problem(client.post("/api/v1/jobs/batch", json=many, headers=AUTH), 413)


def test_cancel_a_queued_job(client, paper_doc):
    svc = client.app.state.service
    job = svc.store.add_job("batch", {"scenes": [{"scene": paper_doc}]})  # not queued to run
    r = client.post(f"/api/v1/jobs/{job['id']}/cancel", headers=AUTH)
    assert r.json()["state"] == "cancelled"
    titled_problem(client.post("/api/v1/jobs/nope/cancel", headers=AUTH), 404)


def test_job_cut_off_by_a_restart_is_interrupted(api_settings, tmp_path):
    settings = Settings(data_dir=tmp_path, api_keys=api_settings.api_keys)
    store = ServiceStore(tmp_path)
    job = store.add_job("batch", {"scenes": []})
    store.set_job(job["id"], state="running", progress=0.4)
    with TestClient(create_app(settings, preload=False)) as c:
        got = c.get(f"/api/v1/jobs/{job['id']}").json()
        assert got["state"] == "interrupted" and "service stopped" in got["error"]
        assert c.get("/api/v1/health").json()["interrupted_jobs_at_start"] == 1
