"""The planner draws the scene's own robot, fetched from the API: here PR2, not TIAGo."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.conftest import LIVE_KEY, free_port
from tests.ui.test_planner_ui import ARGS, ARTIFACTS, CHROMIUM, SCENE

playwright = pytest.importorskip("playwright.sync_api")
pytestmark = pytest.mark.skipif(
    shutil.which("chromium") is None, reason="Debian's chromium is not installed"
)
PR2 = Path(__file__).parents[2] / "examples" / "robots" / "pr2.yaml"


@pytest.fixture(scope="module")
def pr2_app(live_api, region_db):
    from pickstop.reach.build import BuildParams
    from pickstop.robot.model import load
    from pickstop.store.reach_build import build
    from pickstop_ui.app import PlannerApp
    from pickstop_ui.client import PickStopClient

    folder, _ = region_db
    build(load(str(PR2)), BuildParams(samples=500_000, chunk_size=250_000, seed=5), folder)
    client = PickStopClient(live_api, LIVE_KEY)
    config = yaml.safe_load(PR2.read_text())
    r = client.http.post("/api/v1/robots", json=config)
    assert r.status_code == 201 or "already exists" in r.text, r.text
    doc = json.loads(SCENE.read_text())
    doc["robot"] = {"preset": "pr2"}
    doc["task"] = ["tray_2"]
    # At the table's edge: PR2's square base turns within a 0.47 m circle, which must reach
    # the stop from the start.
    doc["trays"][1]["pose"]["y"] = 1.4
    stored = client.create_scene(doc)
    app = PlannerApp(client, stored.id, port=free_port())
    yield app
    app.close()


def test_planner_draws_the_scene_robot_and_its_ghost_at_the_stop(pr2_app):
    app = pr2_app
    assert app.robot is not None and app.robot.name == "pr2"
    names = {h.name for h in app._robot._meshes}
    assert any("r_gripper_palm_link" in n for n in names)
    assert not any("hand_palm_link" in n for n in names)  # not TIAGo
    # The ghost at the stop shows PR2 with the witness arm and the open gripper.
    end = time.monotonic() + 180
    while app.state.plan is None or not app.layer.ghosts:
        assert time.monotonic() < end and app.state.error is None, f"no plan: {app.state.error}"
        time.sleep(0.2)
    plan = app.state.plan
    frame, ghost = app.layer.ghosts[0]
    assert np.allclose(frame.position[:2], (plan.stops[0].x, plan.stops[0].y))
    cfg = dict(zip(ghost.get_actuated_joint_names(), ghost._urdf.cfg, strict=False))
    w = plan.stops[0].witnesses[0]
    for name, value in zip(plan.joints, w.theta, strict=True):
        if name in cfg and "roll" not in name:
            assert cfg[name] == pytest.approx(value, abs=1e-6)
    assert cfg["r_gripper_l_finger_joint"] == pytest.approx(0.3)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    with playwright.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        pg = browser.new_page(viewport={"width": 1280, "height": 800})
        pg.goto(f"http://127.0.0.1:{app.port}/")
        pg.wait_for_function("document.body.innerText.includes('Status: ready')", timeout=120_000)
        time.sleep(2)
        assert "Stops: 1" in pg.inner_text("body")
        pg.screenshot(path=str(ARTIFACTS / "pr2.png"))
        browser.close()
