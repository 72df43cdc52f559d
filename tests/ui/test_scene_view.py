"""The scene as drawn, a pure function of the document (no browser): every tray wall, part
and obstacle lies where the backend checks it, tilted trays included."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
import viser.transforms as vtf

from pickstop.scene import defaults
from pickstop.scene.load import parse_scene
from pickstop.scene.world import obstacle_solids, part_solid, tray_body_solids
from pickstop_ui.scene_view import (
    PALETTE,
    Item,
    Shape,
    initial_sigma,
    scene_drawing,
    tilt_quat,
    tray_colour,
)

SCENES = Path(__file__).parents[2] / "examples" / "scenes"
RACK = SCENES / "rack_cell.json"


def _T(position, wxyz) -> vtf.SE3:
    return vtf.SE3.from_rotation_and_translation(vtf.SO3(np.array(wxyz)), np.array(position))


def _world(item: Item, shape: Shape) -> np.ndarray:
    """``T_world_shape`` (4, 4): the item's root, its body frame (a tray's tilt), the shape."""
    T = _T(item.position, item.wxyz)
    if shape.name.startswith("body/") and item.body_wxyz is not None:
        T = T @ _T((0, 0, 0), item.body_wxyz)
    return (T @ _T(shape.position, shape.wxyz)).as_matrix()


def _half(shape: Shape) -> np.ndarray:
    if shape.kind == "box":
        return np.array(shape.dims) / 2
    r, h = shape.dims
    return np.array([r, r, h / 2])


def _same(shape: Shape, item: Item, solid) -> None:
    T = _world(item, shape)
    if shape.kind == "cylinder":  # an upright cylinder: its yaw is not seen
        assert np.allclose(T[:3, 3], solid.T_world_solid[:3, 3], atol=1e-9)
        assert np.allclose(T[:3, 2], solid.T_world_solid[:3, 2], atol=1e-9)
    else:
        assert np.allclose(T, solid.T_world_solid, atol=1e-9)
    assert np.allclose(_half(shape), solid.half, atol=1e-12)


@pytest.mark.parametrize("name", ["rack_cell", "paper_experiment", "five_trays", "factory_cell"])
def test_drawn_trays_parts_and_obstacles_lie_where_they_are_checked(name):
    path = SCENES / f"{name}.json"
    if not path.is_file():
        pytest.skip(f"no example {name}")
    doc = json.loads(path.read_text())
    scene = parse_scene(doc)
    d = scene_drawing(doc)
    trays = {i.id: i for i in d.items if i.kind == "trays"}
    assert list(trays) == [t.id for t in scene.trays]
    for tray in scene.trays:
        item = trays[tray.id]
        body = [s for s in item.shapes if not s.name.startswith("body/parts/")]
        solids = tray_body_solids(tray)
        assert len(body) == len(solids)
        for s, solid in zip(body, solids, strict=True):
            _same(s, item, solid)
        parts = {s.name.removeprefix("body/parts/"): s for s in item.shapes if "parts/" in s.name}
        for part in tray.parts:
            if part.geometry.shape != "mesh":
                _same(parts[part.id], item, part_solid(tray, part))
    obstacles = {i.id: i for i in d.items if i.kind == "obstacles"}
    for solid, ob in zip(obstacle_solids(scene), scene.obstacles, strict=True):
        if ob.geometry.shape != "mesh":
            _same(obstacles[ob.id].shapes[0], obstacles[ob.id], solid)


def test_a_document_without_tray_dimensions_is_drawn_with_the_formats_defaults():
    doc = json.loads(RACK.read_text())
    bare = copy.deepcopy(doc)
    for t in bare["trays"]:
        for k in ("wall_height", "wall_thickness", "floor_thickness", "color"):
            t.pop(k, None)
    bare.pop("sigma", None)
    scene = parse_scene(bare)  # the model fills in the same defaults
    assert scene.trays[0].wall_height == defaults.TRAY_WALL_HEIGHT
    d = scene_drawing(bare)
    item = d.items[len(doc.get("obstacles", []))]
    for s, solid in zip(item.shapes, tray_body_solids(scene.trays[0]), strict=False):
        _same(s, item, solid)
    assert item.label is not None
    assert item.label[1][2] == pytest.approx(defaults.TRAY_WALL_HEIGHT + 0.09)
    assert initial_sigma(bare) == scene.sigma == defaults.SIGMA
    assert d.colours[scene.trays[0].id] == PALETTE[0]


def test_tray_colours_labels_markers_and_the_camera():
    doc = json.loads(RACK.read_text())
    doc["trays"][0]["color"] = "#102030"
    doc["trays"][0]["name"] = "bolts"
    d = scene_drawing(doc)
    assert tray_colour(0, doc["trays"][0]) == (16, 32, 48) == d.colours[doc["trays"][0]["id"]]
    assert tray_colour(13, {}) == PALETTE[1]
    first = next(i for i in d.items if i.kind == "trays")
    assert first.label is not None and first.label[0] == "bolts"
    assert all(s.colour == (16, 32, 48) for s in first.shapes if "parts/" not in s.name)
    assert [m.name for m in d.markers] == ["start", "goal"]
    assert d.markers[0].position[:2] == (doc["start"]["x"], doc["start"]["y"])
    (x0, y0), (x1, y1) = doc["floor"]["min"], doc["floor"]["max"]
    assert d.floor_size == (x1 - x0, y1 - y0)


def test_a_mesh_shape_is_named_as_not_drawn():
    doc = json.loads(RACK.read_text())
    doc.setdefault("obstacles", []).append(
        {"id": "scan", "geometry": {"shape": "mesh", "path": "m.stl"}, "pose": {"x": 1, "y": 1}}
    )
    d = scene_drawing(doc)
    scan = next(i for i in d.items if i.id == "scan")
    assert scan.shapes == [] and d.undrawn == ["obstacle scan"]


def test_tilt_quaternion_turns_about_the_trays_own_axis():
    R = vtf.SO3(np.array(tilt_quat({"axis": "x", "angle": 0.26}))).as_matrix()
    assert np.allclose(R[:, 0], [1, 0, 0]) and R[2, 1] > 0  # y turned towards z
    R = vtf.SO3(np.array(tilt_quat({"axis": "y", "angle": 0.26}))).as_matrix()
    assert np.allclose(R[:, 1], [0, 1, 0]) and R[0, 2] > 0  # z turned towards x
    assert tilt_quat(None) == (1.0, 0.0, 0.0, 0.0)
