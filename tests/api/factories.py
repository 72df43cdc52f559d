"""Scene documents for the API tests: example scenes grown to hostile sizes."""

from __future__ import annotations

import copy
import json
import time
from pathlib import Path
from typing import Any

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


def paper() -> dict[str, Any]:
    return json.loads((EXAMPLES / "paper_experiment.json").read_text())


def many_trays(n: int) -> dict[str, Any]:
    """The paper scene with ``n`` trays (copies of its first, in a row)."""
    doc = paper()
    first = doc["trays"][0]
    doc["trays"] = [
        {**copy.deepcopy(first), "id": f"t{i}", "name": f"t{i}",
         "pose": {**first["pose"], "x": 0.4 * i}}
        for i in range(n)
    ]  # fmt: skip
    doc.pop("task", None)
    return doc


def many_parts(n: int, tray: int | tuple[int, ...] = 0) -> dict[str, Any]:
    """The paper scene with ``n`` small parts (a grid of 1 cm cubes) in each tray given."""
    doc = paper()
    for k in (tray,) if isinstance(tray, int) else tray:
        doc["trays"][k]["parts"] = [
            {"id": f"p{k}_{i}", "geometry": {"shape": "box", "size": [0.01, 0.01, 0.01]},
             "pose": {"x": -0.12 + 0.02 * (i % 13), "y": -0.08 + 0.02 * (i // 13 % 9), "z": 0}}
            for i in range(n)
        ]  # fmt: skip
    return doc


def many_obstacles(n: int) -> dict[str, Any]:
    doc = paper()
    doc["obstacles"] += [
        {"id": f"o{i}", "geometry": {"shape": "box", "size": [0.01, 0.01, 0.01]},
         "pose": {"x": 4.5, "y": -0.9 + i * 1e-4}}
        for i in range(n)
    ]  # fmt: skip
    return doc


def problem(resp: Any, status: int, field: str | None = None) -> dict[str, Any]:
    """Assert ``resp`` is a problem document of ``status`` (naming ``field``); return it."""
    assert resp.status_code == status, resp.text
    assert resp.headers["content-type"].startswith("application/problem+json")
    body = resp.json()
    assert body["status"] == status and body["detail"]
    if field is not None:
        assert body.get("field") == field, body
    return dict(body)


def titled_problem(resp, status, title=None):
    """Assert ``resp`` is a problem document of ``status`` (titled ``title``); return it."""
    assert resp.status_code == status, resp.text
    assert resp.headers["content-type"].startswith("application/problem+json")
    body = resp.json()
    assert body["status"] == status and body["type"].startswith("https://pickstop.dev/problems/")
    assert body["detail"]
    if title:
        assert body["title"] == title
    return body


def count(client, path):
    return len(client.get(path, params={"limit": 500}).json())


def wait_job(client, job_id, timeout=120):
    t0 = time.time()
    while time.time() - t0 < timeout:
        job = client.get(f"/api/v1/jobs/{job_id}").json()
        if job["state"] not in ("queued", "running"):
            return job
        time.sleep(0.2)
    raise AssertionError(f"job {job_id} still {job['state']}")
