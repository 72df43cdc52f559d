"""Fixtures of the stop-planning tests: a stop planner per module over the session's regions,
the paper scene and its plan."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pickstop.scene.load import parse_scene
from pickstop.sequence.plan_model import PlanOptions
from pickstop.speedups.stop_planner import StopPlanner

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"


@pytest.fixture(scope="module")
def stop_planner(planner):
    return StopPlanner(planner)


@pytest.fixture()
def paper_doc():
    return json.loads((EXAMPLES / "paper_experiment.json").read_text())


@pytest.fixture(scope="module")
def paper_plan(stop_planner):
    scene = parse_scene(json.loads((EXAMPLES / "paper_experiment.json").read_text()))
    return scene, stop_planner.plan(scene, PlanOptions(samples=300))
