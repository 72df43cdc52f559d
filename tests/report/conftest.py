"""The paper-like scene's plan with success rates, computed once per session for the report
tests."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

SCENES = Path(__file__).parents[2] / "examples" / "scenes"


@pytest.fixture(scope="session")
def paper_scene():
    return json.loads((SCENES / "paper_experiment.json").read_text())


@pytest.fixture(scope="session")
def paper_plan(planner, paper_scene):
    from pickstop.scene.load import parse_scene
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.speedups.stop_planner import StopPlanner

    return StopPlanner(planner).plan(parse_scene(paper_scene), PlanOptions(samples=60))
