"""*Suggest layout* in the browser: a quick search for tray_4 (step 0.2 m, no turns, shortlist
3, no Monte Carlo) shows the best suggestion as a ghost with its gain; Accept applies its moved
scene as one step, and Ctrl+Z puts the layout back exactly."""

from __future__ import annotations

import copy

import pytest

from tests.ui import browser as b

pytestmark = b.needs_chromium


def test_a_suggestion_is_shown_accepted_as_one_step_and_undone(pg, app):
    b.settled(app)
    before = copy.deepcopy(app.state.doc)
    b.click_item(pg, app, "trays", "tray_4")
    s = app.suggest
    s.step.value, s.turns.value, s.shortlist.value, s.samples.value = 0.2, "0", 3, 0
    pg.get_by_role("button", name="Suggest layout").click()
    b.wait_for(lambda: not s.ask_btn.disabled and s.job_id is None and s.text.content
               and not s.text.content.startswith("⏳"), 240, "the search")  # fmt: skip
    assert s.layout is not None, s.text.content
    assert "Suggested layout" in s.text.content and "Time:" in s.text.content
    b.wait_for(lambda: "Suggested layout" in pg.inner_text("body"), 10, "the gain in the panel")
    ghost = b.node_position(pg, "/suggestion/tray_4")
    assert ghost is not None
    moved = next(t for t in s.layout["suggestions"][0]["scene"]["trays"] if t["id"] == "tray_4")
    assert ghost[:2] == pytest.approx([moved["pose"]["x"], moved["pose"]["y"]], abs=1e-6)
    assert 3.40 - 1e-9 <= moved["pose"]["x"] <= 3.80 + 1e-9  # it still stands on table B
    pg.get_by_role("button", name="Accept").click()
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"] == moved["pose"], 15, "the accept")
    assert app.state.history.undo_label.startswith("layout tray_4")
    b.wait_for(lambda: not pg.evaluate(
        "n => window.__viserMutable.nodeRefFromName[n].visible", "/suggestion/tray_4"),
        10, "the ghost to go")  # fmt: skip
    b.settled(app)
    pg.mouse.move(200, 700)
    pg.keyboard.press("Control+z")
    b.wait_for(lambda: app.state.doc == before, 15, "Ctrl+Z to restore the layout")
    assert app.state.history.redo_label.startswith("layout tray_4")
    b.settled(app)
