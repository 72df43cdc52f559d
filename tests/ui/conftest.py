"""Plans of the paper-like scene for the planner's pure views (exact, and a preview of it
with tray_1 moved 0.1 m), computed once per session."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture(scope="session")
def plans(planner):
    from pickstop.scene.load import parse_scene
    from pickstop.sequence.plan import StopPlanner
    from pickstop.sequence.plan_model import PlanOptions

    doc = json.loads(SCENE.read_text())
    sp = StopPlanner(planner)
    exact = sp.plan(parse_scene(doc), PlanOptions(samples=0))
    moved = copy.deepcopy(doc)
    moved["trays"][0]["pose"]["x"] -= 0.1
    return exact, sp.preview(parse_scene(moved), PlanOptions(samples=0))
