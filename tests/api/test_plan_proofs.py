"""A stored plan's proven tolerances: a plan whose database or robot is gone answers 409
naming what is missing (nothing proven, the plan's radius still exported)."""

from __future__ import annotations

import pytest

from .conftest import AUTH
from .factories import paper, problem


@pytest.fixture(scope="module")
def plan_doc(client):
    r = client.post("/api/v1/plans", headers=AUTH,
                    json={"scene": paper(), "options": {"samples": 0}})  # fmt: skip
    assert r.status_code == 201, r.text
    return r.json()["plan"]


def _stored(client, plan_doc, **changes) -> str:
    """A plan record of ``plan_doc`` with ``changes`` (as if its robot or database went)."""
    row = client.app.state.service.store.add_plan(None, None, paper(), {}, plan_doc | changes)
    return str(row["id"])


def test_a_plan_whose_database_is_gone_answers_409_naming_it(client, plan_doc):
    plan_id = _stored(client, plan_doc, database="db_deleted0000")
    url = f"/api/v1/plans/{plan_id}/export"
    for params in ({}, {"tolerances": "verified", "format": "lif"}, {"format": "nav2"}):
        body = problem(client.get(url, params=params), 409, "database")
        assert "db_deleted0000" in body["detail"] and "tolerances=radius" in body["detail"]
    assert client.get(url, params={"tolerances": "radius"}).status_code == 200
    assert client.app.state.service.proofs.kept(plan_id) is None


def test_a_plan_whose_robot_is_gone_answers_409_naming_it(client, plan_doc):
    plan_id = _stored(client, plan_doc, robot="ghost-arm")
    body = problem(client.get(f"/api/v1/plans/{plan_id}/export"), 409, "robot")
    assert "'ghost-arm'" in body["detail"]
    r = client.get(f"/api/v1/plans/{plan_id}/export", params={"tolerances": "radius"})
    assert r.status_code == 200
