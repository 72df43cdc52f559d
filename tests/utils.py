"""Shared assertions and factories for the tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pickstop.robot.config import example_robot_data_share

TIAGO_URDF = (
    example_robot_data_share() / "example-robot-data/robots/tiago_description/robots/tiago.urdf"
)


def random_thetas(robot, n: int, seed: int = 0) -> np.ndarray:
    """``(n, dof)`` joint values uniform within the robot's limits."""
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))


def write_config(folder: Path, text: str, name: str = "robot.yaml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


TIAGO_CONFIG = """
name: mytiago
urdf: {urdf}
arm_joints: [torso_lift_joint, arm_1_joint, arm_2_joint, arm_3_joint, arm_4_joint,
             arm_5_joint, arm_6_joint, arm_7_joint]
tool_frame: hand_grasping_frame
footprint: {{radius: 0.275}}
"""


def assert_stop_verified(planner, scene, stop) -> None:
    """Each witness of ``stop`` reaches its grasp from the stop within 1 mm and 0.5 deg and is
    collision-free for coal: every collision link of the robot (the hand's included, the
    grasped part no obstacle for it) against the scene and the floor (its clearance kept), and
    the robot against itself."""
    import math

    from pickstop.regions.pipeline import tray_world
    from pickstop.robot.kinematics import fk

    c, s_ = math.cos(stop.yaw), math.sin(stop.yaw)
    T_world_base = np.eye(4)
    T_world_base[:2, :2] = [[c, -s_], [s_, c]]
    T_world_base[:2, 3] = stop.x, stop.y
    for w in stop.witnesses:
        tray = scene.tray(w.tray_id)
        k = [p.id for p in tray.parts].index(w.part_id)
        target = planner.grasps(scene, tray)[k].Ts_world_tool[w.grasp_index]
        R, p = fk(planner.solver.chain, np.array([w.theta]))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R[0], p[0]
        got = T_world_base @ T
        assert np.linalg.norm(got[:3, 3] - target[:3, 3]) < 1e-3
        cos = (np.trace(got[:3, :3].T @ target[:3, :3]) - 1) / 2
        assert math.degrees(math.acos(min(1.0, cos))) < 0.5
        _, solids, _, _ = tray_world(planner, scene, tray, stop.yaw)
        theta = np.array(w.theta)
        assert not planner.exact_arm.colliding(
            theta, stop.x, stop.y, stop.yaw, solids, w.part_id, scene.floor_clearance
        )
        assert not planner.exact_self.colliding(theta[None])[0]
        assert w.hand == planner.hand.joints


def assert_cells_verified(planner, scene, region, rows) -> None:
    """Each witness of the region's cells ``rows`` reaches its grasp from the cell's centre
    within 1 mm and 0.5 deg, within the joint limits, and is collision-free for coal (the
    robot's arm against the scene and against itself)."""
    import math

    from pickstop.regions.arm import ExactArm
    from pickstop.robot.artifacts import self_collision
    from pickstop.robot.kinematics import fk
    from pickstop.robot.selfcollision import ExactSelfCollision
    from pickstop.scene.world import scene_solids

    robot = planner.robot
    rows = np.asarray(rows, int)
    if not len(rows):
        return
    grasps = planner.grasps(scene, scene.tray(region.tray_id))
    solids = scene_solids(scene)
    exact_arm = ExactArm(robot)
    exact_self = ExactSelfCollision(robot, self_collision(robot, planner.cache_dir)[0])
    c, s = math.cos(region.yaw), math.sin(region.yaw)
    R_world_base = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    xy = region.grid.centres(region.cells[rows, 1], region.cells[rows, 0])
    for k, gs in enumerate(grasps):
        th = region.thetas[rows, k]
        R, p = fk(planner.solver.chain, th)
        for i in range(len(rows)):
            T_world_tool = gs.Ts_world_tool[region.grasp_index[rows[i], k]]
            pw = R_world_base @ p[i] + [xy[i, 0], xy[i, 1], 0.0]
            assert np.linalg.norm(pw - T_world_tool[:3, 3]) <= 1e-3
            cos = (np.trace((R_world_base @ R[i]).T @ T_world_tool[:3, :3]) - 1) / 2
            assert math.acos(float(np.clip(cos, -1, 1))) <= math.radians(0.5) + 1e-9
            assert (th[i] >= robot.lower - 1e-9).all() and (th[i] <= robot.upper + 1e-9).all()
            assert not exact_arm.colliding(th[i], xy[i, 0], xy[i, 1], region.yaw, solids)
        assert not exact_self.colliding(th).any()
