"""Trays stand on something, in the browser: a tray dragged from table A onto the lower
table B follows its top, one dragged off the floor is drawn red with the reason and nothing
is planned, and Ctrl+Z puts it back standing and planned."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from pickstop_ui.resting import INVALID
from tests.ui import browser as b

pytestmark = b.needs_chromium


@pytest.fixture(scope="module")
def app(live_api, tmp_path_factory):
    """The paper-like scene with table B lower (0.60 m) and longer, tray_4 at its far end,
    and the floor ending at the tables' back edge (y 1.95 m): beyond it nothing carries a
    tray."""
    doc = json.loads(b.PAPER.read_text())
    table_b = next(o for o in doc["obstacles"] if o["id"] == "table_b")
    table_b["geometry"]["size"] = [1.4, 0.6, 0.6]
    table_b["pose"]["x"] = 3.9
    tray_4 = next(t for t in doc["trays"] if t["id"] == "tray_4")
    tray_4["pose"].update(x=4.3, z=0.605)
    doc["floor"]["max"][1] = 1.95
    path = tmp_path_factory.mktemp("supports") / "lower_table.json"
    path.write_text(json.dumps(doc))
    with b.planner(live_api, path) as app:
        yield app


def _pull(pg, app, tid: str, axis: int, d: float) -> None:
    """Select tray ``tid`` and pull its gizmo's arrow along ``axis`` (0: x, 1: y) by ``d`` [m]
    with real mouse events."""
    if app.selection.key != ("trays", tid):
        b.click_item(pg, app, "trays", tid)
    pose = b.tray(app, tid)["pose"]
    base = np.array([pose["x"], pose["y"], pose["z"]])
    unit = np.eye(3)[axis]
    cam = b.camera(app)
    for frac in (0.55, 0.45, 0.35, 0.28):  # the arrow's end may lie under the panel
        grab = frac * b.gizmo_length(app, base)
        a = b.project(cam, base + grab * unit)
        if a[0] < 820:
            break
    b.drag(pg, a, b.project(cam, base + (grab + d) * unit), steps=16)


def _committed(app, tid: str) -> dict:
    """Tray ``tid``'s pose in the history's newest step (a drag under way is not in it)."""
    return next(t["pose"] for t in app.state.history.doc()["trays"] if t["id"] == tid)


def _drawn(pg, name: str) -> list[float]:
    return b.node_position(pg, name) or [np.nan] * 3


def test_a_tray_follows_the_table_under_it_and_off_the_floor_it_is_drawn_invalid(pg, app):
    b.settled(app)
    assert b.tray(app, "tray_3")["pose"]["z"] == pytest.approx(0.725)
    # Onto the lower table B: its height follows the table's top.
    seq = app.state.seq
    _pull(pg, app, "tray_3", 0, 1.7)
    b.wait_for(lambda: b.tray(app, "tray_3")["pose"]["x"] > 3.3
               and app.state.history.undo_label == "move tray_3", what="the drag")  # fmt: skip
    on_b = dict(b.tray(app, "tray_3")["pose"])
    assert on_b["z"] == pytest.approx(0.605) and not app.standing.problems
    b.wait_for(lambda: abs(_drawn(pg, "/trays/tray_3")[2] - 0.605) < 1e-6, 10, "the node")
    b.settled(app, since=seq)
    b.ready(pg)
    assert "Support: table B (top 0.600 m)" in pg.inner_text("body")
    b.shot(pg, "supports-01-on-table-b")
    # Off the floor's back edge: nothing carries it. Drawn red, the reason said, no plan.
    _pull(pg, app, "tray_3", 1, 0.8)
    b.wait_for(lambda: app.standing.problems == {"tray_3": "nothing under it"}, 20, "invalid")
    b.wait_for(lambda: _committed(app, "tray_3")["y"] > 2.1, 20, "the release, one step")
    shapes = app.scene.items[("trays", "tray_3")].shapes
    assert all(tuple(h.color) == INVALID for h in shapes)
    b.wait_for(lambda: "⚠ tray_3: nothing under it" in pg.inner_text("body"), 10, "the label")
    body = pg.inner_text("body")
    assert "no plan — ⚠ tray_3: nothing under it" in body and "Status: ready" not in body
    plan, seq = app.state.plan, app.state.seq
    time.sleep(1.0)
    assert app.state.plan is plan and app.state.seq == seq  # the last plan stays greyed
    b.shot(pg, "supports-02-off-the-floor")
    # Ctrl+Z: back on table B, standing, and planned.
    pg.mouse.move(300, 700)
    seq = app.state.seq
    pg.keyboard.press("Control+z")
    b.wait_for(lambda: b.tray(app, "tray_3")["pose"] == on_b, what="the undo")
    b.wait_for(lambda: not app.standing.problems, 10, "it to stand")
    b.wait_for(lambda: all(tuple(h.color) != INVALID for h in shapes), 10, "its colours")
    b.settled(app, since=seq)
    b.ready(pg)
    assert "nothing under it" not in pg.inner_text("body") and app.state.plan.verified
    b.wait_for(lambda: abs(_drawn(pg, "/trays/tray_3")[1] - on_b["y"]) < 1e-6, 10, "the node")
    b.shot(pg, "supports-03-after-ctrl-z")
