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
