"""The region kit's grasps (regions/kit.py): their direction and their reuse."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from pickstop.reach.so3 import quats_to_matrices
from pickstop.scene.load import parse_scene


def test_top_down_grasp_targets_point_down(planner, paper_doc):
    scene = parse_scene(paper_doc)
    hand = planner.hand  # the approach axis is the hand's, in the grasp point's frame
    a_tool = hand.T_tcp_tool[:3, :3].T @ hand.approach
    for gs in planner.grasps(scene, scene.tray("tray_1")):
        assert set(gs.kinds) == {"top"}
        approach = gs.Ts_world_tool[:, :3, :3] @ a_tool
        assert np.allclose(approach, [0, 0, -1], atol=1e-9)
    assert quats_to_matrices(np.array([0.70710678, 0, 0.70710678, 0]))[2, 0] == pytest.approx(
        -1, abs=1e-6
    )


def test_grasps_are_reused_while_nothing_reaches_into_the_hands(planner, paper_doc, monkeypatch):
    from pickstop.regions import kit as kit_module

    calls = []
    real = kit_module.grasps_for_part
    monkeypatch.setattr(kit_module, "grasps_for_part", lambda *a: calls.append(a[2].id) or real(*a))

    def same(a, b):
        return all(
            np.array_equal(x.Ts_world_tool, y.Ts_world_tool) and x.kinds == y.kinds
            for x, y in zip(a, b, strict=True)
        )

    scene = parse_scene(paper_doc)
    before = planner.grasps(scene, scene.tray("tray_4"))
    n = len(calls)
    far = copy.deepcopy(paper_doc)
    next(t for t in far["trays"] if t["id"] == "tray_2")["pose"]["x"] += 0.05
    moved = parse_scene(far)
    assert same(planner.grasps(moved, moved.tray("tray_4")), before) and len(calls) == n
    # tray_4 slid 5 cm along its table: the same grasps in the tray's frame, not computed anew
    slid = copy.deepcopy(paper_doc)
    next(t for t in slid["trays"] if t["id"] == "tray_4")["pose"]["x"] += 0.05
    slid_scene = parse_scene(slid)
    again = planner.grasps(slid_scene, slid_scene.tray("tray_4"))
    assert len(calls) == n
    fresh = [
        real(slid_scene, slid_scene.tray("tray_4"), p, planner.hand)
        for p in slid_scene.tray("tray_4").parts
    ]
    assert same(again, fresh)
    # A board just above tray_4, where the open hands of top-down grasps would be.
    near = copy.deepcopy(paper_doc)
    near["obstacles"].append(
        {
            "id": "board",
            "pose": {"x": 3.6, "y": 1.5, "z": 0.84, "yaw": 0.0},
            "geometry": {"shape": "box", "size": [0.3, 0.2, 0.02]},
        }
    )
    covered = parse_scene(near)
    after = planner.grasps(covered, covered.tray("tray_4"))
    assert len(calls) > n
    assert sum(len(g.Ts_world_tool) for g in after) < sum(len(g.Ts_world_tool) for g in before)
