"""/plans: options checked before work, the same checks for jobs, deadlines."""

from __future__ import annotations

import copy
import time

import pytest
from fastapi.testclient import TestClient

from pickstop.api.app import create_app

from ..conftest import AUTH
from ..factories import count, paper, problem, titled_problem

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


def test_plan_of_a_stored_scene_is_immutable(client, paper_doc):
    sid = client.post("/api/v1/scenes", json=paper_doc, headers=AUTH).json()["id"]
    r = client.post(
        "/api/v1/plans", json={"scene_id": sid, "options": {"samples": 100}}, headers=AUTH
    )
    assert r.status_code == 201, r.text
    rec = r.json()
    assert rec["plan"]["format"] == "pickstop.plan" and rec["scene_revision"] == 1
    pid = rec["id"]
    # The scene changes; the plan keeps the exact input that produced it.
    etag = client.get(f"/api/v1/scenes/{sid}").headers["etag"]
    changed = copy.deepcopy(paper_doc)
    changed["trays"][0]["name"] = "renamed"
    client.put(f"/api/v1/scenes/{sid}", json=changed, headers={**AUTH, "If-Match": etag})
    got = client.get(f"/api/v1/plans/{pid}", params={"include_scene": True}).json()
    assert got["plan"] == rec["plan"] and got["scene"] == paper_doc
    first, second = client.get(f"/api/v1/plans/{pid}"), client.get(f"/api/v1/plans/{pid}")
    assert first.content == second.content and second.json()["plan"] == rec["plan"]
    assert second.headers["content-type"] == "application/json"
    assert "immutable" in second.headers["cache-control"]
    listed = client.get(f"/api/v1/scenes/{sid}/plans").json()
    assert [p["id"] for p in listed] == [pid] and listed[0]["stops"] == len(rec["plan"]["stops"])


def test_inline_plan_and_infeasible_explanation(client, paper_doc):
    r = client.post("/api/v1/plans", json={"scene": paper_doc, "options": {"samples": 0}},
                    headers=AUTH)  # fmt: skip
    assert r.status_code == 201 and r.json()["scene_id"] is None
    before = count(client, "/api/v1/plans")
    body = titled_problem(
        client.post("/api/v1/plans", json={"scene": paper_doc, "options": {"sigma": 0.6}},
                    headers=AUTH), 422, "Infeasible plan",
    )  # fmt: skip
    assert "no plan with sigma = 0.600 m" in body["detail"] and body["field"] == "sigma"
    assert count(client, "/api/v1/plans") == before
    body = titled_problem(client.post("/api/v1/plans", json={"options": {}}, headers=AUTH), 422)
    assert "exactly one of scene_id and scene" in body["detail"]
    body = titled_problem(client.post("/api/v1/plans", json={"scene": paper_doc, "options":
                    {"target": 2}}, headers=AUTH), 422)  # fmt: skip
    assert body["field"] == "options.target"


def test_a_preview_carries_known_regions_and_says_it_is_not_verified(client):
    """While a tray is dragged: the regions planned before, carried with the tray; no
    witnesses, no Monte Carlo, verified false; the exact plan of the same layout afterwards
    is verified. A stored preview is refused."""
    doc = paper()
    exact = client.post(PLANS, json={"scene": doc, "options": {"samples": 0}, "store": False},
                        headers=AUTH)  # fmt: skip
    assert exact.status_code == 200 and exact.json()["plan"]["verified"] is True
    moved = copy.deepcopy(doc)
    moved["trays"][0]["pose"]["x"] += 0.05
    req = {"scene": moved, "options": {"samples": 200}, "mode": "preview", "store": False}
    r = client.post(PLANS, json=req, headers=AUTH)
    assert r.status_code == 200, r.text
    plan = r.json()["plan"]
    assert plan["verified"] is False and plan["notes"][0].startswith("preview:")
    assert plan["stops"] and all(s["witnesses"] == [] for s in plan["stops"])
    assert all(s["success"] is None for s in plan["stops"]) and plan["totals"]["success"] is None
    assert plan["timings"]["verification"] == 0.0

    # Tray 1's region moved with the tray: within its region as planned, moved by the 5 cm,
    # less the cells where the base no longer fits.
    from shapely import affinity
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    def region(p):
        polys = [Polygon(c["polygon"][0], c["polygon"][1:]) for c in p["candidates"]
                 if c["trays"] == ["tray_1"]]  # fmt: skip
        return unary_union(polys)

    was = affinity.translate(region(exact.json()["plan"]), 0.05, 0.0)
    carried = region(plan)
    assert carried.difference(was).area < 1e-6 and carried.area > 0.5 * was.area
    problem(client.post(PLANS, json={**req, "store": True}, headers=AUTH), 422, "store")
    after = client.post(PLANS, json={**req, "mode": "sync", "options": {"samples": 0}},
                        headers=AUTH)  # fmt: skip
    assert after.json()["plan"]["verified"] is True
    assert all(s["witnesses"] for s in after.json()["plan"]["stops"])


def test_a_plan_is_answered_as_the_record_model_would_serialise_it(client, paper_doc):
    """The plan's JSON comes from the planner as bytes; the record around it is the same
    document PlanRecord.model_dump_json gives, stored or not."""
    from pickstop.api.plan_bodies import record_body
    from pickstop.api.schemas import PlanRecord

    for store, status in ((False, 200), (True, 201)):
        r = client.post(PLANS, json={"scene": paper_doc, "options": {"samples": 0, "sigma": 0.07},
                                     "store": store}, headers=AUTH)  # fmt: skip
        assert r.status_code == status, r.text
        assert r.headers["content-type"] == "application/json"
        rec = PlanRecord.model_validate_json(r.content)
        assert r.content == rec.model_dump_json().encode()
        assert rec.plan is not None and rec.plan.parameters.sigma == 0.07
        assert (rec.id is not None) == store
        if store:
            assert r.headers["location"] == f"/api/v1/plans/{rec.id}"
            assert client.get(r.headers["location"]).json()["plan"] == r.json()["plan"]
        bare = rec.model_copy(update={"plan": None})
        assert record_body(bare, rec.plan.model_dump_json().encode()) == r.content


def test_a_previewed_layout_is_planned_ahead_while_the_editor_holds_still(
    api_settings, monkeypatch
):
    """After a preview and a pause with no request, the service makes the layout's exact
    plan in the background: the plan asked for on release computes no region and is
    verified."""
    import threading

    from pickstop.speedups.stop_planner import StopPlanner
    from tests.utils import count_regions

    finished: list[bool] = []
    done = threading.Event()
    real = StopPlanner.plan_ahead

    def ahead(self, *a, **k):
        finished.append(real(self, *a, **k))
        done.set()
        return finished[-1]

    monkeypatch.setattr(StopPlanner, "plan_ahead", ahead)
    settings = api_settings.model_copy(update={"planner_processes": 0})
    with TestClient(create_app(settings)) as client:
        doc = paper()
        first = client.post(PLANS, json={"scene": doc, "options": {"samples": 0}, "store": False},
                            headers=AUTH)  # fmt: skip
        assert first.status_code == 200
        moved = copy.deepcopy(doc)
        moved["trays"][0]["pose"]["x"] += 0.05
        req = {"scene": moved, "options": {"samples": 0}, "mode": "preview", "store": False}
        assert client.post(PLANS, json=req, headers=AUTH).status_code == 200
        assert done.wait(120) and finished == [True]
        made = count_regions(monkeypatch)
        after = client.post(PLANS, json={**req, "mode": "sync"}, headers=AUTH)
        assert after.status_code == 200 and after.json()["plan"]["verified"] is True
        assert made == []
