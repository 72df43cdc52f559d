"""The service under uvicorn on 127.0.0.1: end to end, and schemathesis over its OpenAPI spec."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, settings

from pickstop.settings import hash_key

from .conftest import AUTH, KEY


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def live(region_db, tmp_path_factory):
    folder, _ = region_db
    port = _free_port()
    env = {
        **os.environ,
        "PICKSTOP_DATA_DIR": str(folder),
        "PICKSTOP_API_KEYS": f'["{hash_key(KEY)}"]',
        "PICKSTOP_MAX_SAMPLES": "40000",
        "PICKSTOP_MAX_BATCH": "3",
        "PICKSTOP_MAX_BODY_BYTES": "200000",
    }
    log = (tmp_path_factory.mktemp("live") / "serve.log").open("w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "pickstop.cli", "serve", "--host", "127.0.0.1", "--port",
         str(port), "--log-level", "warning"],
        env=env, stdout=log, stderr=subprocess.STDOUT,
    )  # fmt: skip
    url = f"http://127.0.0.1:{port}"
    t0 = time.time()
    while True:
        try:
            if httpx.get(f"{url}/api/v1/health", timeout=2).status_code == 200:
                break
        except httpx.HTTPError:
            pass
        if proc.poll() is not None or time.time() - t0 > 120:
            proc.kill()
            raise RuntimeError(f"the service did not start; see {log.name}")
        time.sleep(0.3)
    yield url
    proc.terminate()
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()


def test_end_to_end_plan_over_http(live, paper_doc):
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
def live_schema(live):
    return schemathesis.openapi.from_url(f"{live}/api/v1/openapi.json")


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
