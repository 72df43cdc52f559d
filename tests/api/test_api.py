"""Every endpoint through the real app: auth, ETags, problem details, limits, jobs."""

from __future__ import annotations

import copy
import time

import pytest
from fastapi.testclient import TestClient

from pickstop.api.app import create_app
from pickstop.api.store import ServiceStore
from pickstop.settings import Settings

from .conftest import AUTH


def _problem(resp, status, title=None):
    assert resp.status_code == status, resp.text
    assert resp.headers["content-type"].startswith("application/problem+json")
    body = resp.json()
    assert body["status"] == status and body["type"].startswith("https://pickstop.dev/problems/")
    assert body["detail"]
    if title:
        assert body["title"] == title
    return body


def _count(client, path):
    return len(client.get(path, params={"limit": 500}).json())


def test_health_lists_the_loaded_planner(client, region_db):
    body = client.get("/api/v1/health").json()
    assert body["status"] == "ok"
    assert {"robot": "tiago", "database": region_db[1].id} in body["loaded"]


def test_openapi_is_served(client):
    spec = client.get("/api/v1/openapi.json").json()
    assert "/api/v1/plans" in spec["paths"] and "/api/v1/scenes/{scene_id}" in spec["paths"]


def test_writes_need_a_valid_key_reads_do_not(client, paper_doc):
    before = _count(client, "/api/v1/scenes")
    body = _problem(client.post("/api/v1/scenes", json=paper_doc), 401, "Unauthorized")
    assert "API key" in body["detail"]
    bad = {"Authorization": "Bearer wrong"}
    _problem(client.post("/api/v1/scenes", json=paper_doc, headers=bad), 401)
    assert _count(client, "/api/v1/scenes") == before
    assert client.get("/api/v1/robots").status_code == 200


def test_reads_can_require_a_key(api_settings):
    settings = api_settings.model_copy(update={"read_requires_key": True})
    with TestClient(create_app(settings, preload=False)) as c:
        _problem(c.get("/api/v1/scenes"), 401)
        assert c.get("/api/v1/scenes", headers=AUTH).status_code == 200
        _problem(c.get("/api/v1/plans/pln_0123"), 401)  # no cached shortcut around the key


def test_scene_lifecycle_with_etags(client, paper_doc):
    r = client.post("/api/v1/scenes", json=paper_doc, headers=AUTH)
    assert r.status_code == 201
    sid, etag = r.json()["id"], r.headers["etag"]
    assert r.headers["location"] == f"/api/v1/scenes/{sid}"
    got = client.get(f"/api/v1/scenes/{sid}")
    assert got.headers["etag"] == etag and got.json()["scene"] == paper_doc

    changed = copy.deepcopy(paper_doc)
    changed["sigma"] = 0.05
    _problem(client.put(f"/api/v1/scenes/{sid}", json=changed, headers=AUTH), 428)
    ok = client.put(f"/api/v1/scenes/{sid}", json=changed, headers={**AUTH, "If-Match": etag})
    assert ok.status_code == 200 and ok.json()["revision"] == 2
    new_etag = ok.headers["etag"]
    assert new_etag != etag
    # A second editor still holding the old ETag is refused; nothing is overwritten.
    stale = copy.deepcopy(paper_doc)
    stale["sigma"] = 0.2
    body = _problem(
        client.put(f"/api/v1/scenes/{sid}", json=stale, headers={**AUTH, "If-Match": etag}), 412
    )
    assert "changed since you read it" in body["detail"]
    assert client.get(f"/api/v1/scenes/{sid}").json()["scene"]["sigma"] == 0.05

    _problem(client.delete(f"/api/v1/scenes/{sid}", headers={**AUTH, "If-Match": etag}), 412)
    _problem(client.delete(f"/api/v1/scenes/{sid}", headers=AUTH), 428)  # If-Match required
    gone = client.delete(f"/api/v1/scenes/{sid}", headers={**AUTH, "If-Match": new_etag})
    assert gone.status_code == 204
    _problem(client.get(f"/api/v1/scenes/{sid}"), 404, "Not found")


