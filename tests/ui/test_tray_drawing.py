"""The planner draws trays, tilted ones included, where the backend checks them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import viser.transforms as vtf

from pickstop.frames import yaw_quat
from pickstop.scene.load import parse_scene
from pickstop.scene.world import tray_body_solids
from pickstop_ui.geometry import tilt_quat, tray_boxes

RACK = Path(__file__).parents[2] / "examples" / "scenes" / "rack_cell.json"


def _drawn(tray: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    """World pose (4 x 4) and size of each box the planner draws for ``tray``: the tray's
    control frame (x, y, z, yaw), then its tilted body frame, then the box's centre."""
    p = tray["pose"]
    T_root = vtf.SE3.from_rotation_and_translation(
        vtf.SO3(np.array(yaw_quat(p["yaw"]))), np.array([p["x"], p["y"], p["z"]])
    )
    T_body = T_root @ vtf.SE3.from_rotation_and_translation(
        vtf.SO3(np.array(tilt_quat(tray.get("tilt")))), np.zeros(3)
    )
    out = []
    for _, dims, centre in tray_boxes(tray):
        T = T_body @ vtf.SE3.from_translation(np.array(centre))
        out.append((T.as_matrix(), np.array(dims)))
    return out


@pytest.mark.parametrize("tray_id", ["flow_tray", "floor_bin", "upper_tray"])
def test_drawn_tray_boxes_match_the_checked_solids(tray_id):
    doc = json.loads(RACK.read_text())
    tray_doc = next(t for t in doc["trays"] if t["id"] == tray_id)
    solids = tray_body_solids(parse_scene(doc).tray(tray_id))
    drawn = _drawn(tray_doc)
    assert len(drawn) == len(solids)
    for (T, dims), s in zip(drawn, solids, strict=True):
        assert np.allclose(T, s.T_world_solid, atol=1e-9)
        assert np.allclose(dims / 2, s.half, atol=1e-12)


def test_tilt_quaternion_turns_about_the_trays_own_axis():
    R = vtf.SO3(np.array(tilt_quat({"axis": "x", "angle": 0.26}))).as_matrix()
    assert np.allclose(R[:, 0], [1, 0, 0]) and R[2, 1] > 0  # y turned towards z
    R = vtf.SO3(np.array(tilt_quat({"axis": "y", "angle": 0.26}))).as_matrix()
    assert np.allclose(R[:, 1], [0, 1, 0]) and R[0, 2] > 0  # z turned towards x
    assert tilt_quat(None) == (1.0, 0.0, 0.0, 0.0)
