"""POST /layouts: a layout search as a job (progress, result, cancel), checked when submitted."""

from __future__ import annotations

from ..conftest import AUTH
from ..factories import paper, problem, wait_job


def test_a_layout_search_runs_as_a_job(client):
    body = {"scene": paper(), "movable": ["tray_4"], "turns": [0], "step": 0.2,
            "suggestions": 1, "shortlist": 4, "options": {"samples": 0}}  # fmt: skip
    r = client.post("/api/v1/layouts", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"], timeout=300)
    assert job["state"] == "done" and job["kind"] == "layout", job
    doc = job["result"]
    assert doc["format"] == "pickstop.layout" and doc["movable"] == ["tray_4"]
    assert doc["before"]["totals"]["planned"] == 1
    for s in doc["suggestions"]:
        assert s["verified"] and s["moves"][0]["tray"] == "tray_4"
        assert client.post("/api/v1/scenes", json=s["scene"], headers=AUTH).status_code == 201


def test_a_layout_search_can_be_cancelled(client):
    body = {"scene": paper(), "movable": ["tray_4", "tray_2"], "options": {"samples": 500}}
    job = client.post("/api/v1/layouts", json=body, headers=AUTH).json()
    got = client.post(f"/api/v1/jobs/{job['id']}/cancel", headers=AUTH).json()
    assert wait_job(client, got["id"])["state"] == "cancelled"


def test_a_bad_layout_request_is_refused_when_submitted(client):
    body = {"scene": paper(), "movable": ["tray_3"]}  # no order needs it
    problem(client.post("/api/v1/layouts", json=body, headers=AUTH), 422, "movable.0")
    problem(client.post("/api/v1/layouts", json={**body, "movable": ["nope"]}, headers=AUTH),
            422, "movable.0")  # fmt: skip
    problem(client.post("/api/v1/layouts", json={**body, "turns": [45]}, headers=AUTH), 422,
            "turns.0")  # fmt: skip
