"""The robots shipped in examples/robots: each loads and passes `robot check`; the UR5 AMR,
TIAGo Pro and PR2 build small databases, reach every tray of the paper-like scene from verified
stops and plan it, the long bases docking where their bounding circle does not fit."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import shapely

from pickstop.robot.model import load
from tests.utils import assert_route_clear, assert_stop_verified

ROOT = Path(__file__).parents[2]
ROBOTS = ROOT / "examples" / "robots"
CONFIGS = {name: ROBOTS / f"{name}.yaml" for name in ("ur5_amr", "tiago_pro", "tiago_dual", "pr2")}


def paper_scene(config: Path):
    """The paper-like scene, unchanged but for its robot: ``config``."""
    from pickstop.scene.load import parse_scene

    doc = json.loads((ROOT / "examples/scenes/paper_experiment.json").read_text())
    doc["robot"] = {"config": str(config)}
    return parse_scene(doc)


@pytest.fixture(scope="module")
def robots():
    return {name: load(str(path)) for name, path in CONFIGS.items()}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ur5_amr", "tiago_pro", "tiago_dual"])
def test_example_robot_passes_the_check(name, tmp_path_factory):
    from pickstop.robot.check import check_robot
    from pickstop.settings import cache_dir

    report = check_robot(str(CONFIGS[name]), cache_dir(tmp_path_factory.mktemp(name)))
    assert report["screen"]["false_rejection"] <= 0.05
    assert report["hand"]["links"], "the hand's own links are checked"


def test_ur5_amr_is_the_ur5_on_its_base_with_the_gripper_open(robots):
    robot = robots["ur5_amr"]
    assert robot.dof == 6 and robot.config.hand.geometry == "links"
    # The arm's kinematics are ur5_robot.urdf's: reach from the shoulder at the home pose.
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, robot.angles_to_q(np.zeros(6)))
    base = data.oMf[model.getFrameId("arm_base_link")].translation
    flange = data.oMf[model.getFrameId("ee_link")].translation
    assert base == pytest.approx([0.28, 0.0, 0.60])
    # At zero the UR5 lies straight out: 0.425 + 0.39225 along x, offsets along y, 0.089 up.
    assert flange - base == pytest.approx([0.81725, 0.10915 + 0.0823, 0.089159 - 0.09465], abs=1e-6)
    # Open on approach: the pads 85 mm apart, the TCP between them 15 mm short of the tips.
    shape = robot_hand(robot)
    assert shape.joints["gripper_finger_left_joint"] == pytest.approx(0.0425)
    assert shape.max_opening == pytest.approx(0.085)
    assert shape.reach == pytest.approx(0.015, abs=1e-6)


def _tiago_pro_tips(robot, gripper: float):
    """``T_tool_tip`` of the right gripper's two fingertip links, the linkage joints at the
    URDF's mimic values for ``gripper_right_finger_joint = gripper`` [rad]."""
    model = pin.buildModelFromUrdf(str(robot.urdf_path))
    data, q = model.createData(), pin.neutral(model)
    for joint, k in [
        ("finger", 1),
        ("inner_finger_left", 1),
        ("inner_finger_right", 1),
        ("outer_finger_right", 1),
        ("fingertip_left", -1),
        ("fingertip_right", -1),
    ]:
        q[model.idx_qs[model.getJointId(f"gripper_right_{joint}_joint")]] = k * gripper
    pin.framesForwardKinematics(model, data, q)
    T_w_tool = data.oMf[model.getFrameId("arm_right_tool_link")]
    return [
        T_w_tool.actInv(data.oMf[model.getFrameId(f"gripper_right_fingertip_{s}_link")])
        for s in ("left", "right")
    ]


def test_tiago_pro_pads_stay_parallel_and_the_tcp_lies_between_them(robots):
    robot = robots["tiago_pro"]
    assert set(robot.config.hand.pregrasp.values()) == {0.0}  # open: every linkage joint at 0
    open_, closed = _tiago_pro_tips(robot, 0.0), _tiago_pro_tips(robot, 0.8)
    for a, b in zip(open_, closed, strict=True):  # the fingertips only translate
        assert np.allclose(a.rotation, b.rotation, atol=1e-3)
        assert np.linalg.norm(b.translation - a.translation) > 0.03
    # The grasp point: on the centre line between the fingertip links, along the approach.
    mid = 0.5 * (open_[0].translation + open_[1].translation)
    tcp = np.array(robot.config.hand.tool_offset.position)
    assert np.hypot(*(mid - tcp)[:2]) < 1e-3
    shape = robot_hand(robot)
    assert shape.max_opening == pytest.approx(0.079)
    assert 0.005 < shape.reach < 0.02  # the fingertips 14 mm past the grasp point
    assert shape.closing @ np.array([0, 1, 0]) == pytest.approx(1.0)


