"""POST /plans with orders: every order of a mix planned on one layout, stored (each order's
plan a plan record, the mix a mix record), or as a job; bounded by max_orders."""

from __future__ import annotations

from ..conftest import AUTH
from ..factories import paper, problem, wait_job

ORDERS = [{"id": "a", "trays": ["tray_1", "tray_2"], "weight": 2}, {"id": "b", "parts": ["p4a"]}]


def test_a_mix_is_planned_stored_and_fetchable(client):
    body = {"scene": paper(), "orders": ORDERS, "options": {"samples": 0}}
    r = client.post("/api/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    rec = r.json()
    assert r.headers["Location"] == f"/api/v1/mixes/{rec['id']}"
    mix = rec["mix"]
    assert mix["totals"]["orders"] == mix["totals"]["planned"] == 2
    assert client.get(f"/api/v1/mixes/{rec['id']}").json() == rec
    b = client.get(f"/api/v1/plans/{mix['orders'][1]['plan']}", params={"include_scene": True})
    assert b.json()["plan"]["trays"] == ["tray_4"] and b.json()["scene"]["task"] == ["tray_4"]
    assert b.json()["plan"]["totals"]["stops"] == mix["orders"][1]["stops"]
    listed = client.get("/api/v1/mixes").json()
    assert any(m["id"] == rec["id"] and m["orders"] == 2 for m in listed)


def test_a_mix_of_the_scenes_own_orders_as_a_job(client):
    doc = {**paper(), "orders": ORDERS}
    sid = client.post("/api/v1/scenes", json=doc, headers=AUTH).json()["id"]
    body = {"scene_id": sid, "orders": "scene", "options": {"samples": 0}, "mode": "job"}
    r = client.post("/api/v1/plans", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "done" and job["kind"] == "mix", job
    mix = client.get(f"/api/v1/mixes/{job['result']['mix']}").json()
    assert mix["scene_id"] == sid and [o["id"] for o in mix["mix"]["orders"]] == ["a", "b"]


def test_bad_orders_are_refused_before_any_work(client, api_settings):
    body = {"scene": paper(), "orders": [{"id": "a", "trays": ["tray_9"]}]}
    problem(client.post("/api/v1/plans", json=body, headers=AUTH), 422, "orders.0.trays.0")
    problem(client.post("/api/v1/plans", json={**body, "mode": "job"}, headers=AUTH), 422,
            "orders.0.trays.0")  # fmt: skip
    too_many = [{"id": f"o{i}", "trays": ["tray_1"]} for i in range(api_settings.max_orders + 1)]
    problem(client.post("/api/v1/plans", json={"scene": paper(), "orders": too_many},
                        headers=AUTH), 413, "orders")  # fmt: skip
    problem(client.post("/api/v1/plans", json={"scene": paper(), "orders": "scene"},
                        headers=AUTH), 422, "orders")  # fmt: skip
    preview = {"scene": paper(), "orders": ORDERS, "mode": "preview", "store": False}
    problem(client.post("/api/v1/plans", json=preview, headers=AUTH), 422, "mode")
