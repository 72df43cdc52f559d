"""The service under uvicorn on 127.0.0.1: end to end, and schemathesis over its OpenAPI spec."""

from __future__ import annotations

import time

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


def _databases(url: str) -> dict[str, str]:
    rows = httpx.get(f"{url}/api/v1/databases", headers=AUTH, timeout=30).json()
    return {r["id"]: r["state"] for r in rows}


@pytest.fixture(scope="module", autouse=True)
def _fuzzed_builds_leave_nothing(live_api):
    """Fuzzed requests may start jobs (builds, layout searches, batches) and builds may
    complete small databases in the session's data folder: cancel the jobs and delete those
    databases after this module, so that every later test
    finds the folder as it was (a small database built with the default parameters would
    otherwise become the default of services that pin none)."""
    before = set(_databases(live_api))
    yield
    # Every fuzzed job is cancelled, not only builds: a layout search holds the robot's planners
    # while it runs, and later tests' plans on this service would wait for it.
    for job in httpx.get(f"{live_api}/api/v1/jobs?limit=500", headers=AUTH, timeout=30).json():
        if job["state"] in ("queued", "running"):
            httpx.post(f"{live_api}/api/v1/jobs/{job['id']}/cancel", headers=AUTH, timeout=60)
    end = time.monotonic() + 60
    while left := set(_databases(live_api)) - before:
        assert time.monotonic() < end, f"databases left after the fuzzing: {left}"
        for db_id in left:  # 409 while a cancelled build still winds down: asked again
            r = httpx.delete(f"{live_api}/api/v1/databases/{db_id}", headers=AUTH, timeout=60)
            assert r.status_code in (204, 404, 409), r.text
        time.sleep(0.5)


@pytest.fixture(scope="module")
def live_schema(live_api):
    schema = schemathesis.openapi.from_url(f"{live_api}/api/v1/openapi.json")
    # A schema-valid scene or robot can still be refused with a documented 422: a tray inside
    # an obstacle, a URDF that is not there, sizes over the limits. The schema cannot say so.
    accept = schema.config.checks.positive_data_acceptance
    accept.expected_statuses = [*accept.expected_statuses, "422"]
    # An If-Match made up by the tool matches no ETag: 412, as documented; error fits written
    # into a stored scene (write: true) need one: 428 without it, as documented.
    accept.expected_statuses = [*accept.expected_statuses, "412", "428"]
    # A missing If-Match is 428 Precondition Required (RFC 6585), as documented.
    missing = schema.config.checks.missing_required_header
    missing.expected_statuses = [*missing.expected_statuses, "428"]
    # A batch over the limit is refused as too large (413), as any oversized body is.
    refuse = schema.config.checks.negative_data_rejection
    refuse.expected_statuses = [*refuse.expected_statuses, "413"]
    return schema


@schema.parametrize()
@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,
)
def test_no_server_errors_and_responses_match_the_spec(case):
    """Every check schemathesis has, over every operation."""
    case.call_and_validate(headers=AUTH, timeout=120)


