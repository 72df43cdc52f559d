"""Grasp generation per shape, filtered by the tray."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pickstop.robot.hand import HandShape, hand_shape
from pickstop.scene.grasps import candidate_grasps, grasps_for_part, hand_solids
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Box, Cylinder, Gripper, Part, Pose
from pickstop.scene.world import solids_overlap, tray_solids, world_part_transform

PAPER = json.loads(
    (Path(__file__).parents[2] / "examples/scenes/paper_experiment.json").read_text()
)


def _rot_ok(T):
    R = T[:3, :3]
    return np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)


@pytest.fixture(scope="module")
def hand(tiago):
    return hand_shape(tiago)


def test_box_top_and_side_grasps_respect_opening():
    part = Part(id="b", geometry=Box(size=(0.04, 0.10, 0.06)))
    grasps = candidate_grasps(part, HandShape.parallel(max_opening=0.05))
    assert all(_rot_ok(T) for T, _ in grasps)
    top = [T for T, k in grasps if k == "top"]
    # Only closing across the 4 cm side fits a 5 cm opening: angles 0 and 180 degrees.
    assert len(top) == 2
    for T in top:
        assert np.allclose(T[:3, 0], [0, 0, -1])
        assert abs(T[0, 1]) > 0.99
    assert any(k == "side" for _, k in grasps)


def test_cylinder_grasps_all_around():
    part = Part(id="c", geometry=Cylinder(radius=0.02, height=0.05))
    grasps = candidate_grasps(
        part, HandShape.parallel(), Gripper(top_down_angles=8, side_directions=8)
    )
    assert sum(k == "top" for _, k in grasps) == 8
    # Side grasps closing horizontally fit (4 cm); closing vertically over 5 cm fits too.
    assert sum(k == "side" for _, k in grasps) == 16


def test_symmetric_gripper_halves_top_down_angles():
    part = Part(id="c", geometry=Cylinder(radius=0.02, height=0.05))
    a = candidate_grasps(part, HandShape.parallel(), Gripper(symmetric=False))
    b = candidate_grasps(part, HandShape.parallel(), Gripper(symmetric=True))
    assert sum(k == "top" for _, k in b) == sum(k == "top" for _, k in a)
    angles = [np.arctan2(T[1, 1], T[0, 1]) for T, k in b if k == "top"]
    assert max(angles) - min(angles) < np.pi


def test_too_wide_part_has_no_grasp():
    part = Part(id="w", geometry=Box(size=(0.2, 0.2, 0.2)))
    assert candidate_grasps(part, HandShape.parallel(max_opening=0.08)) == []


def test_tray_walls_block_side_grasps_and_kept_grasps_are_clear(hand):
    scene = parse_scene(PAPER)
    tray = scene.tray("tray_1")
    for part in tray.parts:
        gs = grasps_for_part(scene, tray, part, hand)
        assert len(gs.Ts_part_tool) > 0
        assert set(gs.kinds) == {"top"}  # 5 cm walls: no side grasp of a 3 cm part
        obstacles = tray_solids(scene, tray, exclude_part=part.id)
        T_wp = world_part_transform(tray, part)
        for T in gs.Ts_part_tool:
            solids = hand_solids(hand, T_wp @ T)
            assert not any(solids_overlap(a, b) for a in solids for b in obstacles)


def test_user_grasps_override(hand):
    doc = json.loads(json.dumps(PAPER))
    doc["trays"][1]["parts"][0]["grasps"] = [
        {"position": [0, 0, 0.03], "quaternion_wxyz": [0.0, 0.7071068, 0.7071068, 0.0]}
    ]
    scene = parse_scene(doc)
    tray = scene.tray("tray_2")
    gs = grasps_for_part(scene, tray, tray.parts[0], hand)
    assert gs.user_given and len(gs.Ts_part_tool) <= 1


def test_neighbouring_part_blocks_a_grasp(hand):
    doc = json.loads(json.dumps(PAPER))
    tray = doc["trays"][1]
    alone = grasps_for_part(
        parse_scene(doc),
        parse_scene(doc).tray("tray_2"),
        parse_scene(doc).tray("tray_2").parts[0],
        hand,
    )
    tray["parts"].append(
        {
            "id": "tall",
            "geometry": {"shape": "box", "size": [0.03, 0.03, 0.05]},
            "pose": {"x": 0.0, "y": 0.06, "z": 0.0, "yaw": 0.0},
        }
    )
    scene = parse_scene(doc)
    crowded = grasps_for_part(scene, scene.tray("tray_2"), scene.tray("tray_2").parts[0], hand)
    assert len(crowded.Ts_part_tool) < len(alone.Ts_part_tool)
    assert Pose() == Pose(x=0, y=0, z=0, yaw=0)


@pytest.mark.parametrize(("axis", "angle"), [("x", 0.26), ("y", -0.3)])
def test_tilted_tray_grasps_approach_along_its_tilted_normal(hand, axis, angle):
    doc = json.loads(json.dumps(PAPER))
    tray = doc["trays"][0]
    # lifted so that its low edge rests on the table
    half = tray["inner_size"][1 if axis == "x" else 0] / 2 + tray["wall_thickness"]
    tray["pose"]["z"] += half * np.sin(abs(angle)) + 0.002
    doc["trays"][0]["tilt"] = {"axis": axis, "angle": angle}
    scene = parse_scene(doc)
    tray = scene.tray("tray_1")
    normal = world_part_transform(tray, tray.parts[0])[:3, 2]
    assert abs(normal[2] - np.cos(angle)) < 1e-12
    R_tcp_grasp = hand.R_grasp_tcp.T
    for part in tray.parts:
        gs = grasps_for_part(scene, tray, part, hand)
        T_world_part = world_part_transform(tray, part)
        assert "top" in gs.kinds
        for T, kind in zip(gs.Ts_part_tcp, gs.kinds, strict=True):
            approach = (T_world_part @ T)[:3, :3] @ R_tcp_grasp[:, 0]
            if kind == "top":
                assert np.allclose(approach, -normal, atol=1e-9)
            else:  # side grasps run parallel to the tilted floor
                assert abs(approach @ normal) < 1e-9
        # The tool targets are the same grasp points, moved by the hand's tool offset.
        assert np.allclose(gs.Ts_world_tool, T_world_part @ gs.Ts_part_tcp @ hand.T_tcp_tool)


def test_grasps_too_close_to_the_floor_are_dropped(hand):
    """A tray on the floor: top-down grasps put the open hand within the clearance."""
    doc = json.loads(json.dumps(PAPER))
    doc["obstacles"] = []  # the tables gone, the other trays with them
    doc["trays"], doc["task"] = doc["trays"][:1], None
    doc["trays"][0]["pose"]["z"] = doc["trays"][0]["floor_thickness"]
    tray_id = doc["trays"][0]["id"]
    counts = {}
    for clearance in (0.0, 0.05):
        doc["floor_clearance"] = clearance
        scene = parse_scene(doc)
        tray = scene.tray(tray_id)
        sets = [grasps_for_part(scene, tray, p, hand) for p in tray.parts]
        counts[clearance] = [(len(gs.kinds), gs.near_floor) for gs in sets]
    assert all(n > 0 for n, _ in counts[0.0])
    for (kept, near), (kept_high, near_high) in zip(counts[0.0], counts[0.05], strict=True):
        assert kept_high < kept and near_high - near >= kept - kept_high


def _grasps_one_solid_at_a_time(scene, tray, part, hand):
    """The grasps of ``part`` as the open hand's solids test them one by one (each one's
    bounds from the solid itself): what grasps_for_part's bounds at once must agree with."""
    from pickstop.scene.grasps import PART_CLEARANCE, _candidates, _heights, clear_of
    from pickstop.scene.world import SolidSet, part_solid, solid_below

    T_wp = world_part_transform(tray, part)
    obstacles = SolidSet.of(tray_solids(scene, tray, exclude_part=part.id))
    target = part_solid(tray, part)
    kept, low_ones = [], 0
    for T0, kind in _candidates(scene, tray, part, hand):
        low = False
        for T in _heights(T0, kind, part):
            solids = hand_solids(hand, T_wp @ T)
            if any(solid_below(a, scene.floor_clearance) for a in solids):
                low = True
                continue
            if any(obstacles.overlaps(a) for a in solids):
                continue
            if clear_of(solids, target, PART_CLEARANCE):
                kept.append(T)
                break
        else:
            low_ones += low
    return np.array(kept).reshape(-1, 4, 4), low_ones


