"""Plans of the paper-like scene for the planner's pure views (exact, and a preview of it
with tray_1 moved 0.1 m), computed once per session; and for the browser tests, a planner of
the paper-like scene with a headless Chromium page on it, one per module (a module planning
another scene overrides ``app``)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture(scope="session")
def plans(planner):
    from pickstop.scene.load import parse_scene
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.speedups.stop_planner import StopPlanner

    doc = json.loads(SCENE.read_text())
    sp = StopPlanner(planner)
    exact = sp.plan(parse_scene(doc), PlanOptions(samples=0))
    moved = copy.deepcopy(doc)
    moved["trays"][0]["pose"]["x"] -= 0.1
    return exact, sp.preview(parse_scene(moved), PlanOptions(samples=0))


@pytest.fixture(scope="module")
def app(live_api):
    from tests.ui import browser as b

    with b.planner(live_api) as app:
        yield app


@pytest.fixture(scope="module")
def pg(app):
    from tests.ui import browser as b

    with b.page(app) as pg:
        yield pg