def test_health_answers_while_heavy_requests_run(live_api):
    """The event loop never computes: /health answers within 100 ms while a regions request
    of four 48-part trays, a plan with 5,000 Monte Carlo samples per stop and a 2,000-tray
    body are in flight. (Each sample checks TIAGo's 37 hand meshes exactly: 20,000 per stop
    outlast the server's 20 s deadline here.)"""
    import threading
    import time

    from .factories import many_parts, many_trays, paper

    with httpx.Client(base_url=live_api, timeout=120) as c:
        doc = many_parts(48, tray=(0, 1, 2, 3))
        sid = c.post("/api/v1/scenes", json=doc, headers=AUTH).json()["id"]
        done = threading.Event()
        answers: list[int] = []

        def heavy() -> None:
            with httpx.Client(base_url=live_api, timeout=120) as h:
                answers.append(h.get(f"/api/v1/scenes/{sid}/regions").status_code)
                seed = time.time_ns() % 2**31  # nothing cached
                plan = {"scene": paper(), "options": {"samples": 5000, "seed": seed},
                        "store": False}  # fmt: skip
                answers.append(h.post("/api/v1/plans", json=plan, headers=AUTH).status_code)
                big = many_trays(2000)
                answers.append(h.post("/api/v1/scenes", json=big, headers=AUTH).status_code)
            done.set()

        worker = threading.Thread(target=heavy)
        worker.start()
        latencies = []
        time.sleep(0.2)
        while not done.is_set() and len(latencies) < 2000:
            t0 = time.perf_counter()
            assert c.get("/api/v1/health").status_code == 200
            latencies.append(time.perf_counter() - t0)
            time.sleep(0.02)
        worker.join()
    assert answers == [200, 200, 413], answers
    latencies.sort()
    p50, top = latencies[len(latencies) // 2] * 1e3, latencies[-1] * 1e3
    print(f"/health during heavy requests: {len(latencies)} polls, p50 {p50:.1f} ms, "
          f"max {top:.1f} ms")  # fmt: skip
    assert len(latencies) >= 10
    assert latencies[int(len(latencies) * 0.95)] < 0.1, latencies[-10:]


def test_the_planner_client_deletes_with_its_etag(live_api, paper_doc):
    from pickstop_ui.client import ApiProblem, PickStopClient

    from .conftest import KEY

    client = PickStopClient(live_api, KEY)
    stored = client.create_scene(paper_doc)
    assert client.limits()["max_trays"] >= len(paper_doc["trays"])
    changed = client.save_scene(stored.id, {**paper_doc, "sigma": 0.05}, stored.etag)
    with pytest.raises(ApiProblem) as e:
        client.delete_scene(stored.id, stored.etag)  # stale
    assert e.value.status == 412
    client.delete_scene(stored.id, changed.etag)
    with pytest.raises(ApiProblem) as e:
        client.scene(stored.id)
    assert e.value.status == 404


def test_a_client_that_leaves_stops_its_computation(live_api):
    """A plan whose client disconnects is stopped and releases the planner: the next plan of
    the same robot is served at once, not after the abandoned one's Monte Carlo (20,000
    samples at each of the factory cell's six stops: half a minute here)."""
    import json
    import time

    from .factories import EXAMPLES

    cell = json.loads((EXAMPLES / "factory_cell.json").read_text())
    with httpx.Client(base_url=live_api, timeout=120) as c:
        quick = {"scene": cell, "options": {"samples": 0}, "store": False}
        assert c.post("/api/v1/plans", json=quick, headers=AUTH).status_code == 200  # warm
        time.sleep(3)  # let the background checks of the other candidates settle
        heavy = {"scene": cell, "store": False,
                 "options": {"samples": 20000, "seed": time.time_ns() % 2**31}}  # fmt: skip
        with pytest.raises(httpx.TimeoutException):
            c.post("/api/v1/plans", json=heavy, headers=AUTH, timeout=1.5)
        t0 = time.perf_counter()
        r = c.post("/api/v1/plans", json=quick, headers=AUTH)
        seconds = time.perf_counter() - t0
    assert r.status_code == 200, r.text
    assert seconds < 10.0, seconds


def test_health_answers_while_yaml_bodies_decode(live_api):
    """Three clients sending YAML robot configs at the size limit, and YAML nested deeper than
    a parser recurses, over and over: /health answers within 100 ms throughout (the YAML is
    decoded in child processes, never on the API's interpreter)."""
    import threading
    import time

    big = "name: big\nurdf: robot.urdf\narm_joints: [a]\ntool_frame: t\nlocked_joints:\n"
    big += "".join(f"  joint_{i}: {{x: [1, 2.5, true, null, 'q{i}']}}\n" for i in range(2050))
    nested = "a: " + "[" * 45_000 + "]" * 45_000 + "\n"
    with httpx.Client(base_url=live_api, timeout=60) as c:
        limit = c.get("/api/v1/limits").json()["max_yaml_bytes"]
    assert limit - 5000 < len(big) <= limit and len(nested) <= limit
    headers = {**AUTH, "Content-Type": "application/yaml"}
    stop = threading.Event()
    answers: list[int] = []

    def send(body: str) -> None:
        with httpx.Client(base_url=live_api, timeout=60) as h:
            while not stop.is_set():
                answers.append(h.post("/api/v1/robots", content=body, headers=headers).status_code)

    senders = [threading.Thread(target=send, args=(b,)) for b in (big, big, nested)]
    for t in senders:
        t.start()
    latencies = []
    with httpx.Client(base_url=live_api, timeout=30) as c:
        t_end = time.monotonic() + 8.0
        while time.monotonic() < t_end:
            t0 = time.perf_counter()
            assert c.get("/api/v1/health").status_code == 200
            latencies.append(time.perf_counter() - t0)
            time.sleep(0.01)
    stop.set()
    for t in senders:
        t.join()
    latencies.sort()
    p99, top = latencies[int(len(latencies) * 0.99)] * 1e3, latencies[-1] * 1e3
    print(f"/health during YAML bodies: {len(latencies)} polls, {len(answers)} YAML requests "
          f"{sorted(set(answers))}, p99 {p99:.1f} ms, max {top:.1f} ms")  # fmt: skip
    assert set(answers) == {422} and len(answers) >= 6
    assert p99 < 100.0, latencies[-10:]
