"""Select, then edit, in the browser: no gizmo until a click selects, a pan over a table moves
nothing (over the selected tray's gizmo neither), the gizmo's large arrow moves the tray,
Esc and a click on empty floor deselect, and no gizmo is drawn into an exported PNG."""

from __future__ import annotations

import copy
import time

import numpy as np
import pytest

from tests.ui import browser as b

pytestmark = b.needs_chromium


def _poses(app):
    return copy.deepcopy([(o["id"], o["pose"]) for k in ("trays", "obstacles")
                          for o in app.state.doc[k]])  # fmt: skip


def test_nothing_carries_a_gizmo_until_a_click_selects(pg, app):
    assert app.selection.key is None and not app.selection.gizmo.visible
    assert b.node_position(pg, "/trays/tray_4") is not None
    assert "Nothing selected" in pg.inner_text("body")


def test_a_pan_over_an_unselected_table_moves_nothing(pg, app):
    b.settled(app)
    before, cam0 = _poses(app), np.array(b.camera(app).position)
    table = next(o for o in app.state.doc["obstacles"] if o["id"] == "table_a")
    top = (table["pose"]["x"], table["pose"]["y"] + 0.25, table["geometry"]["size"][2])
    a = b.project(b.camera(app), top)
    for button in ("right", "left", "middle"):  # pan, orbit, dolly: none grabs the table
        b.drag(pg, a, (a[0] + 120, a[1] + 40), button=button)
        time.sleep(0.3)
    b.wait_for(lambda: not np.allclose(b.camera(app).position, cam0), 5, "the camera to move")
    assert _poses(app) == before and app.state.history.undo_label is None
    assert app.selection.key is None


def test_click_selects_and_only_a_left_drag_of_the_gizmo_moves_the_tray(pg, app):
    b.settled(app)
    b.reset_camera(app)
    b.click_item(pg, app, "trays", "tray_4")
    assert app.selection.gizmo.visible
    b.wait_for(lambda: "Selected: tray_4 (tray)" in pg.inner_text("body"), 10, "the panel")
    assert np.allclose(app.selection.gizmo.position[:2], [3.6, 1.5])
    b.wait_for(lambda: b.node_position(pg, "/helpers/gizmo") is not None, 10, "the gizmo")
    t = b.tray(app, "tray_4")
    base = np.array([t["pose"]["x"], t["pose"]["y"], t["pose"]["z"]])
    a, end = b.grab_x_arrow(pg, app, "tray_4", base, 0.2)
    before = _poses(app)
    b.drag(pg, a, (a[0] - 80, a[1]), button="right")  # a pan that starts on the gizmo's arrow
    time.sleep(1.0)
    assert _poses(app) == before, "a right-drag over the gizmo moved the tray"
    a, end = b.grab_x_arrow(pg, app, "tray_4", base, 0.2)  # the camera moved: aim anew
    b.drag(pg, a, end)
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"]["x"] > 3.7, 15, "the drag")
    assert b.tray(app, "tray_4")["pose"]["y"] == pytest.approx(1.5)
    b.settled(app)
    assert app.state.history.undo_label == "move tray_4"
    # The item's node follows the gizmo in the browser.
    x = b.tray(app, "tray_4")["pose"]["x"]
    b.wait_for(lambda: abs(b.node_position(pg, "/trays/tray_4")[0] - x) < 1e-6, 10, "the node")


def test_esc_and_a_click_on_empty_floor_deselect(pg, app):
    b.reset_camera(app)
    if app.selection.key is None:
        b.click_item(pg, app, "trays", "tray_4")
    pg.mouse.move(200, 700)
    pg.keyboard.press("Escape")
    b.wait_for(lambda: app.selection.key is None, 10, "Esc to deselect")
    assert not app.selection.gizmo.visible
    b.click_item(pg, app, "obstacles", "table_b")
    assert app.selection.key == ("obstacles", "table_b")
    floor = b.project(b.camera(app), (0.5, -0.8, 0.0))
    pg.mouse.click(*floor)
    b.wait_for(lambda: app.selection.key is None, 10, "a floor click to deselect")


def test_the_png_export_is_rendered_without_the_gizmo(pg, app, monkeypatch):
    import viser

    b.click_item(pg, app, "trays", "tray_1")
    seen = []
    render = viser.ClientHandle.get_render

    def spy(self, *args, **kwargs):
        seen.append(app.selection.gizmo.visible)
        return render(self, *args, **kwargs)

    monkeypatch.setattr(viser.ClientHandle, "get_render", spy)
    with pg.expect_download(timeout=60_000) as dl:
        pg.get_by_role("button", name="Download PNG snapshot").click()
    assert dl.value.suggested_filename.endswith(".png")
    assert seen == [False] and app.selection.gizmo.visible  # hidden for the render only
