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


def test_database_info_says_whether_the_screen_meets_its_bound():
    from pickstop.api.schemas import DatabaseInfo

    ok = DatabaseInfo.of({"id": "a", "screen_false_rejection": 0.03})
    over = DatabaseInfo.of({"id": "b", "screen_false_rejection": 0.07})
    assert ok.screen_meets_bound is True and ok.screen_bound == 0.05
    assert over.screen_meets_bound is False and over.screen_false_rejection == 0.07
    assert DatabaseInfo.of({"id": "c"}).screen_meets_bound is None  # not measured
