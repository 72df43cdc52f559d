"""The plan document (sequence/plan_model.py)."""

from __future__ import annotations

import json

from pickstop.sequence.plan_model import Plan


def test_plan_document_round_trips(paper_plan):
    _, plan = paper_plan
    doc = json.loads(json.dumps(plan.model_dump(mode="json")))
    assert Plan.model_validate(doc) == plan
    assert doc["format"] == "pickstop.plan" and doc["database"]
