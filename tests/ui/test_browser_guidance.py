"""Placement guidance in the browser: selecting tray_4 draws its zones on the supports (with
the legend), dropping it after a drag asks for them anew, and Esc removes them."""

from __future__ import annotations

import time

import numpy as np

from tests.ui import browser as b

pytestmark = b.needs_chromium

VISIBLE = """n => { const o = window.__viserMutable.nodeRefFromName[n];
                    return o ? o.visible : null; }"""


def _drawn(pg, app):
    """The kinds of zone whose node the browser holds and shows."""
    return {k for k in app.guidance.nodes if pg.evaluate(VISIBLE, f"/guidance/{k}")}


def test_selecting_a_tray_draws_its_zones_and_esc_removes_them(pg, app):
    b.settled(app)
    assert not app.guidance.nodes
    t0 = time.perf_counter()
    b.click_item(pg, app, "trays", "tray_4")
    b.wait_for(lambda: _drawn(pg, app), 30, "the zones' nodes in the browser")
    ms = (time.perf_counter() - t0) * 1e3
    print(f"\ntray_4 clicked -> zones in the browser: {ms:.0f} ms "
          f"(selected -> drawn: {app.guidance_ms:.0f} ms)")  # fmt: skip
    b.wait_for(lambda: "Guidance for tray_4" in pg.inner_text("body"), 10, "the legend")
    assert "shares" in app.guidance.nodes
    v = np.asarray(app.guidance.nodes["shares"].vertices)
    z = b.tray(app, "tray_4")["pose"]["z"]
    assert np.allclose(v[:, 2], z, atol=0.01)  # on table B's top
    # The zone tray_4 stands in now holds its centre.
    here = app.guidance_md.content.split("now: *")[1].split("*")[0]
    assert here in ("shares", "own")
    pg.mouse.move(200, 700)
    pg.keyboard.press("Escape")
    b.wait_for(lambda: app.selection.key is None, 10, "Esc to deselect")
    b.wait_for(lambda: not _drawn(pg, app), 10, "the zones to go")
    assert "Guidance for" not in app.guidance_md.content


def test_dropping_the_tray_after_a_drag_asks_for_its_zones_anew(pg, app):
    b.reset_camera(app)
    t = b.tray(app, "tray_4")
    base = np.array([t["pose"]["x"], t["pose"]["y"], t["pose"]["z"]])
    a, end = b.grab_x_arrow(pg, app, "tray_4", base, 0.1)  # within table B (x up to 3.80)
    b.wait_for(lambda: _drawn(pg, app), 30, "the zones on selecting")
    seq = app.guide.seq
    b.drag(pg, a, end)
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"]["x"] > base[0] + 0.05, 15, "the drag")
    assert b.tray(app, "tray_4")["pose"]["x"] <= 3.80 + 1e-9
    b.wait_for(lambda: app.guide.seq > seq, 10, "a new guidance request")
    b.wait_for(lambda: _drawn(pg, app) and "Guidance for tray_4" in app.guidance_md.content,
               30, "the zones after the drop")  # fmt: skip
    b.settled(app)
