"""Camera presets: every one frames the whole scene in the view's free part, beside the panel."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from pickstop_ui.views import (
    MARGIN,
    PRESETS,
    Viewport,
    _corners,
    preset,
    project,
    project_depth,
    scene_bounds,
)

SCENES = sorted((Path(__file__).parents[2] / "examples" / "scenes").glob("*.json"))


def _framed(doc, pose, vp):
    lo, hi = scene_bounds(doc)
    px, depth = project_depth(pose, vp, _corners(lo, hi))
    assert np.all(depth > 0)
    return px


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
@pytest.mark.parametrize("name", PRESETS)
def test_each_preset_shows_the_whole_scene_beside_the_panel(path, name):
    doc = json.loads(path.read_text())
    vp = Viewport.default()
    px = _framed(doc, preset(name, doc, vp), vp)
    (x0, y0), (x1, y1) = px.min(axis=0), px.max(axis=0)
    assert x0 >= MARGIN - 1 and x1 <= vp.free_right - MARGIN + 1
    assert y0 >= MARGIN - 1 and y1 <= vp.height - MARGIN + 1
    # Tight: the scene fills the free part along one of its sides.
    assert (x1 - x0) >= vp.free_right - 2 * MARGIN - 2 or (y1 - y0) >= vp.height - 2 * MARGIN - 2


@settings(max_examples=150, deadline=None)
@given(st.floats(600, 2600), st.floats(400, 1600), st.floats(0.4, 1.0),
       st.sampled_from(PRESETS), st.sampled_from(SCENES))  # fmt: skip
@example(1287.0, 400.0, 0.9375, "front", SCENES[0].with_name("paper_experiment.json"))
def test_any_window_and_panel_width_frames_the_scene(w, h, free, name, path):
    doc = json.loads(path.read_text())
    vp = Viewport(w, h, free * w)
    px = _framed(doc, preset(name, doc, vp), vp)
    assert px[:, 0].min() >= MARGIN - 1 and px[:, 0].max() <= vp.free_right - MARGIN + 1
    assert px[:, 1].min() >= MARGIN - 1 and px[:, 1].max() <= h - MARGIN + 1


def test_the_top_view_looks_straight_down_with_y_up_on_screen():
    doc = json.loads(SCENES[0].read_text())
    vp = Viewport.default()
    pose = preset("top", doc, vp)
    d = np.asarray(pose.look_at) - np.asarray(pose.position)
    assert d[2] / np.linalg.norm(d) < -0.999  # within 2.6 degrees of straight down
    a, b, c = project(pose, vp, np.array([[1.0, 1.0, 0.0], [1.0, 2.0, 0.0], [2.0, 1.0, 0.0]]))
    assert b[1] < a[1] - 10 and abs(b[0] - a[0]) < 2  # +y is up
    assert c[0] > a[0] + 10 and abs(c[1] - a[1]) < 2  # +x is right
    # Nearly orthographic: a pillar's top and foot land within a few pixels.
    foot, top = project(pose, vp, np.array([[2.4, 0.2, 0.0], [2.4, 0.2, 3.0]]))
    assert math.dist(foot, top) < 0.05 * vp.height


def test_fit_keeps_the_viewing_direction_and_a_bad_name_is_refused():
    doc = json.loads(SCENES[0].read_text())
    vp = Viewport.default()
    look = np.array([1.0, 2.0, -1.0])
    pose = preset("fit", doc, vp, look)
    d = np.asarray(pose.look_at) - np.asarray(pose.position)
    assert np.allclose(d / np.linalg.norm(d), look / np.linalg.norm(look))
    with pytest.raises(ValueError, match="no view preset 'side'"):
        preset("side", doc, vp)
