"""The region kit: the heavy, typed resources every region computation needs, built once.

One robot and one reachability database, and what is derived from them: the batched IK
solver, the sphere covers of the arm and of the robot against itself, the exact (coal) checks
and the open hand's shape. What a computation derives from a scene (grasps, open-hand
spaces, object bounds, each part's grasps judged against its own tray) is asked of a
:class:`~pickstop.regions.keep.Keep` keyed by everything it depends on: the kit keeps
nothing (:meth:`RegionKit.keep`); the region planner of :mod:`pickstop.speedups.region_planner`
keeps them in bounded caches, beside its region caches and the memo of refinements across
tray positions. Within one scene the kit makes its solids, bounds and grasps once.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pickstop.reach.batch_ik import BatchSolver
from pickstop.reach.database import ReachDatabase
from pickstop.regions.arm import SPHERE_EXCESS, ArmSpheres, ExactArm
from pickstop.regions.keep import Keep, KeepNothing
from pickstop.robot.exact import ExactSelfCollision
from pickstop.robot.hand import HandShape, hand_shape
from pickstop.robot.model import RobotModel
from pickstop.robot.screen import SphereModel
from pickstop.runtime.cancel import checkpoint
from pickstop.scene.grasps import (
    GraspSet,
    OwnVerdicts,
    grasps_for_part,
    hand_space,
    own_verdicts,
)
from pickstop.scene.model import Part, Scene, Tray
from pickstop.scene.world import (
    AGREE_MARGIN,
    Groups,
    Solid,
    object_solids,
    other_solids,
    part_solid,
    pose_matrix,
    scene_solids,
    shape_solid,
    tray_body_solids,
)

# axis-aligned (lo, hi) bounds [m] of solids, each with whether the solid is that box
Bounds = list[tuple[np.ndarray, np.ndarray, bool]]
# what a kit builds from its robot and database alone, shared by a scratch kit
_BUILT = frozenset(
    ["robot", "db", "solver", "arm", "self_spheres", "exact_self", "hand", "reach_xy",
     "cache_dir"]
)  # fmt: skip


@dataclass
class _SceneMemo:
    """What a plan asks about one scene many times (scenes are frozen: kept by the scene
    object): the solids of each object, every object's bounds with its tray id (None: an
    obstacle), the grasps by tray."""

    scene: Scene
    groups: Groups | None = None
    bounds: list[tuple[str | None, str, Bounds]] | None = None
    grasps: dict[str, list[GraspSet]] = field(default_factory=dict)


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
    cache_dir: Path | None = None  # per-robot derived data (disabled pairs, screen)
    # what the kit keeps between computations (:meth:`keep`), by the keys it asks with
    grasp_memo: Keep[str, GraspSet] = field(default_factory=KeepNothing, init=False, repr=False)
    _hand_spaces: Keep[str, tuple[np.ndarray, np.ndarray]] = field(
        default_factory=KeepNothing, init=False, repr=False
    )
    _bounds: Keep[str, Bounds] = field(default_factory=KeepNothing, init=False, repr=False)
    # each part's grasps judged against its own tray alone, wherever the tray stands
    _own_verdicts: Keep[str, OwnVerdicts] = field(
        default_factory=KeepNothing, init=False, repr=False
    )
    # what a plan asks about its scene many times, made once for the last scene asked about
    _scene_memo: _SceneMemo | None = field(default=None, init=False, repr=False)

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
        self.exact_arm = ExactArm(self.robot, self.arm, bounds=self.keep("arm.solid_bounds"))
        self.reach_xy = self.db.reach_xy
        self.grasp_memo = self.keep("kit.grasps")
        self._hand_spaces = self.keep("kit.hand_spaces")
        self._bounds = self.keep("kit.object_bounds")
        self._own_verdicts = self.keep("kit.own_verdicts")

    def keep(self, name: str) -> Keep[Any, Any]:
        """Where the kit keeps what it derives under ``name`` between computations: nothing
        (every answer is made anew). The region planner keeps each in a bounded cache."""
        return KeepNothing()

    def scratch(self) -> RegionKit:
        """A kit of the same robot and database sharing what is built from them alone (the
        solver, the sphere covers, the self-collision checks, the hand), with exact arm
        checks of its own, keeping nothing and none of a subclass's caches: what it computes
        depends on its arguments alone. (The footprint's blocked regions go with the robot:
        where a region planner of it hung its caches there, this kit reads them too; they are
        pure functions of their keys, so the answers are the same.)"""
        out = object.__new__(RegionKit)
        for f in dataclasses.fields(RegionKit):
            if f.name in _BUILT:
                value = getattr(self, f.name)
            elif f.default_factory is not dataclasses.MISSING:
                value = f.default_factory()
            else:
                value = f.default
            setattr(out, f.name, value)
        out.exact_arm = ExactArm(self.robot, self.arm)
        return out

    def checkpoint(self) -> None:
        """Raise :class:`~pickstop.runtime.cancel.Cancelled` if the computation under way is
        to stop (its token: :func:`pickstop.runtime.cancel.checkpoint`). Called between the
        steps of a region (parts, rounds, waves of growth), where every memo is whole: what
        was done so far stays remembered for the next computation."""
        checkpoint()

    def grasps(self, scene: Scene, tray: Tray) -> list[GraspSet]:
        """The grasps of every part of ``tray``, reused while nothing that reaches into the
        space of its open hands changes (other trays elsewhere may move freely). They are
        fixed in the tray's frame: where nothing else reaches into that space, a tray moved
        along the floor keeps them, carried with it."""
        if scene.tray(tray.id) is not tray:  # a tray not of this scene (as it stands)
            return self._grasps(scene, tray)
        by_tray = self._memo(scene).grasps
        if tray.id not in by_tray:
            by_tray[tray.id] = self._grasps(scene, tray)
        return list(by_tray[tray.id])

    def _grasps(self, scene: Scene, tray: Tray) -> list[GraspSet]:
        others = self._bounds_of(scene, tray.id)
        at = _floor_position(tray)
        tray_json = _placed(tray)
        gripper_json = f"{scene.gripper.model_dump_json()}{self.hand.key}|{scene.floor_clearance}"
        out = []
        foreign: list[Solid] | None = None  # the rest of the scene, made if a part needs it
        turnable = _turnable(tray)
        for part in tray.parts:
            key = f"{tray_json}|{part.id}|{gripper_json}"
            own_key = f"{turnable}|{part.id}|{gripper_json}"
            space = self.hand_space(scene, tray, part)
            near = _reaching_in(others, space, at)
            full = hashlib.sha256("|".join([key, *sorted(near)]).encode()).hexdigest()
            found = self.grasp_memo.get(full)
            if found is None:
                own = self._own_verdicts.get_or_make(
                    own_key, lambda part=part: own_verdicts(scene, tray, part, self.hand)
                )
                if foreign is None:
                    foreign = other_solids(scene, tray, self.object_solids(scene))
                found = self.grasp_memo.put(
                    full,
                    _moved_by(grasps_for_part(scene, tray, part, self.hand, own, foreign), -at),
                )
            out.append(_moved_by(found, at))
        return out

    def _memo(self, scene: Scene) -> _SceneMemo:
        """The memo of ``scene`` (a new one if the last scene asked about was another)."""
        last = self._scene_memo
        if last is None or last.scene is not scene:
            last = self._scene_memo = _SceneMemo(scene)
        return last

    def object_solids(self, scene: Scene) -> Groups:
        """:func:`~pickstop.scene.world.object_solids` of ``scene``, made once for the last
        scene asked about (a plan asks for them many times; scenes are frozen)."""
        memo = self._memo(scene)
        if memo.groups is None:
            memo.groups = object_solids(scene)
        return memo.groups

    def solids_of(self, scene: Scene) -> list[Solid]:
        """Every solid of ``scene`` (:meth:`object_solids`)."""
        return scene_solids(scene, groups=self.object_solids(scene))

    def learn_grasps(self, entries: dict[str, GraspSet]) -> None:
        """Keep grasps another process computed (:mod:`pickstop.runtime.region_processes`), by the
        keys :meth:`grasps` finds them by."""
        for key, grasps in entries.items():
            self.grasp_memo.put(key, grasps)

    def hand_space(self, scene: Scene, tray: Tray, part: Part) -> tuple[np.ndarray, np.ndarray]:
        """:func:`pickstop.scene.grasps.hand_space`, computed once per tray (wherever it
        stands on the floor), part and hand."""
        key = f"hand|{_placed(tray)}|{part.id}|{scene.gripper.model_dump_json()}"
        at = _floor_position(tray)

        def make() -> tuple[np.ndarray, np.ndarray]:
            lo, hi = hand_space(scene, tray, part, self.hand)
            return lo - at, hi - at

        lo, hi = self._hand_spaces.get_or_make(key, make)
        return lo + at, hi + at

    def objects_near(self, scene: Scene, tray: Tray, radius: float) -> list[str]:
        """The definitions of the objects but ``tray`` with a solid whose bounding box comes
        within ``radius`` [m] of the tray's centre in the floor plane."""
        c = np.array([tray.pose.x, tray.pose.y])
        out = []
        for d, bounds in self._bounds_of(scene, tray.id):
            for lo, hi, _ in bounds:
                gap = np.maximum(np.maximum(lo[:2] - c, c - hi[:2]), 0.0)
                if float(np.hypot(*gap)) <= radius:
                    out.append(d)
                    break
        return out

    def _bounds_of(self, scene: Scene, exclude: str) -> list[tuple[str, Bounds]]:
        """Every object but the tray ``exclude``: its definition and its solids' bounds, each
        with whether the solid is an axis-aligned box (its bounds are the box); the objects
        of a scene listed once (by the scene object, as its grasps are)."""
        memo = self._memo(scene)
        if memo.bounds is None:
            memo.bounds = self._objects_bounds(scene)
        return [(d, b) for tid, d, b in memo.bounds if tid != exclude]

    def _objects_bounds(self, scene: Scene) -> list[tuple[str | None, str, Bounds]]:
        out: list[tuple[str | None, str, Bounds]] = []
        for o in scene.obstacles:
            d = o.model_dump_json()
            b = self._bounds.get_or_make(
                d, lambda o=o: [_bounds(shape_solid(o.geometry, pose_matrix(o.pose), o.id))]
            )
            out.append((None, d, b))
        for t in scene.trays:
            d = t.model_dump_json()
            b = self._bounds.get_or_make(
                d, lambda t=t: [_bounds(s) for s in tray_body_solids(t) + [part_solid(t, p)
                                                                        for p in t.parts]]
            )  # fmt: skip
            out.append((t.id, d, b))
        return out


