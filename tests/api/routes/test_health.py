"""/health and /limits: the limits a client can check before sending."""

from __future__ import annotations


def test_limits_are_published(client, api_settings):
    limits = client.get("/api/v1/limits").json()
    assert limits["max_trays"] == api_settings.max_trays
    assert limits["max_body_bytes"] == api_settings.max_body_bytes
    assert limits["request_deadline_s"] == api_settings.request_deadline
    for key in ("max_parts_per_tray", "max_parts", "max_obstacles", "max_mesh_triangles",
                "max_grid_cells", "max_mc_samples", "max_batch", "max_build_samples"):  # fmt: skip
        assert limits[key] >= 0
    assert client.get("/api/v1/health").json()["limits"] == limits


def test_health_lists_the_loaded_planner(client, region_db):
    """The planner process loads in the background (health never waits for it): once it has,
    health lists its planner."""
    import time

    want = {"robot": "tiago", "database": region_db[1].id}
    end = time.monotonic() + 180
    while True:
        body = client.get("/api/v1/health").json()
        assert body["status"] == "ok"
        if want in body["loaded"] or time.monotonic() > end:
            break
        time.sleep(0.2)
    assert want in body["loaded"]


def test_openapi_is_served(client):
    spec = client.get("/api/v1/openapi.json").json()
    assert "/api/v1/plans" in spec["paths"] and "/api/v1/scenes/{scene_id}" in spec["paths"]
