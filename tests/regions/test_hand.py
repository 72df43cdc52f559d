"""The robot's own hand in every check: fingers against the scene, the grasped part aside."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from pickstop.regions.arm import ArmSpheres, ExactArm, arm_links, screen_arm
from pickstop.robot.config import PRESET_DIR, parse_config
from pickstop.robot.hand import hand_shape
from pickstop.robot.kinematics import Chain, fk_soa
from pickstop.robot.model import load_robot
from pickstop.scene.grasps import grasps_for_part, hand_solids
from pickstop.scene.load import parse_scene
from pickstop.scene.model import Box, Part
from pickstop.scene.world import BoxArrays, Solid, solids_overlap, tray_solids, world_part_transform

ROOT = Path(__file__).parents[2]
PAPER = json.loads((ROOT / "examples/scenes/paper_experiment.json").read_text())


def _placements(robot, theta):
    data, gdata = robot.model.createData(), pin.GeometryData(robot.geom_model)
    pin.forwardKinematics(robot.model, data, robot.angles_to_q(theta))
    pin.updateGeometryPlacements(robot.model, data, robot.geom_model, gdata)
    return gdata.oMg


def _box_at(robot, theta, geometry_name, owner, size=0.01):
    """A small box at the centre of one collision geometry, in the world (base at origin)."""
    gid = next(i for i, o in enumerate(robot.geom_model.geometryObjects) if o.name == geometry_name)
    geom = robot.geom_model.geometryObjects[gid].geometry
    geom.computeLocalAABB()
    c_local = 0.5 * (np.asarray(geom.aabb_local.min_) + np.asarray(geom.aabb_local.max_))
    M = _placements(robot, theta)[gid]
    T = np.eye(4)
    T[:3, 3] = M.rotation @ c_local + M.translation
    return Solid.box(T, (size, size, size), owner)


@pytest.fixture(scope="module")
def theta(pr2):
    return np.clip(np.array([0.2, -0.5, 0.3, -1.0, -1.2, 0.5, -0.8, 0.3]), pr2.lower, pr2.upper)


def test_the_hand_is_checked_with_its_own_links(pr2, theta):
    hand = {lk.name for lk in arm_links(pr2) if lk.name.startswith("r_gripper")}
    assert {"r_gripper_l_finger_tip_link", "r_gripper_palm_link"} <= hand
    shape = hand_shape(pr2)
    assert {n.rsplit("_", 1)[0] for n, _, _ in shape.geometries} >= {
        "r_gripper_l_finger_tip_link",
        "r_gripper_r_finger_tip_link",
    }
    # Open at the pre-grasp values: the pads 52 mm apart, the tips 14 mm past the grasp point.
    assert shape.joints["r_gripper_l_finger_joint"] == pytest.approx(0.3)
    assert 0.008 < shape.reach < 0.02


def test_a_fingertip_into_the_tray_floor_is_rejected(pr2, theta):
    """A floor board that only the real fingertip touches: exact and screen both reject."""
    floor = _box_at(pr2, theta, "r_gripper_l_finger_tip_link_0", "tray_x")
    exact = ExactArm(pr2)
    assert exact.colliding(theta, 0.0, 0.0, 0.0, [floor])
    spheres = ArmSpheres.of(pr2)
    chain = Chain.from_robot(pr2)
    _, _, frames = fk_soa(chain, theta[:, None], frames=True)
    assert screen_arm(spheres, BoxArrays.of([floor]), frames, np.zeros((1, 2)), 0.0)[0]
    # The part being grasped is no obstacle for the fingers...
    part = _box_at(pr2, theta, "r_gripper_l_finger_tip_link_0", "p1")
    assert not exact.colliding(theta, 0.0, 0.0, 0.0, [part], target="p1")
    assert not screen_arm(
        spheres, BoxArrays.of([part]), frames, np.zeros((1, 2)), 0.0, targets="p1"
    )[0]
    # ...but it is for the rest of the arm.
    elbow = _box_at(pr2, theta, "r_forearm_link_0", "p1", size=0.03)
    assert exact.colliding(theta, 0.0, 0.0, 0.0, [elbow], target="p1")


def test_grasps_are_filtered_with_the_real_hand(pr2):
    scene = parse_scene(PAPER)
    shape = hand_shape(pr2)
    tray = scene.tray("tray_4")
    for part in tray.parts:
        gs = grasps_for_part(scene, tray, part, shape)
        obstacles = tray_solids(scene, tray, exclude_part=part.id)
        T_wp = world_part_transform(tray, part)
        for T in gs.Ts_part_tcp:
            solids = hand_solids(shape, T_wp @ T)
            assert not any(solids_overlap(a, b) for a in solids for b in obstacles)
            # Top-down: the open hand stays above the tray floor.
            low = min(s.aabb()[0][2] for s in solids)
            assert low >= tray.pose.z - 1e-9
    # A part so low that the open hand would reach below the floor gets no top grasp.
    flat = Part(id="flat", geometry=Box(size=(0.03, 0.03, 0.01)))
    doc = json.loads(json.dumps(PAPER))
    doc["trays"][3]["parts"] = [json.loads(flat.model_dump_json())]
    scene2 = parse_scene(doc)
    gs = grasps_for_part(scene2, scene2.tray("tray_4"), scene2.tray("tray_4").parts[0], shape)
    assert gs.too_low and "top" not in gs.kinds


def test_tool_offset_moves_the_grasp_point(pr2):
    base = yaml.safe_load((ROOT / "examples/robots/pr2.yaml").read_text())
    base["hand"]["tool_offset"] = {"position": [0.02, 0.0, 0.01], "rpy": [0.0, 0.0, 0.3]}
    moved = load_robot(parse_config(base), ROOT / "examples" / "robots")
    scene = parse_scene(PAPER)
    tray = scene.tray("tray_4")
    part = tray.parts[0]
    a = grasps_for_part(scene, tray, part, hand_shape(pr2))
    b = grasps_for_part(scene, tray, part, hand_shape(moved))
    T_wp = world_part_transform(tray, part)
    for T_tcp, T_tool in zip(T_wp @ b.Ts_part_tcp, b.Ts_world_tool, strict=True):
        # The tool frame sits so that the offset puts the grasp point where the grasp wants it.
        got = T_tool[:3, 3] + T_tool[:3, :3] @ np.array([0.02, 0.0, 0.01])
        assert np.allclose(got, T_tcp[:3, 3], atol=1e-9)
    assert len(a.Ts_world_tool) and len(b.Ts_world_tool)
    assert not np.allclose(a.Ts_world_tool[0, :3, 3], b.Ts_world_tool[0, :3, 3])


def _tiago_variant(**hand):
    """The tiago preset with its hand block changed."""
    doc = yaml.safe_load((PRESET_DIR / "tiago.yaml").read_text())
    doc["hand"].update(hand)
    return load_robot(parse_config(doc), PRESET_DIR)


def test_boxes_stand_in_for_a_hand_without_geometry():
    robot = _tiago_variant(geometry="boxes")
    shape = hand_shape(robot)
    assert len(shape.geometries) == 3
    assert not any(lk.name.startswith("hand_") for lk in arm_links(robot))


def test_tiago_pinches_a_3cm_part_with_every_finger_above_the_tray_floor(tiago):
    """The Hey5's pre-grasp pinch (thumb opposed, index flexed, middle-ring-little relaxed):
    top-down grasps of the paper scene's 3 cm parts in trays with 5 cm walls exist, and every
    collision mesh of the hand keeps at least the floor clearance off the tray floor (coal
    distances). Straight and open, the same fingers reach 95 mm past the grasp frame: no
    top-down grasp at all."""
    import coal

    from pickstop.scene.grasps import FLOOR_CLEARANCE, PART_CLEARANCE
    from pickstop.scene.world import _coal, part_solid, tray_body_solids

    shape = hand_shape(tiago)
    assert tiago.config.hand.geometry == "links" and len(shape.geometries) >= 30
    assert shape.joints["hand_thumb_abd_joint"] == pytest.approx(1.5707)
    assert shape.joints["hand_mrl_joint"] == pytest.approx(1.5)
    assert shape.reach < 0.015  # along the approach, past the grasp point
    # The thumb and index pads lie on either side of the grasp point, max_opening apart.
    pads = {}
    for name, geom, T in shape.geometries:
        if name.startswith(("hand_thumb_flex_2", "hand_index_flex_3")):
            pts = np.asarray(geom.vertices()) @ T[:3, :3].T + T[:3, 3]
            pads[name.split("_")[1]] = pts @ shape.closing
    assert pads["index"].min() - pads["thumb"].max() >= shape.max_opening - 1e-3
    assert pads["thumb"].max() < 0 < pads["index"].min()

    scene = parse_scene(PAPER)
    kept = 0
    for tray_id in ("tray_1", "tray_3"):
        tray = scene.tray(tray_id)
        gf, tf = _coal(tray_body_solids(tray)[0])  # the tray's floor board
        for part in tray.parts:
            if part.geometry.shape != "box" or part.geometry.size[2] > 0.03:
                continue
            gs = grasps_for_part(scene, tray, part, shape)
            top = [T for T, k in zip(gs.Ts_part_tcp, gs.kinds, strict=True) if k == "top"]
            assert top, part.id
            T_wp = world_part_transform(tray, part)
            gp, tp = _coal(part_solid(tray, part))
            for T in top:
                T_wt = T_wp @ T
                for _, geom, T_tg in shape.geometries:
                    M = T_wt @ T_tg
                    tg = coal.Transform3s(M[:3, :3], M[:3, 3])
                    d = coal.distance(
                        geom, tg, gf, tf, coal.DistanceRequest(), coal.DistanceResult()
                    )
                    assert d >= FLOOR_CLEARANCE - 1e-4, (part.id, d)
                    # On approach the open hand keeps off the part it is to grasp, too.
                    d = coal.distance(
                        geom, tg, gp, tp, coal.DistanceRequest(), coal.DistanceResult()
                    )
                    assert d >= PART_CLEARANCE - 1e-4, (part.id, d)
                kept += 1
    assert kept >= 8
    # Curled into the palm, the middle, ring and little fingers would lie inside the part.
    curled = {k: 0.6283 for k in tiago.config.hand.pregrasp if k.startswith("hand_middle_")}
    curled.update({k: 0.6837 for k in tiago.config.hand.pregrasp if k.startswith(("hand_ring_",
                   "hand_little_")) and "abd" not in k})  # fmt: skip
    fist = _tiago_variant(
        pregrasp={**tiago.config.hand.pregrasp, **curled, "hand_middle_abd_joint": 0.0}
    )
    tray = scene.tray("tray_1")
    assert len(grasps_for_part(scene, tray, tray.parts[0], hand_shape(fist)).kinds) == 0

    straight = hand_shape(_tiago_variant(pregrasp={}, tool_offset={}, approach_axis=[1, 0, 0],
                                         closing_axis=[0, 1, 0]))  # fmt: skip
    assert straight.reach == pytest.approx(0.095, abs=0.002)
    tray = scene.tray("tray_1")
    gs = grasps_for_part(scene, tray, tray.parts[0], straight)
    assert gs.too_low and "top" not in gs.kinds
