"""Plans of the example scenes (session database), a live Mosquitto on loopback."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).parents[2] / "examples" / "scenes"
SCENES = ["paper_experiment", "five_trays", "factory_cell", "rack_cell"]


def scene_of(name: str):
    from pickstop.scene.load import parse_scene

    return parse_scene(json.loads((EXAMPLES / f"{name}.json").read_text()))


@pytest.fixture(scope="session")
def fleet_stop_planner(planner):
    from pickstop.speedups.stop_planner import StopPlanner

    return StopPlanner(planner)


@pytest.fixture(scope="session")
def example_plans(fleet_stop_planner):
    """``name -> (scene, plan)`` at sigma 0.10 (the paper's rule), 300 samples per stop."""
    from pickstop.sequence.plan_model import PlanOptions

    out = {}
    for name in SCENES:
        scene = scene_of(name)
        out[name] = (scene, fleet_stop_planner.plan(scene, PlanOptions(sigma=0.10, samples=300)))
    return out


@pytest.fixture()
def mosquitto():
    """A Mosquitto of its own on a free 127.0.0.1 port, stopped after the test."""
    from pickstop.fleet.broker import LocalMosquitto, mosquitto_path

    try:
        mosquitto_path()
    except Exception:
        if shutil.which("mosquitto") is None:
            pytest.fail("mosquitto is not installed (apt-get install mosquitto)")
    with LocalMosquitto() as m:
        yield m
