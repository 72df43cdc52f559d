"""The compiled kernels loaded before the first region: each run once on one configuration."""

from __future__ import annotations

import numpy as np

from pickstop.reach.batch_ik import refine_batch
from pickstop.regions.arm import screen_arm
from pickstop.regions.kit import RegionKit
from pickstop.robot.kinematics import fk_soa
from pickstop.robot.selfcollision import screen as screen_self
from pickstop.scene.world import BoxArrays, Solid
from pickstop.speedups.checked import CheckedConfigs, group_boxes_of
from pickstop.speedups.region_memo import Change, ChangeSet


def warm_kernels(kit: RegionKit) -> None:
    """Run each compiled kernel once on one configuration and one box: they load now
    (compiled once per checkout, then read from numba's cache), not in the first region."""
    theta = np.zeros((1, kit.robot.dof))
    _, _, frames = fk_soa(kit.solver.chain, theta.T.copy(), frames=True)
    solids = [Solid.box(np.eye(4), np.ones(3), "warm-up")]
    boxes = BoxArrays.of(solids)
    screen_arm(kit.arm, boxes, frames, np.zeros((1, 2)), 0.0)
    screen_self(kit.self_spheres, frames)
    kit.exact_arm.colliding(theta[0], 0.0, 0.0, 0.0, solids, boxes=boxes)
    change = Change(-np.ones(3), np.ones(3))
    ChangeSet.of([change]).hit(np.zeros((1, 3)), np.ones((1, 3)))
    group_boxes_of(kit, theta, np.zeros((1, 2)), 0.0, np.zeros(1, int), 1)
    CheckedConfigs(kit, theta, np.zeros((1, 2)), 0.0, np.zeros(1, int)).touched_by(
        [change], [np.zeros(1, int)]
    )
    refine_batch(kit.solver, theta, np.eye(3)[None], np.zeros((1, 3)), give_up=((1, 1.0),))
