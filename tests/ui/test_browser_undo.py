"""Undo, redo and revert in the browser: a drag taken back with Ctrl+Z puts the tray where it
was to the bit, and the plan with it; a removed tray comes back."""

from __future__ import annotations

import numpy as np

from tests.ui import browser as b

pytestmark = b.needs_chromium


def _drag_tray(pg, app, tid: str, dx: float) -> None:
    """Grab the tray's gizmo x arrow and pull it ``dx`` [m] along x."""
    t = b.tray(app, tid)
    base = np.array([t["pose"]["x"], t["pose"]["y"], t["pose"]["z"]])
    a, end = b.grab_x_arrow(pg, app, tid, base, dx)
    b.drag(pg, a, end)


def test_ctrl_z_after_a_drag_puts_the_tray_and_the_plan_back_exactly(pg, app):
    b.settled(app)
    pose0 = dict(b.tray(app, "tray_4")["pose"])
    stops0, seq0 = b.stops(app.state.plan), app.state.seq
    _drag_tray(pg, app, "tray_4", 0.2)
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"]["x"] > pose0["x"] + 0.1, what="the drag")
    b.settled(app)
    b.ready(pg)
    assert b.stops(app.state.plan) != stops0 and app.state.history.undo_label == "move tray_4"
    assert "Undo move tray_4" in pg.inner_text("body")
    pg.mouse.move(300, 700)
    seq = app.state.seq
    pg.keyboard.press("Control+z")
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"] == pose0, what="the undo")
    b.settled(app, since=seq)
    b.ready(pg)
    assert app.state.seq > seq0 + 1 and app.state.plan.verified
    assert b.stops(app.state.plan) == stops0  # the plan as it was, stop for stop
    b.wait_for(lambda: abs(b.node_position(pg, "/trays/tray_4")[0] - pose0["x"]) < 1e-6, 10,
               "the browser")  # fmt: skip
    assert "Redo move tray_4" in pg.inner_text("body")
    b.shot(pg, "undo-01-after-ctrl-z")
    # Redo moves it again; Revert to saved takes it back as one more undoable step.
    pg.keyboard.press("Control+Shift+z")
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"]["x"] > pose0["x"] + 0.1, what="the redo")
    pg.get_by_role("button", name="Revert to saved").click()
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"] == pose0, what="the revert")
    assert app.state.history.undo_label == "revert to saved" and not app.state.history.dirty
    b.settled(app)


def test_a_removed_tray_comes_back_with_ctrl_z(pg, app):
    b.ready(pg)
    ids = [t["id"] for t in app.state.doc["trays"]]
    app._tray_ui["sel"].value = "tray_2"
    seq = app.state.seq
    pg.get_by_role("button", name="Remove", exact=True).click()
    b.wait_for(lambda: "tray_2" not in [t["id"] for t in app.state.doc["trays"]], what="remove")
    b.wait_for(lambda: b.node_position(pg, "/trays/tray_2") is None, 10, "the node to go")
    assert "Removed tray_2" in pg.inner_text("body")
    b.settled(app, since=seq)
    assert all("tray_2" not in s[3] for s in b.stops(app.state.plan))
    pg.mouse.move(300, 700)
    seq = app.state.seq
    pg.keyboard.press("Control+z")
    b.wait_for(lambda: [t["id"] for t in app.state.doc["trays"]] == ids, what="the undo")
    b.wait_for(lambda: b.node_position(pg, "/trays/tray_2") is not None, 10, "the node")
    b.settled(app, since=seq)
    assert any("tray_2" in s[3] for s in b.stops(app.state.plan))
    assert pg.get_by_label("needed: tray_2").is_checked()