def test_invalid_scene_names_the_field_and_stores_nothing(client, paper_doc):
    before = _count(client, "/api/v1/scenes")
    doc = copy.deepcopy(paper_doc)
    doc["trays"][0]["inner_size"] = [-0.3, 0.2]
    body = _problem(client.post("/api/v1/scenes", json=doc, headers=AUTH), 422, "Invalid input")
    assert body["field"] == "trays.0.inner_size.0"
    assert any(e["field"] == "trays.0.inner_size.0" for e in body["errors"])
    doc = copy.deepcopy(paper_doc)
    doc["robot"] = {"config": "../../etc/robot.yaml"}
    body = _problem(client.post("/api/v1/scenes", json=doc, headers=AUTH), 422)
    assert body["field"] == "robot.config"
    _problem(client.post("/api/v1/scenes", content=b"{not json", headers={**AUTH,
             "content-type": "application/json"}), 422)  # fmt: skip
    assert _count(client, "/api/v1/scenes") == before


def test_grid_and_body_limits(client, paper_doc):
    doc = copy.deepcopy(paper_doc)
    doc["base_grid"] = {"resolution": 0.005}
    body = _problem(client.post("/api/v1/scenes", json=doc, headers=AUTH), 422)
    assert "exceeds the limit" in body["detail"] and body["field"] == "base_grid"
    big = copy.deepcopy(paper_doc)
    big["description"] = "x" * 400_000
    _problem(client.post("/api/v1/scenes", json=big, headers=AUTH), 413, "Request too large")


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
    before = _count(client, "/api/v1/plans")
    body = _problem(
        client.post("/api/v1/plans", json={"scene": paper_doc, "options": {"sigma": 0.6}},
                    headers=AUTH), 422, "Infeasible plan",
    )  # fmt: skip
    assert "no plan with sigma = 0.600 m" in body["detail"] and body["field"] == "sigma"
    assert _count(client, "/api/v1/plans") == before
    body = _problem(client.post("/api/v1/plans", json={"options": {}}, headers=AUTH), 422)
    assert "exactly one of scene_id and scene" in body["detail"]
    body = _problem(client.post("/api/v1/plans", json={"scene": paper_doc, "options":
                    {"target": 2}}, headers=AUTH), 422)  # fmt: skip
    assert body["field"] == "options.target"


def test_regions_and_intersections(client, paper_doc):
    sid = client.post("/api/v1/scenes", json=paper_doc, headers=AUTH).json()["id"]
    body = client.get(f"/api/v1/scenes/{sid}/regions", params={"sigma": 0.1}).json()
    feats = body["regions"]["features"]
    assert {f["properties"]["tray_id"] for f in feats} == {"tray_1", "tray_2", "tray_4"}
    inter = body["intersections"]["features"]
    assert any(f["properties"]["order"] == 2 for f in inter)
    for f in inter:
        p = f["properties"]
        assert p["kept"] == (p["inscribed_radius"] >= 0.1)


def _wait(client, job_id, timeout=120):
    t0 = time.time()
    while time.time() - t0 < timeout:
        job = client.get(f"/api/v1/jobs/{job_id}").json()
        if job["state"] not in ("queued", "running"):
            return job
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} still {job['state']}")


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
    job = _wait(client, r.json()["id"])
    assert job["state"] == "done" and job["progress"] == 1.0
    res = job["result"]
    assert res["planned"] == 1 and res["failed"] == 1
    assert "no plan with sigma" in res["plans"][1]["error"]
    pid = res["plans"][0]["plan_id"]
    assert client.get(f"/api/v1/plans/{pid}").json()["scene_id"] == sid


def test_batch_limits_and_bad_items(client, paper_doc):
    _problem(client.post("/api/v1/jobs/batch", json={"scenes": [{"scene_id": "nope"}]},
             headers=AUTH), 422)  # fmt: skip
    many = {"scenes": [{"scene_id": "x"}] * 201}
    _problem(client.post("/api/v1/jobs/batch", json=many, headers=AUTH), 413)