def robot_hand(robot):
    from pickstop.robot.hand import hand_shape

    return hand_shape(robot)


def _surface_points(geom) -> np.ndarray:
    """Points ``(N, 3)`` on a coal geometry, in its frame: mesh vertices, box corners, rings
    of cylinders and spheres."""
    import coal

    if isinstance(geom, coal.BVHModelBase):
        return np.asarray(geom.vertices(), dtype=float)
    ring = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    circle = np.stack([np.cos(ring), np.sin(ring), np.zeros_like(ring)], 1)
    if isinstance(geom, coal.Box):
        h = np.asarray(geom.halfSide)
        return np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * h
    if isinstance(geom, coal.Cylinder):
        r, h = geom.radius, geom.halfLength
        return np.concatenate([r * circle + [0, 0, -h], r * circle + [0, 0, h]])
    if isinstance(geom, coal.Sphere):
        rot = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
        return geom.radius * np.concatenate([circle, circle @ rot.T, circle @ rot @ rot.T])
    raise AssertionError(f"no points for {type(geom).__name__}")


@pytest.mark.parametrize("name", ["ur5_amr", "tiago_pro", "tiago"])
def test_derived_footprint_holds_the_base_outline(name, robots, tiago):
    """Every point of the collision geometry fixed to the base below the footprint height,
    placed with pinocchio, lies inside the outline derived from the URDF."""
    robot = tiago if name == "tiago" else robots[name]
    fp = robot.footprint
    assert fp.derived and fp.polygon is not None and fp.clearance == 0.02
    outline = shapely.Polygon(fp.polygon).buffer(1e-9)
    data, gdata = robot.model.createData(), pin.GeometryData(robot.geom_model)
    pin.forwardKinematics(robot.model, data, robot.angles_to_q(np.zeros(robot.dof)))
    pin.updateGeometryPlacements(robot.model, data, robot.geom_model, gdata)
    checked = set()
    for i, obj in enumerate(robot.geom_model.geometryObjects):
        if obj.parentJoint != 0:
            continue  # moves with the arm: not the base
        M = gdata.oMg[i]
        w = _surface_points(obj.geometry) @ np.asarray(M.rotation).T + np.asarray(M.translation)
        low = w[w[:, 2] <= fp.height + 1e-9]
        if len(low):
            checked.add(obj.name)
            assert shapely.contains_xy(outline, low[:, 0], low[:, 1]).all(), obj.name
    assert len(checked) >= 3
    if name == "ur5_amr":  # the 0.90 x 0.60 m chassis plus the 2 cm clearance
        bounds = shapely.Polygon(fp.polygon).bounds
        assert bounds == pytest.approx((-0.47, -0.32, 0.47, 0.32), abs=1e-6)
        assert {"amr_chassis_link_0", "amr_wheel_left_link_0", "amr_caster_fl_link_0"} <= checked
    if name == "tiago":  # the PMB2's 0.25 m round base and its wheels, plus 2 cm
        assert 0.265 < max(np.hypot(*v) for v in fp.polygon) < 0.28
        assert {"base_link_0", "wheel_left_link_0"} <= checked
        from pickstop.robot.check import _footprint_line

        line = _footprint_line(fp.model_dump())  # what `robot check` prints
        assert "derived from the base's collision geometry below 0.35 m plus 0.02 m" in line


