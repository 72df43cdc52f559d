"""Assertions shared by the region tests."""

from __future__ import annotations

import numpy as np

from pickstop.regions.arm import ExactArm
from pickstop.robot.kinematics import Chain, fk
from pickstop.scene.world import scene_solids


def assert_verified(tiago, planner, scene, tray_id, xy, yaw, thetas, grasp_index):
    """Each witness ``thetas: (N, P, dof)`` on its base ``xy: (N, 2)`` reaches its grasp's
    tool pose, keeps the joint limits and is free of the scene and of itself (exact)."""
    from pickstop.robot.artifacts import self_collision
    from pickstop.robot.selfcollision import ExactSelfCollision

    chain = Chain.from_robot(tiago)
    grasps = planner.grasps(scene, scene.tray(tray_id))
    solids = scene_solids(scene)
    exact_arm = ExactArm(tiago)
    exact_self = ExactSelfCollision(tiago, self_collision(tiago, planner.cache_dir)[0])
    c, s = np.cos(yaw), np.sin(yaw)
    for k, gs in enumerate(grasps):
        th = thetas[:, k]
        R, p = fk(chain, th)
        for i in range(len(th)):
            T_wt = gs.Ts_world_tool[grasp_index[i, k]]
            # The tool pose in the world from the witness on its base.
            Rw = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ R[i]
            pw = np.array(
                [
                    c * p[i, 0] - s * p[i, 1] + xy[i, 0],
                    s * p[i, 0] + c * p[i, 1] + xy[i, 1],
                    p[i, 2],
                ]
            )
            assert np.linalg.norm(pw - T_wt[:3, 3]) <= 1e-3
            cosang = (np.trace(Rw.T @ T_wt[:3, :3]) - 1) / 2
            assert np.arccos(np.clip(cosang, -1, 1)) <= np.radians(0.5) + 1e-9
            assert (th[i] >= tiago.lower - 1e-9).all() and (th[i] <= tiago.upper + 1e-9).all()
            assert not exact_arm.colliding(th[i], xy[i, 0], xy[i, 1], yaw, solids)
        assert not exact_self.colliding(th).any()
