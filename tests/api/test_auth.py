"""Authentication: writes need a key, reads only if configured."""

from __future__ import annotations

from fastapi.testclient import TestClient

from pickstop.api.app import create_app

from .conftest import AUTH
from .factories import count, titled_problem


def test_writes_need_a_valid_key_reads_do_not(client, paper_doc):
    before = count(client, "/api/v1/scenes")
    body = titled_problem(client.post("/api/v1/scenes", json=paper_doc), 401, "Unauthorized")
    assert "API key" in body["detail"]
    bad = {"Authorization": "Bearer wrong"}
    titled_problem(client.post("/api/v1/scenes", json=paper_doc, headers=bad), 401)
    assert count(client, "/api/v1/scenes") == before
    assert client.get("/api/v1/robots").status_code == 200


def test_reads_can_require_a_key(api_settings):
    settings = api_settings.model_copy(update={"read_requires_key": True})
    with TestClient(create_app(settings, preload=False)) as c:
        titled_problem(c.get("/api/v1/scenes"), 401)
        assert c.get("/api/v1/scenes", headers=AUTH).status_code == 200
        titled_problem(c.get("/api/v1/plans/pln_0123"), 401)  # no cached shortcut around the key
