"""Clarity in the browser: a rename shows in the 3D label, the stop labels and the stops list;
hovering a rejected circle names its trays and the reason; the status speaks plainly; an
impossible sigma states the largest that plans; labels of the factory cell never overlap."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from pickstop_ui.declutter import label_box
from pickstop_ui.picking import item_box, pick
from tests.ui import browser as b

pytestmark = b.needs_chromium


def _scene_text(pg, name: str) -> str | None:
    """The text of label node ``name`` as the browser's scene tree holds it."""
    return pg.evaluate(
        """n => { const s = window.__viserSceneTree.getState()[n];
                  return s && s.message ? s.message.props.text : null; }""",
        name,
    )


def test_a_rename_shows_in_the_3d_label_the_stop_labels_and_the_stops_list(pg, app):
    b.settled(app)
    app._tray_ui["sel"].value = "tray_4"
    # The text field's label names no input (viser's text field has its own id): its row's.
    name = pg.locator("xpath=//label[normalize-space(.)='name']/ancestor::div[.//input][1]"
                      "//input").first  # fmt: skip
    # The selection's name reaches the page in a message of its own: typing before it came
    # would be overwritten by it.
    b.wait_for(lambda: name.input_value() == app._tray_name("tray_4") == "tray_4", 10,
               "the selected tray's name on the page")  # fmt: skip
    name.fill("brackets B-12")
    b.wait_for(lambda: app._tray_ui["name"].value == "brackets B-12", 10, "the typed name")
    seq = app.state.seq
    pg.get_by_role("button", name="Rename", exact=True).click()
    b.wait_for(lambda: b.tray(app, "tray_4").get("name") == "brackets B-12", 10, "the rename")
    b.settled(app, since=seq)
    b.wait_for(lambda: _scene_text(pg, "/trays/tray_4/label") == "brackets B-12", 10, "3D label")
    stop = next(s for s in app.state.plan.stops if "tray_4" in s.trays)
    labels = [h.text for _, h in app.layer.labels()]
    assert any(t.startswith(f"stop {stop.index + 1}: ") and "brackets B-12" in t for t in labels)
    text = pg.inner_text("body")
    assert "brackets B-12" in text.split("Stops")[-1]  # the stops list
    assert "needed: brackets B-12 (tray_4)" in text
    assert app.state.history.undo_label == "rename tray_4"


def test_the_status_speaks_plainly(pg, app):
    b.settled(app)
    b.ready(pg)  # the page follows the planner a moment later
    n, t = len(app.state.plan.stops), len(app.state.plan.trays)
    text = pg.inner_text("body")
    assert f"Status: ready — {n} stops cover {t} trays" in text


def _reachable_on_screen(app, x: float, y: float) -> bool:
    """The floor point (x, y) is seen, left of the panel, and no item hides it."""
    cam = b.camera(app)
    px = b.project(cam, (x, y, 0.0))
    if not (20 < px[0] < 800 and 20 < px[1] < 780):
        return False
    boxes = [x for x in map(item_box, app.scene.drawn_items()) if x is not None]
    return pick(boxes, *b.ray_at(cam, px)) is None


def test_hovering_a_rejected_circle_names_its_trays_and_reason(pg, app):
    # Raise sigma just above a shared stop's circle: that candidate is rejected.
    plan = app.state.plan
    shared = min(s.inscribed_radius for s in plan.stops if len(s.trays) >= 2)
    app.sigma.value = math.ceil((shared + 1e-3) / 0.005) * 0.005
    b.wait_for(lambda: app.state.plan.parameters.sigma == app.sigma.value, 60, "the replan")
    b.settled(app)
    plan = app.state.plan
    centres = np.array([[c.x, c.y] for c in plan.candidates])
    stops = np.array([[s.x, s.y] for s in plan.stops])
    for c in sorted((c for c in plan.candidates if c.status == "rejected"),
                    key=lambda c: -c.inscribed_radius):  # fmt: skip
        others = np.hypot(*(centres - [c.x, c.y]).T)
        clear = np.sort(others)[1] > 0.05 and np.hypot(*(stops - [c.x, c.y]).T).min() > 0.15
        if clear and _reachable_on_screen(app, c.x, c.y):
            break
    else:
        pytest.fail("no rejected circle in view to hover")
    pg.mouse.move(*b.project(b.camera(app), (c.x, c.y, 0.0)))
    tip = pg.locator("#pickstop-tip")
    tip.wait_for(state="visible", timeout=5000)
    text = tip.inner_text()
    names = {t["id"]: t.get("name") or t["id"] for t in app.state.doc["trays"]}
    assert text.startswith("Rejected candidate")
    assert all(names[t] in text for t in c.trays) and c.reason in text
    b.shot(pg, "clarity-hover-rejected")
    pg.mouse.move(5, 5)
    app.sigma.value = 0.1
    b.wait_for(lambda: app.state.plan.parameters.sigma == 0.1, 60, "sigma back")


def test_an_impossible_sigma_states_the_largest_that_plans(pg, app):
    b.settled(app)
    app.sigma.value = 0.5
    pg.wait_for_function("() => document.body.innerText.includes('Status: no plan')",
                         timeout=60_000)  # fmt: skip
    text = pg.inner_text("body")
    assert "the largest sigma that keeps a candidate stop for every tray is" in text
    app.sigma.value = 0.1
    b.ready(pg)


def test_the_factory_cells_labels_never_overlap(live_api, pg):
    # A second page in the same browser (one Playwright per process at a time).
    with b.planner(live_api, b.SCENES / "factory_cell.json") as factory:
        fp = pg.context.browser.new_page(viewport={"width": b.SIZE[0], "height": b.SIZE[1]})
        fp.goto(f"http://127.0.0.1:{factory.port}/")
        b.ready(fp, 180_000)
        b.settled(factory, 120)
        b.wait_for(lambda: bool(factory.viewports), 10, "the page's layout")
        time.sleep(1.0)
        factory._declutter()
        cam = b.camera(factory)
        vp_h = b.SIZE[1]
        boxes, hidden = [], 0
        for _, h, anchor in factory.scene.labels() + [
            (k, h, tuple(h.position)) for k, h in factory.layer.labels()
        ]:
            if not h.visible:
                hidden += 1
                continue
            boxes.append(label_box(b.project(cam, anchor), str(h.text), vp_h))
        assert hidden > 0 and len(boxes) >= 5
        for i, a in enumerate(boxes):
            for c in boxes[i + 1 :]:
                assert not (a[0] < c[2] and c[0] < a[2] and a[1] < c[3] and c[1] < a[3])
        b.shot(fp, "clarity-factory-labels")
        fp.close()
