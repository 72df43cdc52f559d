"""/databases: every build parameter checked before the job is queued."""

from __future__ import annotations

import pytest

from ..conftest import AUTH
from ..factories import problem


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
