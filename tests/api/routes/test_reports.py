"""/plans/{id}/report and /plans/{id}/stops.csv: a stored plan as HTML and CSV, 404 otherwise."""

from __future__ import annotations

import csv
import io

from ..conftest import AUTH
from ..factories import paper, problem


def test_a_stored_plans_report_and_csv(client):
    r = client.post("/api/v1/plans", json={"scene": paper(), "options": {"samples": 40}},
                    headers=AUTH)  # fmt: skip
    assert r.status_code == 201, r.text
    rec = r.json()
    pid, plan = rec["id"], rec["plan"]
    html = client.get(f"/api/v1/plans/{pid}/report")
    assert html.status_code == 200 and html.headers["content-type"].startswith("text/html")
    assert "<svg" in html.text and html.text.count("<tr class='stop'>") == len(plan["stops"])
    assert pid in html.text
    got = client.get(f"/api/v1/plans/{pid}/stops.csv")
    assert got.status_code == 200 and got.headers["content-type"].startswith("text/csv")
    assert "attachment" in got.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(got.text)))
    assert [r["trays"].split(";") for r in rows] == [s["trays"] for s in plan["stops"]]


def test_an_unknown_plan_is_404_for_both(client):
    for tail in ("report", "stops.csv"):
        problem(client.get(f"/api/v1/plans/pln_nope/{tail}"), 404, "plan_id")
