"""/databases: every build parameter checked before the job is queued."""

from __future__ import annotations

import pytest

from ..conftest import AUTH
from ..factories import problem, titled_problem, wait_job


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"seed": -1}, "seed"),
        ({"resolution": 0.6}, "resolution"),
        ({"thinning": 10}, "thinning"),
        ({"samples": 999}, "samples"),
        ({"robot": "../../etc/passwd"}, "robot"),
    ],
)
def test_build_parameters_are_checked_at_submission(client, params, field):
    before = len(client.get("/api/v1/jobs", params={"limit": 500}).json())
    problem(client.post("/api/v1/databases", json=params, headers=AUTH), 422, field)
    assert len(client.get("/api/v1/jobs", params={"limit": 500}).json()) == before


def test_build_job_and_limits(client):
    titled_problem(client.post("/api/v1/databases", json={"samples": 10**9}, headers=AUTH), 422)
    titled_problem(client.post("/api/v1/databases", json={"robot": "fetchy"}, headers=AUTH), 422)
    r = client.post("/api/v1/databases", json={"samples": 30_000, "chunk_size": 10_000,
                    "seed": 5}, headers=AUTH)  # fmt: skip
    assert r.status_code == 202
    job = wait_job(client, r.json()["id"])
    assert job["state"] == "done", job
    db_id = job["result"]["database"]
    info = client.get(f"/api/v1/databases/{db_id}").json()
    assert info["state"] == "complete" and info["samples"] == 30_000
    assert client.delete(f"/api/v1/databases/{db_id}", headers=AUTH).status_code == 204
    titled_problem(client.get(f"/api/v1/databases/{db_id}"), 404)


def _settings(folder, **over):
    from pickstop.settings import Settings, hash_key

    from ..conftest import KEY

    return Settings(data_dir=folder, api_keys=[hash_key(KEY)], planner_processes=0,
                    region_processes=1, **over)  # fmt: skip


def _build(c, **params):
    r = c.post("/api/v1/databases", json={"robot": "tiago", **params}, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_job(c, r.json()["id"], timeout=300)
    assert job["state"] == "done", job
    return job["result"]["database"]


def test_a_later_build_never_becomes_the_database_of_plans_naming_none(tmp_path):
    """A key holder's build with more configurations and a thinner floor margin, after a
    restart, is still not what plans use when they name no database; the setting is."""
    from fastapi.testclient import TestClient

    from pickstop.api.app import create_app

    with TestClient(create_app(_settings(tmp_path), preload=False)) as c:
        first = _build(c, samples=1000)
        thin = _build(c, samples=3000, floor_clearance=1e-38)
        rows = {d["id"]: d for d in c.get("/api/v1/databases").json()}
        assert rows[thin]["stored"] > rows[first]["stored"]
    with TestClient(create_app(_settings(tmp_path))) as c:  # restarted
        assert c.get("/api/v1/health").json()["loaded"] == [{"robot": "tiago", "database": first}]
    chosen = _settings(tmp_path, default_databases={"tiago": thin})
    with TestClient(create_app(chosen)) as c:
        assert c.get("/api/v1/health").json()["loaded"][0]["database"] == thin


def _fake_database(folder, db_id, **over):
    import json as _json

    from pickstop.store import reach_catalog as rc
    from pickstop.store.catalog import Catalog

    row = {"id": db_id, "robot": "tiago", "robot_hash": "h" * 64, "dof": 8, "resolution": 0.05,
           "orientation": 6, "samples": 2000, "seed": 0, "chunk_size": 1000, "thinning": 0.0,
           "code_version": "test", "joint_lower": _json.dumps([0.0] * 8),
           "joint_upper": _json.dumps([1.0] * 8), "state": "interrupted",
           "created": "2026-01-01T00:00:00+00:00", **over}  # fmt: skip
    cat = Catalog(folder)
    rc.insert_database(cat, row)
    cat.close()
    (folder / "reach" / db_id).mkdir(parents=True)
    (folder / "reach" / db_id / "chunk-000000.parquet").write_bytes(b"x")


def test_interrupted_builds_are_deleted_after_the_retention(tmp_path):
    from datetime import UTC, datetime

    from fastapi.testclient import TestClient

    from pickstop.api.app import create_app
    from pickstop.store.reach_catalog import builder_tag

    _fake_database(tmp_path, "old")
    _fake_database(tmp_path, "recent", created=datetime.now(UTC).isoformat(timespec="seconds"))
    _fake_database(tmp_path, "busy", state="building", builder=builder_tag())  # this process
    settings = _settings(tmp_path, interrupted_retention=3600)
    with TestClient(create_app(settings, preload=False)) as c:
        states = {d["id"]: d["state"] for d in c.get("/api/v1/databases").json()}
        assert states == {"recent": "interrupted", "busy": "building"}
        assert not (tmp_path / "reach" / "old").exists()
        body = problem(c.delete("/api/v1/databases/busy", headers=AUTH), 409)
        assert "being built" in body["detail"]
        assert c.delete("/api/v1/databases/recent", headers=AUTH).status_code == 204
        assert not (tmp_path / "reach" / "recent").exists()


def test_database_info_says_whether_the_screen_meets_its_bound():
    from pickstop.api.schemas import DatabaseInfo

    ok = DatabaseInfo.of({"id": "a", "screen_false_rejection": 0.03})
    over = DatabaseInfo.of({"id": "b", "screen_false_rejection": 0.07})
    assert ok.screen_meets_bound is True and ok.screen_bound == 0.05
    assert over.screen_meets_bound is False and over.screen_false_rejection == 0.07
    assert DatabaseInfo.of({"id": "c"}).screen_meets_bound is None  # not measured


def test_deleting_a_database_being_built_is_a_documented_409(client):
    spec = client.get("/api/v1/openapi.json").json()["paths"]
    assert "409" in spec["/api/v1/databases/{db_id}"]["delete"]["responses"]
