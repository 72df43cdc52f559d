"""HTTP as clients expect it: 413 (chunked too), 415, 405 with Allow, 401 before the body,
and every 4xx naming its field or saying where in the body."""

from __future__ import annotations

import json

import pytest

from .conftest import AUTH
from .factories import paper, problem, titled_problem

SCENES = "/api/v1/scenes"
JSON = {"content-type": "application/json"}


def test_a_chunked_body_over_the_limit_is_413(client, api_settings):
    chunk = b" " * 65536

    def stream():
        yield b'{"name": "'
        for _ in range(api_settings.max_body_bytes // len(chunk) + 2):
            yield chunk
        yield b'"}'

    r = client.post(SCENES, content=stream(), headers={**AUTH, **JSON})
    assert "content-length" not in r.request.headers
    problem(r, 413, "body")


def test_a_body_that_is_not_json_is_415(client):
    r = client.post(SCENES, content=json.dumps(paper()), headers={**AUTH, "content-type":
                    "text/plain"})  # fmt: skip
    problem(r, 415, "Content-Type")
    problem(client.post(SCENES, data={"a": "b"}, headers=AUTH), 415, "Content-Type")


def test_a_wrong_method_is_405_with_allow(client):
    r = client.patch(SCENES, headers=AUTH)
    problem(r, 405)
    assert set(r.headers["allow"].replace(" ", "").split(",")) >= {"GET", "POST"}


def test_the_key_is_checked_before_the_body(client):
    r = client.post(SCENES, content=b"{not json", headers=JSON)
    body = problem(r, 401, "Authorization")
    assert "writes need" not in body["detail"]
    problem(client.post(SCENES, content=b"{not json", headers={**AUTH, **JSON}), 422, "body")


@pytest.mark.parametrize(
    ("raw", "where"),
    [
        (b'{"name": "x",}', "line 1 column 14"),
        (b'{"name": "\xff"}', "UTF-8 at byte 10"),
        (b"[" * 5000 + b"]" * 5000, "nested too deeply"),
        (b'{"trays": ' + b"[" * 990 + b"]" * 990 + b"}", "nested too deeply"),
        (b'{"sigma": ' + b"9" * 5000 + b"}", "5000 digits"),
    ],
)
def test_a_broken_body_names_body_and_where(client, raw, where):
    body = problem(client.post(SCENES, content=raw, headers={**AUTH, **JSON}), 422, "body")
    assert where in body["detail"], body["detail"]


def test_a_nan_is_reported_as_not_a_number(client):
    raw = json.dumps({**paper(), "sigma": float("nan")}).encode()
    body = problem(client.post(SCENES, content=raw, headers={**AUTH, **JSON}), 422, "sigma")
    assert "not a finite number" in body["detail"] and "<= 1" not in body["detail"]
    r = client.get(f"{SCENES}/scn_x/regions", params={"sigma": "NaN"})
    assert r.status_code in (404, 422)
    plan = {"scene": paper(), "options": {"sigma": 1e400}}
    raw = json.dumps(plan).replace("Infinity", "1e400").encode()
    problem(client.post("/api/v1/plans", content=raw, headers={**AUTH, **JSON}), 422,
            "options.sigma")  # fmt: skip


def test_unknown_paths_are_problems(client):
    titled_problem(client.get("/api/v1/plans/nope"), 404)
    titled_problem(client.get("/api/v1/nothing"), 404)
    titled_problem(client.get("/api/v1/scenes", params={"limit": 0}), 422)


def test_a_body_with_thousands_of_errors_lists_the_first_fifty(client):
    config = {"name": "many", "urdf": "x.urdf", "arm_joints": ["a"], "tool_frame": "t",
              "locked_joints": {f"j{i}": "not a number" for i in range(1000)}}  # fmt: skip
    body = problem(client.post("/api/v1/robots", json=config, headers=AUTH), 422)
    assert len(body["errors"]) == 50 and body["errors"][0]["field"].startswith("locked_joints.")
    assert "the first 50 are listed" in body["detail"]
    assert len(body["detail"]) < 2100
