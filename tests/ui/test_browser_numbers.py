"""Numbers in the browser: the selected tray's pose shown and typed exactly, read out live
while it is dragged, the snap step set in the panel, a measured distance, yaw in the stops."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from tests.ui import browser as b

pytestmark = b.needs_chromium


def _field(pg, label: str):
    return pg.get_by_label(label, exact=True)


def test_typing_x_and_y_moves_the_selected_tray_there(pg, app):
    b.settled(app)
    b.click_item(pg, app, "trays", "tray_4")
    # The selection's numbers reach the page after the click (a message of their own).
    b.wait_for(lambda: float(_field(pg, "x [m]").input_value()) == pytest.approx(3.6), 10,
               "the selected tray's x")  # fmt: skip
    assert float(_field(pg, "z [m]").input_value()) == pytest.approx(0.725)
    stops0, seq = b.stops(app.state.plan), app.state.seq
    for label, value in (("x [m]", "3.415"), ("y [m]", "1.435")):
        _field(pg, label).fill(value)
        time.sleep(0.3)
    _field(pg, "y [m]").press("Enter")
    b.wait_for(lambda: b.tray(app, "tray_4")["pose"]["x"] == 3.415, 10, "the typed x")
    pose = b.tray(app, "tray_4")["pose"]
    assert (pose["x"], pose["y"], pose["z"], pose["yaw"]) == (3.415, 1.435, 0.725, 0.0)
    assert app.state.history.undo_label == "place tray_4"
    b.wait_for(lambda: np.allclose(app.selection.gizmo.position, [3.415, 1.435, 0.725]), 10,
               "the gizmo")  # fmt: skip
    b.wait_for(lambda: abs(b.node_position(pg, "/trays/tray_4")[0] - 3.415) < 1e-6, 10, "node")
    b.settled(app, since=seq)
    assert b.stops(app.state.plan) != stops0
    assert any("tray_4" in s.trays and math.hypot(s.x - 3.415, s.y - 1.435) < 1.2
               for s in app.state.plan.stops)  # fmt: skip


def test_the_numbers_read_out_live_while_dragging_and_the_snap_step_holds(pg, app):
    b.settled(app)
    _field(pg, "snap [m]").fill("0.1")
    b.wait_for(lambda: app.snap.value == pytest.approx(0.1), 10, "the snap step")
    t = b.tray(app, "tray_4")
    x0 = t["pose"]["x"]
    base = np.array([x0, t["pose"]["y"], t["pose"]["z"]])
    a, end = b.grab_x_arrow(pg, app, "tray_4", base, 0.2)
    pg.mouse.move(*a)
    pg.mouse.down()
    seen = []
    for k in range(1, 21):
        pg.mouse.move(a[0] + (end[0] - a[0]) * k / 20, a[1] + (end[1] - a[1]) * k / 20)
        time.sleep(0.08)
        if k in (10, 20):
            time.sleep(0.3)
            seen.append(
                (float(_field(pg, "x [m]").input_value()), b.tray(app, "tray_4")["pose"]["x"])
            )
    pg.mouse.up()
    b.settled(app)
    # Mid-drag the field showed where the tray was then, before the release.
    assert seen[0][0] == pytest.approx(seen[0][1], abs=1e-4) and seen[0][0] != pytest.approx(x0)
    x1 = b.tray(app, "tray_4")["pose"]["x"]
    steps = (x1 - x0) / 0.1
    assert abs(steps - round(steps)) < 1e-9 and round(steps) >= 1
    assert float(_field(pg, "x [m]").input_value()) == pytest.approx(x1, abs=1e-4)


def test_the_measure_tool_reads_the_distance_between_two_picked_points(pg, app):
    b.settled(app)
    pg.get_by_role("button", name="Measure a distance").click()
    b.wait_for(lambda: app.measure.on, 10, "the tool")
    cam = b.camera(app)
    for p in ((0.5, -0.5, 0.0), (2.0, -0.5, 0.0)):
        pg.mouse.click(*b.project(cam, p))
        time.sleep(0.5)
    b.wait_for(lambda: len(app.measure.points) == 2, 10, "two points")
    a, c = (np.asarray(p) for p in app.measure.points)
    assert np.allclose(a, (0.5, -0.5, 0.0), atol=0.02) and np.allclose(
        c, (2.0, -0.5, 0.0), atol=0.02
    )
    d = float(np.linalg.norm(c - a))
    b.wait_for(lambda: f"Distance: {d:.3f} m" in pg.inner_text("body"), 10, "the distance")
    assert app.selection.key == ("trays", "tray_4")  # measuring clicks select nothing
    pg.mouse.move(300, 700)
    pg.keyboard.press("Escape")
    b.wait_for(lambda: not app.measure.on, 10, "Esc to end the tool")


def test_the_stops_list_gives_each_stops_yaw(pg, app):
    b.settled(app)
    text = pg.inner_text("body")
    for s in app.state.plan.stops:
        assert f"({s.x:.2f}, {s.y:.2f}) m, yaw {math.degrees(s.yaw):.0f}°" in text
