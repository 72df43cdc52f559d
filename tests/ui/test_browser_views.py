"""Views in the browser: each preset, and the top view above all, shows the whole scene in
the part of the view the panel leaves free (the paper-like scene and the factory cell)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pickstop_ui.views import _corners, scene_bounds
from tests.ui import browser as b

pytestmark = b.needs_chromium


@pytest.fixture(scope="module", params=["paper_experiment", "factory_cell"])
def app(live_api, request):
    with b.planner(live_api, b.SCENES / f"{request.param}.json") as app:
        yield app


def _panel_left(pg) -> float:
    box = pg.locator('[data-testid="floating-panel"]').first.bounding_box()
    return float(box["x"])


def _inside(pg, app) -> np.ndarray:
    """The scene's bounding box corners on the page [px] as the browser's camera sees them."""
    cam = b.camera(app)
    lo, hi = scene_bounds(app.state.doc)
    return np.array([b.project(cam, p) for p in _corners(lo, hi)])


@pytest.mark.parametrize("button", ["Top", "Front", "Iso", "Fit all"])
def test_each_view_shows_the_whole_scene_beside_the_panel(pg, app, button):
    b.settled(app)
    b.wait_for(lambda: bool(app.viewports), 10, "the page's layout")
    before = np.array(b.camera(app).position)
    pg.get_by_role("button", name=button, exact=True).click()
    time.sleep(1.5)
    if button != "Fit all":
        assert not np.allclose(b.camera(app).position, before) or button == "Iso"
    px = _inside(pg, app)
    left = _panel_left(pg)
    assert px[:, 0].min() >= 0 and px[:, 0].max() <= left, (px, left)
    assert px[:, 1].min() >= 0 and px[:, 1].max() <= b.SIZE[1]
    name = app.state.doc.get("name", "scene").replace(" ", "-")
    b.shot(pg, f"views-{name}-{button.replace(' ', '-').lower()}")


def test_the_top_view_looks_straight_down(pg, app):
    pg.get_by_role("button", name="Top", exact=True).click()
    time.sleep(1.5)
    cam = b.camera(app)
    d = np.asarray(cam.look_at) - np.asarray(cam.position)
    assert d[2] / np.linalg.norm(d) < -0.999
    # The goal, under the panel in the old first view, is in the free part.
    goal = app.state.doc["goal"]
    gx, gy = b.project(cam, (goal["x"], goal["y"], 0.0))
    assert 0 < gx < _panel_left(pg) and 0 < gy < b.SIZE[1]