@pytest.mark.parametrize("name", ["paper_experiment", "factory_cell", "rack_cell"])
def test_grasps_tested_at_once_are_those_tested_one_solid_at_a_time(hand, name):
    doc = json.loads((Path(__file__).parents[2] / f"examples/scenes/{name}.json").read_text())
    scene = parse_scene(doc)
    for tray in scene.trays[:6]:
        for part in tray.parts:
            got = grasps_for_part(scene, tray, part, hand)
            want, low = _grasps_one_solid_at_a_time(scene, tray, part, hand)
            np.testing.assert_array_equal(got.Ts_part_tcp, want)
            assert got.near_floor == low


@pytest.mark.parametrize("name", ["five_trays", "factory_cell"])
def test_grasps_from_verdicts_judged_elsewhere_are_those_tested_where_the_tray_stands(hand, name):
    # Each tray's own verdicts judged where it stands, then the tray moved and turned (into
    # reach of its neighbours too; and with a bar over a part's edge, above the walls, which
    # only the rest of the scene holds): its grasps are those of the reference at the new
    # place.
    from pickstop.scene.grasps import own_verdicts
    from pickstop.scene.model import SceneError

    doc = json.loads((Path(__file__).parents[2] / f"examples/scenes/{name}.json").read_text())
    scene = parse_scene(doc)
    compared = blocked = 0
    for k, tray in enumerate(scene.trays[:4]):
        verdicts = {p.id: own_verdicts(scene, tray, p, hand) for p in tray.parts}
        for dx, dy, turn in ((0.04, 0.0, 0.0), (0.0, -0.15, 0.0), (-0.25, 0.1, 0.0),
                             (0.0, 0.0, 0.3), (0.05, -0.1, -1.2), (0.0, 0.0, np.pi)):  # fmt: skip
            moved = json.loads(json.dumps(doc))
            t = moved["trays"][k]
            t["pose"]["x"] += dx
            t["pose"]["y"] += dy
            t["pose"]["yaw"] = t["pose"].get("yaw", 0.0) + turn
            p0 = t["parts"][0]
            # over the part's edge: its pose (and the edge) turned with the tray
            yaw = t["pose"]["yaw"]
            ex, ey = p0["pose"]["x"] + p0["geometry"]["size"][0] / 2, p0["pose"]["y"]
            bar = {
                "id": "bar",
                "geometry": {"shape": "box", "size": [0.012, 0.08, 0.012]},
                "pose": {
                    "x": t["pose"]["x"] + np.cos(yaw) * ex - np.sin(yaw) * ey,
                    "y": t["pose"]["y"] + np.sin(yaw) * ex + np.cos(yaw) * ey,
                    "z": t["pose"]["z"] + t["floor_thickness"] + p0["geometry"]["size"][2] + 0.03,
                    "yaw": yaw,
                },
            }
            with_bar = json.loads(json.dumps(moved))
            with_bar["obstacles"].append(bar)
            counts = []
            for d in (moved, with_bar):
                try:
                    there = parse_scene(d)
                except SceneError:
                    break  # the tray would overlap another
                t2 = there.tray(tray.id)
                got = grasps_for_part(there, t2, t2.parts[0], hand, verdicts[t2.parts[0].id])
                want, low = _grasps_one_solid_at_a_time(there, t2, t2.parts[0], hand)
                np.testing.assert_allclose(got.Ts_part_tcp, want, atol=1e-12)
                assert got.near_floor == low
                counts.append(len(got.Ts_part_tcp))
                compared += 1
            blocked += len(counts) == 2 and counts[1] < counts[0]
    assert compared >= 12 and blocked >= 4
