"""The region kit: the heavy, typed resources every region computation needs, built once.

One robot and one reachability database, and what is derived from them: the batched IK
solver, the sphere covers of the arm and of the robot against itself, the exact (coal) checks
and the open hand's shape. Beside them the memos of what a computation derives from a scene
(grasps, open-hand spaces, refinements across tray positions); each is keyed by everything it
depends on, so none needs invalidating. Region caches live in :mod:`pickstop.regions.planner`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pickstop.reach.batch_ik import BatchSolver
from pickstop.reach.database import ReachDatabase
from pickstop.regions.arm import SPHERE_EXCESS, ArmSpheres, ExactArm
from pickstop.regions.reuse import ReuseCache
from pickstop.robot.exact import ExactSelfCollision
from pickstop.robot.hand import HandShape, hand_shape
from pickstop.robot.model import RobotModel
from pickstop.robot.screen import SphereModel
from pickstop.scene.grasps import GraspSet, grasps_for_part, hand_space
from pickstop.scene.model import Part, Scene, Tray
from pickstop.scene.world import part_solid, pose_matrix, shape_solid, tray_body_solids

Bounds = list[tuple[np.ndarray, np.ndarray]]  # axis-aligned (lo, hi) boxes [m]
MEMO_SIZE = 4096  # open-hand spaces and object bounds kept, each


@dataclass
class RegionKit:
    """What region computation needs of one robot and database, built once (see the module)."""

    robot: RobotModel
    db: ReachDatabase
    solver: BatchSolver = field(init=False)
    arm: ArmSpheres = field(init=False)  # the arm's links against the scene (sphere screen)
    self_spheres: SphereModel = field(init=False)  # the robot against itself (sphere screen)
    exact_self: ExactSelfCollision = field(init=False)
    exact_arm: ExactArm = field(init=False)
    hand: HandShape = field(init=False)
    reach_xy: float = field(init=False)  # [m] the database's horizontal reach
    grasp_cache: dict[str, GraspSet] = field(default_factory=dict)
    reuse: ReuseCache = field(default_factory=ReuseCache)  # refinements across tray positions
    cache_dir: Path | None = None  # per-robot derived data (disabled pairs, screen)
    _hand_spaces: dict[str, tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict, init=False, repr=False
    )
    _bounds: dict[str, Bounds] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        from pickstop.robot.artifacts import derived, self_collision

        self.solver = BatchSolver.of(self.robot)
        self.hand = hand_shape(self.robot)
        # Covering the arm links takes about a second: made once per robot, kept on disk.
        self.arm = derived(
            self.robot,
            self.cache_dir,
            f"arm-spheres-{SPHERE_EXCESS}",
            lambda: ArmSpheres.of(self.robot),
        )
        disabled, self.self_spheres = self_collision(self.robot, self.cache_dir)
        self.exact_self = ExactSelfCollision(self.robot, disabled)
        self.exact_arm = ExactArm(self.robot)
        self.reach_xy = self.db.reach_xy

    def grasps(self, scene: Scene, tray: Tray) -> list[GraspSet]:
        """The grasps of every part of ``tray``, reused while nothing that reaches into the
        space of its open hands changes (other trays elsewhere may move freely)."""
        others = self._bounds_of(scene, tray.id)
        tray_json = tray.model_dump_json()
        gripper_json = f"{scene.gripper.model_dump_json()}{self.hand.key}|{scene.floor_clearance}"
        out = []
        for part in tray.parts:
            key = f"{tray_json}|{part.id}|{gripper_json}"
            space = self.hand_space(scene, tray, part)
            near = [d for d, bounds in others if any(_overlap(b, space) for b in bounds)]
            full = hashlib.sha256("|".join([key, *sorted(near)]).encode()).hexdigest()
            if full not in self.grasp_cache:
                self.grasp_cache[full] = grasps_for_part(scene, tray, part, self.hand)
            out.append(self.grasp_cache[full])
        return out

    def hand_space(self, scene: Scene, tray: Tray, part: Part) -> tuple[np.ndarray, np.ndarray]:
        """:func:`pickstop.scene.grasps.hand_space`, computed once per tray, part and hand."""
        key = f"hand|{tray.model_dump_json()}|{part.id}|{scene.gripper.model_dump_json()}"
        if key not in self._hand_spaces:
            if len(self._hand_spaces) >= MEMO_SIZE:
                self._hand_spaces.clear()
            self._hand_spaces[key] = hand_space(scene, tray, part, self.hand)
        return self._hand_spaces[key]

    def _bounds_of(self, scene: Scene, exclude: str) -> list[tuple[str, Bounds]]:
        """Every object but the tray ``exclude``: its definition and its solids' bounds."""
        if len(self._bounds) > MEMO_SIZE:
            self._bounds.clear()
        out = []
        for o in scene.obstacles:
            d = o.model_dump_json()
            if d not in self._bounds:
                self._bounds[d] = [shape_solid(o.geometry, pose_matrix(o.pose), o.id).aabb()]
            out.append((d, self._bounds[d]))
        for t in scene.trays:
            if t.id != exclude:
                d = t.model_dump_json()
                if d not in self._bounds:
                    solids = tray_body_solids(t) + [part_solid(t, p) for p in t.parts]
                    self._bounds[d] = [s.aabb() for s in solids]
                out.append((d, self._bounds[d]))
        return out


def _overlap(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    return bool(np.all(a[0] <= b[1]) and np.all(b[0] <= a[1]))