@pytest.fixture(scope="module", params=["ur5_amr", "tiago_pro", "pr2"])
def planned(request, robots, tmp_path_factory):
    """A small database of the robot, its region planner and the paper-like scene."""
    from pickstop.reach.build import BuildParams
    from pickstop.settings import cache_dir
    from pickstop.speedups.region_planner import RegionPlanner
    from pickstop.store.reach_build import build
    from pickstop.store.reach_catalog import open_database

    robot = robots[request.param]
    folder = tmp_path_factory.mktemp(f"{request.param}-data")
    row = build(robot, BuildParams(samples=400_000, chunk_size=200_000, seed=3), folder, workers=2)
    assert row["state"] == "complete" and 0 <= row["screen_false_rejection"] <= 0.05
    planner = RegionPlanner(
        robot, open_database(folder, robot, row["id"]), cache_dir=cache_dir(folder)
    )
    return request.param, planner, paper_scene(CONFIGS[request.param])


@pytest.mark.slow
def test_paper_scene_trays_reached_from_exactly_verified_cells(planned):
    from pickstop.regions.reference import verify_witnesses

    _, planner, scene = planned
    reached = 0
    for tray_id in scene.task_trays:
        region = planner.tray_region(scene, tray_id)
        if not len(region.cells):
            continue
        reached += 1
        check = verify_witnesses(planner, scene, region)
        assert check.witnesses > 0 and check.failures == 0, (tray_id, check)
    assert reached == len(scene.task_trays)


@pytest.mark.slow
def test_paper_scene_plan_witnesses_pass_exact_checks_with_the_hand(planned):
    """Every witness of the plan: FK on its grasp, no coal contact of any collision link (hand
    links included) with the scene or the robot itself."""
    from pickstop.regions.arm import arm_links, is_hand_link
    from pickstop.sequence.cover import InfeasiblePlanError
    from pickstop.sequence.plan_model import PlanOptions
    from pickstop.speedups.stop_planner import StopPlanner

    name, planner, scene = planned
    assert any(is_hand_link(planner.robot, lk.name) for lk in arm_links(planner.robot))
    if name == "ur5_amr":
        # The goal lies 0.50 m from the floor's edge, inside the base's 0.57 m circle, at yaw
        # 90 deg: only a sideways move reaches it, which the AMR's two drive wheels cannot
        # make. The unchanged scene says so; facing the edge, the base drives straight in.
        with pytest.raises(InfeasiblePlanError, match="along its heading"):
            StopPlanner(planner).plan(scene, PlanOptions(samples=0, sigma=0.05))
        scene = scene.model_copy(update={"goal": scene.goal.model_copy(update={"yaw": 0.0})})
    try:  # a 400k-sample database: regions smaller than a full build's, so sigma 5 cm
        plan = StopPlanner(planner).plan(scene, PlanOptions(samples=100, sigma=0.05))
    except InfeasiblePlanError as e:  # a robot that cannot serve every tray says why
        pytest.fail(f"{name}: {e.message}")
    assert sorted(t for s in plan.stops for t in s.trays) == sorted(scene.task_trays)
    for stop in plan.stops:
        assert_stop_verified(planner, scene, stop)
    assert_route_clear(planner.robot, scene, plan)
    docked = [leg for leg in plan.legs if leg.segment_yaws]
    if name == "ur5_amr":  # the goal lies 0.50 m from the floor's edge, its circle is 0.57 m
        assert plan.legs[-1].segment_yaws and plan.legs[-1].segment_yaws[-1] == scene.goal.yaw
    if name == "pr2":  # stops 0.45-0.46 m from the tables, its circle is 0.467 m
        assert docked


def test_tiago_dual_hey5_pinches_every_paper_scene_part_from_above(robots):
    """The right Hey5 in the tiago preset's open pinch: its hand reaches 12 mm past the grasp
    point (95 mm straight and open), and every part of the paper-like scene has top-down
    grasps clear of the tray."""
    from pickstop.robot.hand import hand_shape
    from pickstop.scene.grasps import grasps_for_part

    robot = robots["tiago_dual"]
    hand = hand_shape(robot)
    assert hand.reach < 0.015
    assert hand.joints["hand_right_thumb_abd_joint"] == pytest.approx(1.5707)
    assert not any("safety_box" in name for name, _, _ in hand.geometries)
    scene = paper_scene(CONFIGS["tiago_dual"])
    for tray_id in scene.task_trays:
        tray = scene.tray(tray_id)
        for part in tray.parts:
            grasps = grasps_for_part(scene, tray, part, hand)
            assert "top" in grasps.kinds and not grasps.too_low, part.id
