"""The planner's drawings as pure functions of a plan (no browser), and its document edits."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from pickstop.scene.load import parse_scene
from pickstop.sequence.plan import StopPlanner
from pickstop.sequence.plan_model import PlanOptions
from pickstop_ui import edits
from pickstop_ui.plan_view import PREVIEW, STALE, VERIFIED, plan_drawing, style_of

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"


@pytest.fixture(scope="module")
def plans(planner):
    doc = json.loads(SCENE.read_text())
    sp = StopPlanner(planner)
    exact = sp.plan(parse_scene(doc), PlanOptions(samples=0))
    moved = copy.deepcopy(doc)
    moved["trays"][0]["pose"]["x"] -= 0.1
    return exact, sp.preview(parse_scene(moved), PlanOptions(samples=0))


def test_a_verified_plan_is_drawn_with_its_regions_route_and_ghosts(plans):
    exact, _ = plans
    assert style_of(exact) is VERIFIED and style_of(exact, stale=True) is STALE
    joints = [*exact.joints, "gripper_left_finger_joint"]
    d = plan_drawing(
        exact, {"tray_1": (1, 2, 3)}, VERIFIED, joints, {"gripper_left_finger_joint": 0.04}
    )
    assert set(d.regions) == set(exact.trays) and d.regions["tray_1"][2] == (1, 2, 3)
    assert all(len(f) > 0 for _, f, _ in d.regions.values())
    assert d.route.shape[1:] == (2, 3) and len(d.route) > 2
    assert len(d.centres) == len(exact.candidates) == len(d.centre_colours)
    assert len(d.ghosts) == len(exact.stops) and all(g.cfg is not None for g in d.ghosts)
    w = exact.stops[0].witnesses[0]
    np.testing.assert_allclose(d.ghosts[0].cfg[: len(exact.joints)], w.theta)
    assert d.ghosts[0].cfg[-1] == pytest.approx((w.hand or {}).get(joints[-1], 0.04))
    assert all("(preview)" not in text for text, _ in d.labels)


def test_a_preview_is_drawn_as_one_dashed_lighter_and_without_robots(plans):
    _, preview = plans
    assert not preview.verified and style_of(preview) is PREVIEW
    d = plan_drawing(preview, {}, style_of(preview), list(preview.joints), {})
    full = plan_drawing(preview, {}, VERIFIED, list(preview.joints), {})
    assert PREVIEW.route != VERIFIED.route and PREVIEW.kept != VERIFIED.kept
    assert PREVIEW.region_opacity < VERIFIED.region_opacity and not PREVIEW.ghosts
    # Dashed: the route is cut into pieces, half of its length drawn.
    length = lambda s: float(np.linalg.norm(s[:, 1] - s[:, 0], axis=1).sum())  # noqa: E731
    assert 0.3 * length(full.route) < length(d.route) < 0.7 * length(full.route)
    assert all(g.cfg is None for g in d.ghosts)  # no witnesses in a preview
    assert d.labels and all(text.endswith("(preview)") for text, _ in d.labels)


def test_a_dragged_tray_moves_in_whole_base_cells():
    doc = json.loads(SCENE.read_text())
    x0, y0 = doc["trays"][0]["pose"]["x"], doc["trays"][0]["pose"]["y"]
    pose = edits.move(doc, "trays", doc["trays"][0]["id"], x0 + 0.061, y0 - 0.013, 0.2)
    assert pose is not None
    assert pose["x"] == pytest.approx(x0 + 0.05) and pose["y"] == pytest.approx(y0 - 0.025)
    assert pose["yaw"] == 0.2 and doc["trays"][0]["pose"]["x"] == pose["x"]
    assert edits.move(doc, "trays", "nope", 0, 0, 0) is None
    ob = doc["obstacles"][0]["id"] if doc.get("obstacles") else None
    if ob is not None:  # obstacles move freely
        assert edits.move(doc, "obstacles", ob, 1.2345, 0.5, 0.0)["x"] == 1.2345