def test_build_job_and_limits(client):
    _problem(client.post("/api/v1/databases", json={"samples": 10**9}, headers=AUTH), 422)
    _problem(client.post("/api/v1/databases", json={"robot": "fetchy"}, headers=AUTH), 422)
    r = client.post("/api/v1/databases", json={"samples": 30_000, "chunk_size": 10_000,
                    "seed": 5}, headers=AUTH)  # fmt: skip
    assert r.status_code == 202
    job = _wait(client, r.json()["id"])
    assert job["state"] == "done", job
    db_id = job["result"]["database"]
    info = client.get(f"/api/v1/databases/{db_id}").json()
    assert info["state"] == "complete" and info["samples"] == 30_000
    assert client.delete(f"/api/v1/databases/{db_id}", headers=AUTH).status_code == 204
    _problem(client.get(f"/api/v1/databases/{db_id}"), 404)


def test_cancel_a_queued_job(client, paper_doc):
    svc = client.app.state.service
    job = svc.store.add_job("batch", {"scenes": [{"scene": paper_doc}]})  # not queued to run
    r = client.post(f"/api/v1/jobs/{job['id']}/cancel", headers=AUTH)
    assert r.json()["state"] == "cancelled"
    _problem(client.post("/api/v1/jobs/nope/cancel", headers=AUTH), 404)


def test_job_cut_off_by_a_restart_is_interrupted(api_settings, tmp_path):
    settings = Settings(data_dir=tmp_path, api_keys=api_settings.api_keys)
    store = ServiceStore(tmp_path)
    job = store.add_job("batch", {"scenes": []})
    store.set_job(job["id"], state="running", progress=0.4)
    with TestClient(create_app(settings, preload=False)) as c:
        got = c.get(f"/api/v1/jobs/{job['id']}").json()
        assert got["state"] == "interrupted" and "service stopped" in got["error"]
        assert c.get("/api/v1/health").json()["interrupted_jobs_at_start"] == 1


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ({"urdf": "/etc/passwd"}, "urdf"),
        ({"urdf": "../../../etc/robot.urdf"}, "urdf"),
        ({"urdf": "robot.urdf", "package_dirs": ["../../.."]}, "package_dirs.0"),
    ],
)
def test_robot_paths_are_confined(client, config, field):
    base = {"name": "evil", "arm_joints": ["j1"], "tool_frame": "tool",
            "footprint": {"radius": 0.3}}  # fmt: skip
    body = _problem(client.post("/api/v1/robots", json={**base, **config}, headers=AUTH), 422)
    assert "outside the allowed folders" in body["detail"] and body["field"] == field
    assert "evil" not in [r["name"] for r in client.get("/api/v1/robots").json()]


def test_register_a_robot_from_the_bundled_data(client):
    pr2 = {"name": "tiago_copy", "urdf": "package://example-robot-data/robots/tiago_description/"
           "robots/tiago.urdf", "arm_joints": ["torso_lift_joint", "arm_1_joint", "arm_2_joint",
           "arm_3_joint", "arm_4_joint", "arm_5_joint", "arm_6_joint", "arm_7_joint"],
           "tool_frame": "hand_grasping_frame", "footprint": {"radius": 0.275}}  # fmt: skip
    r = client.post("/api/v1/robots", json=pr2, headers=AUTH)
    assert r.status_code == 201, r.text
    assert r.json()["dof"] == 8
    names = [x["name"] for x in client.get("/api/v1/robots").json()]
    assert "tiago" in names and "tiago_copy" in names
    _problem(client.post("/api/v1/robots", json=pr2, headers=AUTH), 422)  # exists already


def test_unknown_paths_are_problems(client):
    _problem(client.get("/api/v1/plans/nope"), 404)
    _problem(client.get("/api/v1/nothing"), 404)
    _problem(client.get("/api/v1/scenes", params={"limit": 0}), 422)


def test_mesh_paths_outside_the_data_folder_are_refused(client, paper_doc):
    before = _count(client, "/api/v1/scenes")
    doc = copy.deepcopy(paper_doc)
    mesh = {"shape": "mesh", "path": "../../../etc/passwd"}
    doc["obstacles"].append({"id": "evil", "geometry": mesh, "pose": {"x": 2.5, "y": 0.0}})
    body = _problem(client.post("/api/v1/scenes", json=doc, headers=AUTH), 422)
    assert body["field"] == "obstacles.2.geometry.path"
    assert "outside the allowed folders" in body["detail"]
    assert _count(client, "/api/v1/scenes") == before
