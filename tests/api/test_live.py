"""The service under uvicorn on 127.0.0.1: end to end, and schemathesis over its OpenAPI spec."""

from __future__ import annotations

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, settings

from .conftest import AUTH


def test_end_to_end_plan_over_http(live_api, paper_doc):
    live = live_api
    with httpx.Client(base_url=live, timeout=120) as c:
        assert c.get("/api/v1/health").json()["status"] == "ok"
        r = c.post("/api/v1/scenes", json=paper_doc, headers=AUTH)
        assert r.status_code == 201
        sid = r.json()["id"]
        r = c.post("/api/v1/plans", json={"scene_id": sid, "options": {"samples": 50}},
                   headers=AUTH)  # fmt: skip
        assert r.status_code == 201, r.text
        plan_id = r.json()["id"]
        got = c.get(f"/api/v1/plans/{plan_id}").json()
        assert got["plan"]["totals"]["stops"] == len(got["plan"]["stops"]) >= 1


schema = schemathesis.pytest.from_fixture("live_schema")


@pytest.fixture(scope="module")
def live_schema(live_api):
    return schemathesis.openapi.from_url(f"{live_api}/api/v1/openapi.json")


@schema.parametrize()
@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
)
def test_no_server_errors_and_responses_match_the_spec(case):
    from schemathesis.checks import not_a_server_error
    from schemathesis.specs.openapi.checks import response_schema_conformance

    case.call_and_validate(
        headers=AUTH, timeout=120, checks=[not_a_server_error, response_schema_conformance]
    )
