"""What a click hits: item boxes, the slab test against sampled points, the nearest item."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pickstop_ui.picking import Box, floor_point, hit_point, item_box, pick, ray_box
from pickstop_ui.scene_view import scene_drawing

SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "paper_experiment.json"
DOWN = np.array([0.0, 0.0, -1.0])


def _boxes():
    d = scene_drawing(json.loads(SCENE.read_text()))
    return [b for b in (item_box(i) for i in d.items) if b is not None]


def test_a_click_from_above_picks_the_tray_not_the_table_beneath():
    boxes = _boxes()
    tray4 = next(b for b in boxes if b.id == "tray_4")
    assert tray4.kind == "trays" and tray4.centre[2] > 0.725
    assert pick(boxes, np.array([3.6, 1.5, 5.0]), DOWN).id == "tray_4"
    # Beside the tray, over table_b's top: the table.
    assert pick(boxes, np.array([3.6, 1.9, 5.0]), DOWN).id == "table_b"
    assert pick(boxes, np.array([0.0, -0.5, 5.0]), DOWN) is None
    assert floor_point(np.array([0.0, -0.5, 5.0]), DOWN) == (0.0, -0.5, 0.0)
    assert floor_point(np.array([0.0, 0.0, 5.0]), -DOWN) is None
    top = hit_point(boxes, np.array([3.6, 1.9, 5.0]), DOWN)
    assert math.isclose(top[2], 2 * next(b for b in boxes if b.id == "table_b").half[2])


def test_a_turned_tray_box_follows_its_yaw():
    doc = json.loads(SCENE.read_text())
    doc["trays"][3]["pose"]["yaw"] = math.pi / 2
    b = next(item_box(i) for i in scene_drawing(doc).items if i.id == "tray_4")
    flat = next(item_box(i) for i in scene_drawing(json.loads(SCENE.read_text())).items
                if i.id == "tray_4")  # fmt: skip
    assert b.half == flat.half and math.isclose(b.yaw, math.pi / 2)
    # The tray is longer along its own x: turned, that length lies along the world y.
    long_x = flat.half[0] > flat.half[1]
    probe = np.array([3.6, 1.5 + 0.95 * max(flat.half[:2]), 5.0])
    assert (ray_box(probe, DOWN, b) is not None) == long_x


BOXES = st.builds(
    Box,
    st.just("trays"),
    st.just("b"),
    st.tuples(*[st.floats(-3, 3)] * 3),
    st.tuples(*[st.floats(0.05, 1.0)] * 3),
    st.floats(-math.pi, math.pi),
)
UNIT = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1)


def _inside(box: Box, u: tuple[float, float, float]) -> np.ndarray:
    """The point at fractions ``u`` (each in [-1, 1]) of the box's half extents, in the world."""
    local = np.asarray(u) * np.asarray(box.half) * 0.999
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(box.centre) + R @ local


@settings(max_examples=300, deadline=None)
@given(BOXES, st.tuples(*[st.floats(-1, 1)] * 3), UNIT, st.floats(0.0, 5.0))
def test_a_ray_through_a_point_inside_enters_the_box_no_later_than_that_point(box, u, d, back):
    d = np.asarray(d) / np.linalg.norm(d)
    p = _inside(box, u)
    origin = p - back * d
    t = ray_box(origin, d, box)
    assert t is not None and t <= back + 1e-9
    # Entered where the ray is on the box's surface (or at its start, inside).
    q = origin + t * d
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    local = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ (q - np.asarray(box.centre))
    assert np.all(np.abs(local) <= np.asarray(box.half) + 1e-6)


@settings(max_examples=300, deadline=None)
@given(BOXES, st.tuples(*[st.floats(-1, 1)] * 3), UNIT, st.floats(0.01, 5.0))
def test_a_ray_pointing_away_from_a_box_it_left_misses_it(box, u, d, gap):
    d = np.asarray(d) / np.linalg.norm(d)
    # Leave the box along d from a point inside, then keep going: the box lies behind.
    p = _inside(box, u)
    exit_t = max(ray_box(p + 10 * d, -d, box) or 0.0, 0.0)  # from outside, back along -d
    out = p + (10 - exit_t + gap) * d
    assert ray_box(out, d, box) is None