def _bounds(s: Solid) -> tuple[np.ndarray, np.ndarray, bool]:
    lo, hi = s.aabb()
    return lo, hi, s.aligned_box


def _reaching_in(
    others: list[tuple[str, Bounds]], space: tuple[np.ndarray, np.ndarray], at: np.ndarray
) -> list[str]:
    """What of ``others`` reaches into the open hands' ``space`` (world bounds [m]), as the
    grasps see it from a tray standing at ``at: (3,)``: an axis-aligned box by the part of it
    inside the space (padded by :data:`~pickstop.scene.world.AGREE_MARGIN`), relative to the
    tray (a table the tray slides along looks the same); any other solid by its object's
    definition and the tray's place."""
    lo, hi = space[0] - AGREE_MARGIN, space[1] + AGREE_MARGIN
    out: list[str] = []
    if not others:
        return out
    # a first look at every solid at once: most objects are far from the hands
    flat = [(k, b_lo, b_hi) for k, (_, bounds) in enumerate(others) for b_lo, b_hi, _ in bounds]
    all_lo = np.array([b[1] for b in flat]).reshape(-1, 3)
    all_hi = np.array([b[2] for b in flat]).reshape(-1, 3)
    meets = np.all(all_lo <= hi, axis=1) & np.all(lo <= all_hi, axis=1)
    near = sorted({flat[i][0] for i in np.flatnonzero(meets).tolist()})
    for d, bounds in (others[k] for k in near):
        if all(aligned for *_, aligned in bounds):
            for b_lo, b_hi, _ in bounds:
                c_lo, c_hi = np.maximum(b_lo, lo) - at, np.minimum(b_hi, hi) - at
                if np.all(c_lo <= c_hi):
                    out.append(f"box {np.round(c_lo, 9).tolist()} {np.round(c_hi, 9).tolist()}")
        else:
            out.append(f"{d} seen from {at[0]!r}, {at[1]!r}")
    return out


def _floor_position(tray: Tray) -> np.ndarray:
    """``(3,)`` [m] where the tray stands on the floor: its x, y (z 0)."""
    return np.array([tray.pose.x, tray.pose.y, 0.0])


def _placed(tray: Tray) -> str:
    """The tray's definition but for where it stands on the floor (its x and y)."""
    return tray.model_dump_json(exclude={"pose": {"x", "y"}})


def _turnable(tray: Tray) -> str:
    """The tray's definition but for where it stands and how it is turned about the vertical
    (its x, y and yaw): what its own verdicts depend on (:class:`OwnVerdicts`)."""
    return tray.model_dump_json(exclude={"pose": {"x", "y", "yaw"}})


def _moved_by(gs: GraspSet, d: np.ndarray) -> GraspSet:
    """The grasps ``gs`` of a tray moved by ``d: (3,)`` [m] (the grasp points stay)."""
    T = gs.Ts_world_tool.copy()
    T[:, :3, 3] += d
    return dataclasses.replace(gs, Ts_world_tool=T)
