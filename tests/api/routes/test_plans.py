"""/plans: options checked before work, the same checks for jobs, deadlines."""

from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient

from pickstop.api.app import create_app

from ..conftest import AUTH
from ..factories import paper, problem

PLANS = "/api/v1/plans"


@pytest.mark.parametrize("mode", ["sync", "job"])
def test_a_negative_seed_is_refused_before_any_work(client, mode):
    before = len(client.get("/api/v1/jobs", params={"limit": 500}).json())
    req = {"scene": paper(), "options": {"seed": -1, "samples": 10}, "mode": mode}
    t0 = time.perf_counter()
    problem(client.post(PLANS, json=req, headers=AUTH), 422, "options.seed")
    assert time.perf_counter() - t0 < 1.0
    assert len(client.get("/api/v1/jobs", params={"limit": 500}).json()) == before


def test_a_plan_job_is_validated_when_submitted(client):
    bad = paper()
    bad["trays"][0]["inner_size"] = [-0.3, 0.2]
    r = client.post(PLANS, json={"scene": bad, "mode": "job"}, headers=AUTH)
    problem(r, 422, "scene.trays.0.inner_size.0")
    bad = paper()
    bad["robot"] = {"preset": "../../etc/passwd"}
    problem(client.post(PLANS, json={"scene": bad, "mode": "job"}, headers=AUTH), 422,
            "scene.robot.preset")  # fmt: skip
    problem(client.post(PLANS, json={"scene_id": "scn_nope", "mode": "job"}, headers=AUTH), 422,
            "scene_id")  # fmt: skip


def test_monte_carlo_samples_are_limited(client, api_settings):
    n = api_settings.max_mc_samples + 1
    body = problem(client.post(PLANS, json={"scene": paper(), "options": {"samples": n}},
                               headers=AUTH), 422, "options.samples")  # fmt: skip
    assert "exceed the limit" in body["detail"]


def test_a_request_over_its_deadline_is_stopped_and_the_next_plan_is_served(api_settings):
    settings = api_settings.model_copy(update={"request_deadline": 1.0})
    with TestClient(create_app(settings)) as c:
        # Monte Carlo of 20,000 samples per stop, a fresh seed so that nothing is cached.
        seed = time.time_ns() % 2**31
        heavy = {"scene": paper(), "options": {"samples": 20000, "seed": seed}, "store": False}
        t0 = time.perf_counter()
        body = problem(c.post(PLANS, json=heavy, headers=AUTH), 504)
        assert "deadline of 1 s" in body["detail"]
        assert time.perf_counter() - t0 < 3.0
        quick = {"scene": paper(), "options": {"samples": 0}, "store": False}
        t0 = time.perf_counter()
        c.app.state.service.settings = settings.model_copy(update={"request_deadline": 60.0})
        r = c.post(PLANS, json=quick, headers=AUTH)
        assert r.status_code == 200, r.text
        assert time.perf_counter() - t0 < 20.0  # not behind the stopped computation
