"""The arm against the scene: conservative spheres (a compiled screen) and exact coal checks.

Links are every collision link of the reduced model that moves with the arm (joints 1..n),
the hand's own links included at their pre-grasp joint values. The part being grasped is no
obstacle for the hand links (``target``); everything else is, for every link. The floor is an
obstacle too (``floor``: the clearance every link keeps above it [m]), for the arm's links and
for the hand, its own links or the boxes that stand in for them (:mod:`pickstop.robot.floor`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from pickstop import frames
from pickstop.frames import rot2
from pickstop.regions.arm_kernel import contacts_many, link_contacts, screen_links
from pickstop.regions.envelope import Envelope
from pickstop.regions.keep import Keep, KeepNothing
from pickstop.robot.fk_kernel import joint_frames
from pickstop.robot.floor import FLOOR_CLEARANCE, ExactFloor, FloorSpheres, below_floor
from pickstop.robot.kinematics import Chain
from pickstop.robot.link_geometry import arm_links, is_hand_link
from pickstop.robot.model import RobotModel
from pickstop.scene.world import TOUCH, BoxArrays, Solid, _coal, collide

SPHERE_EXCESS = 0.01  # [m] how far a covering sphere may stick out of its link


def arm_geometry_ids(robot: RobotModel) -> list[int]:
    """Collision geometries on moving arm bodies, the hand's included."""
    return sorted(i for link in arm_links(robot) for i in link.geometry_ids)


def owner_codes(
    boxes: BoxArrays, targets: Sequence[str] | np.ndarray | str | None, n: int
) -> np.ndarray:
    """``(n,)`` per configuration, the index code of the owner its hand may touch (-1: none)."""
    codes = boxes.owner_index
    if targets is None:
        return np.full(n, -1)
    if isinstance(targets, str):
        return np.full(n, codes.get(targets, -1))
    assert len(targets) == n, (len(targets), n)
    return np.array([codes.get(t, -1) for t in targets], dtype=np.int64)


@dataclass(frozen=True)
class JointGroups:
    """An arm's covering spheres grouped by joint: J groups."""

    joints: np.ndarray  # (J,) joint index (1..n) of each group
    leaves: list[np.ndarray]  # (J,) the covering spheres of each group
    links: list[np.ndarray]  # (J,) the links of each group
    lo: np.ndarray  # (J, 3) [m] a box around each group's spheres, in its joint's frame
    hi: np.ndarray  # (J, 3)


@dataclass(frozen=True)
class ArmSpheres:
    """Covering spheres of the arm links in their joint frames, grouped per link."""

    link_joint: np.ndarray  # (L,) joint index (1..n) carrying each link
    is_hand: np.ndarray  # (L,) bool: a hand link (the grasped part is no obstacle for it)
    bound_c: np.ndarray  # (L, 3) bounding sphere of each link [m]
    bound_r: np.ndarray  # (L,)
    leaf_link: np.ndarray  # (S,) link of each covering sphere
    leaf_c: np.ndarray  # (S, 3)
    leaf_r: np.ndarray  # (S,)
    floor: FloorSpheres  # the leaves, and the stand-in hand's hull points, per joint

    @functools.cached_property
    def leaf_start(self) -> np.ndarray:
        """``(L,)`` index of each link's first leaf (leaves are stored link by link)."""
        return np.searchsorted(self.leaf_link, np.arange(len(self.bound_r)))

    @functools.cached_property
    def leaf_count(self) -> np.ndarray:
        """``(L,)`` how many leaves cover each link."""
        return np.bincount(self.leaf_link, minlength=len(self.bound_r))

    @functools.cached_property
    def link_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """``lo, hi: (L, 3)`` [m] each link's covering spheres bounded by a box in its joint's
        frame."""
        start = self.leaf_start
        return (
            np.minimum.reduceat(self.leaf_c - self.leaf_r[:, None], start),
            np.maximum.reduceat(self.leaf_c + self.leaf_r[:, None], start),
        )

    @functools.cached_property
    def joint_groups(self) -> JointGroups:
        """The covering spheres grouped by the joint that carries them (the hand's links all
        ride on the last one)."""
        leaf_joint = self.link_joint[self.leaf_link]
        joints = np.unique(leaf_joint)
        leaves = [np.flatnonzero(leaf_joint == j) for j in joints]
        return JointGroups(
            joints,
            leaves,
            [np.unique(self.leaf_link[k]) for k in leaves],
            np.array([(self.leaf_c[k] - self.leaf_r[k, None]).min(0) for k in leaves]),
            np.array([(self.leaf_c[k] + self.leaf_r[k, None]).max(0) for k in leaves]),
        )

    @functools.cached_property
    def group_joint(self) -> np.ndarray:
        """``(J,)`` int64: the 0-based joint of each of :attr:`joint_groups`."""
        return (self.joint_groups.joints - 1).astype(np.int64)

    @functools.cached_property
    def link_group(self) -> np.ndarray:
        """``(L,)`` int64: which of :attr:`joint_groups` each link is in (-1: it has no leaves)."""
        out = np.full(len(self.bound_r), -1, np.int64)
        for g, links in enumerate(self.joint_groups.links):
            out[links] = g
        return out

    @classmethod
    def of(cls, robot: RobotModel, excess: float = SPHERE_EXCESS) -> ArmSpheres:
        from pickstop.robot.link_geometry import LinkShape
        from pickstop.robot.spheres import cover

        joints, hand, bc, br, ll, lc, lr = [], [], [], [], [], [], []
        for k, link in enumerate(arm_links(robot)):
            hand.append(is_hand_link(robot, link.name))
            s = cover(LinkShape.of(robot, tuple(link.geometry_ids)), excess)
            c = s[:, :3].mean(axis=0)
            r = float(np.max(np.linalg.norm(s[:, :3] - c, axis=1) + s[:, 3]))
            joints.append(link.joint)
            bc.append(c)
            br.append(r)
            ll += [k] * len(s)
            lc.append(s[:, :3])
            lr.append(s[:, 3])
        floor = FloorSpheres.with_hand(
            robot, np.array(joints)[np.array(ll)], np.concatenate(lc), np.concatenate(lr)
        )
        return cls(
            np.array(joints),
            np.array(hand, dtype=bool),
            np.array(bc),
            np.array(br),
            np.array(ll),
            np.concatenate(lc),
            np.concatenate(lr),
            floor,
        )


def points_to_world(
    frames: list[tuple[np.ndarray, np.ndarray]],
    joint: np.ndarray,
    local: np.ndarray,
    base_xy: np.ndarray,
    yaw: float,
) -> np.ndarray:
    """Points ``local: (P, 3)`` on joints ``joint: (P,)`` for every configuration -> (B, P, 3)."""
    R = np.stack([frames[j - 1][0] for j in joint])  # (P, 3, 3, B)
    p = np.stack([frames[j - 1][1] for j in joint])  # (P, 3, B)
    pts = np.einsum("pikb,pk->bpi", R, local) + p.transpose(2, 0, 1)
    R = rot2(yaw)  # written out per entry: twice as fast as a stacked matmul
    out = np.empty_like(pts)
    out[..., 0] = R[0, 0] * pts[..., 0] + R[0, 1] * pts[..., 1] + base_xy[:, None, 0]
    out[..., 1] = R[1, 0] * pts[..., 0] + R[1, 1] * pts[..., 1] + base_xy[:, None, 1]
    out[..., 2] = pts[..., 2]
    return out


def screen_arm(
    spheres: ArmSpheres,
    boxes: BoxArrays,
    frames: list[tuple[np.ndarray, np.ndarray]],
    base_xy: np.ndarray,
    yaw: float,
    envelope: Envelope | None = None,
    targets: Sequence[str] | np.ndarray | str | None = None,
    floor: float | None = None,
) -> np.ndarray:
    """``(B,)`` True where the arm may touch a solid or the floor; False is guaranteed free.

    frames: :func:`fk_soa` joint frames of B configurations (base frame); base_xy: (B, 2).
    envelope: if given, the owners of the solids that flagged a configuration are recorded.
    targets: the part each configuration grasps (one for all, or one per configuration): no
    obstacle for the hand links. floor: the clearance [m] every link and the hand keep above
    the floor (None: the floor is not checked).
    """
    B = base_xy.shape[0]
    if B == 0:
        return np.zeros(B, bool)
    flagged = np.zeros(B, bool) if floor is None else below_floor(spheres.floor, frames, floor)
    if len(boxes.centres) == 0:
        return flagged
    code = owner_codes(boxes, targets, B)  # (B,)
    box_hit = np.zeros(len(boxes.centres), bool)
    screen_links(
        np.stack([R for R, _ in frames]),
        np.stack([p for _, p in frames]),
        spheres.link_joint - 1,
        spheres.bound_c,
        spheres.bound_r,
        spheres.is_hand,
        spheres.leaf_start,
        spheres.leaf_count,
        spheres.leaf_c,
        spheres.leaf_r,
        np.ascontiguousarray(base_xy, dtype=float),
        math.cos(yaw),
        math.sin(yaw),
        boxes.centres,
        boxes.R,
        boxes.half,
        boxes.is_cylinder,
        boxes.radius,
        boxes.lo,
        boxes.hi,
        boxes.owner_codes,
        code,
        TOUCH,
        spheres.group_joint,
        spheres.joint_groups.lo,
        spheres.joint_groups.hi,
        spheres.link_group,
        flagged,
        box_hit,
    )
    if envelope is not None:
        envelope.hit_owners.update(boxes.owners[k] for k in np.flatnonzero(box_hit))
    return flagged


class ExactArm:
    """Exact arm-versus-solids checks with coal (one per thread)."""

    def __init__(
        self,
        robot: RobotModel,
        spheres: ArmSpheres | None = None,
        bounds: Keep[tuple[Solid, ...], tuple[np.ndarray, ...]] | None = None,
    ) -> None:
        """spheres: the arm's covering spheres; with them, :meth:`colliding` hands coal only
        the geometries of links whose spheres meet a solid (given the solids' boxes).
        bounds: where the bounding boxes of the solid lists checked against are kept (by the
        lists' identity; :class:`~pickstop.regions.keep.KeepNothing` if not given)."""
        self.robot = robot
        self.data = robot.model.createData()
        self.ids = arm_geometry_ids(robot)
        self.spheres = spheres
        pos = {g: k for k, g in enumerate(self.ids)}
        # per covering-sphere link (ArmSpheres' order), its geometries' indices among ids
        self.link_geoms = [[pos[g] for g in lk.geometry_ids] for lk in arm_links(robot)]
        assert spheres is None or len(spheres.bound_r) == len(self.link_geoms)
        names = {g: lk.name for lk in arm_links(robot) for g in lk.geometry_ids}
        self.hand = np.array([is_hand_link(robot, names[i]) for i in self.ids], bool)
        self.geometries = [robot.geom_model.geometryObjects[i].geometry for i in self.ids]
        centres, halves = [], []
        for geom in self.geometries:
            geom.computeLocalAABB()
            lo, hi = np.asarray(geom.aabb_local.min_), np.asarray(geom.aabb_local.max_)
            centres.append((lo + hi) / 2)
            halves.append((hi - lo) / 2)
        # (G, 3) each: the local bounding box of every checked geometry
        self.local_c = np.array(centres).reshape(-1, 3)
        self.local_h = np.array(halves).reshape(-1, 3)
        self.floor = ExactFloor(robot)
        assert self.floor.ids == self.ids  # one placement of the geometries serves both
        # (G, 3, 3), (G, 3): where the geometries are after :meth:`place` (base frame)
        self.R = np.zeros((len(self.ids), 3, 3))
        self.p = np.zeros((len(self.ids), 3))
        self.M = np.tile(np.eye(4), (robot.model.njoints, 1, 1))  # and the joints
        # the chain's FK stands for pinocchio's where the model's joints are the chain's
        self._chain = Chain.from_robot(robot) if robot.model.njoints == robot.dof + 1 else None
        self._axis_index = np.zeros(0, np.int64)
        if self._chain is not None:
            self._axis_index = self._chain.axis_index.astype(np.int64)
        self._Rj = np.zeros((robot.dof, 3, 3))
        self._pj = np.zeros((robot.dof, 3))
        self._bounds_memo = bounds if bounds is not None else KeepNothing()
        pl = self.floor.placements  # contiguous, for the compiled placements of :meth:`checks`
        self._R_local = np.ascontiguousarray(pl.R_local)
        self._p_local = np.ascontiguousarray(pl.p_local)

    def below_floor(self, clearance: float) -> list[str]:
        """After :meth:`place`: the arm geometries, and the stand-in hand boxes
        (``hand:<k>``), reaching ``z <= clearance`` [m] (the floor is z = 0 of the base)."""
        return self.floor.placed_below(self.M, self.R, self.p, clearance)

    def place(self, theta: np.ndarray) -> None:
        """Forward kinematics and geometry placements (base frame) of ``theta: (dof,)``: the
        chain's own FK, compiled (the one the screens and the IK use, tested against
        pinocchio's), or pinocchio's where the model has joints beyond the chain."""
        if self._chain is None:
            q = self.robot.angles_to_q(theta)
            pin.forwardKinematics(self.robot.model, self.data, q)
            self.M = self.floor.placements.joints(self.data)  # (njoints, 4, 4)
        else:
            c = self._chain
            joint_frames(
                c.R_parent_joint, c.p_parent_joint, self._axis_index, c.axes, c.prismatic,
                np.ascontiguousarray(theta, dtype=float), self._Rj, self._pj,
            )  # fmt: skip
            self.M[1:, :3, :3] = self._Rj
            self.M[1:, :3, 3] = self._pj
        self.R, self.p = self.floor.placements.of(self.data, self.M)

    def colliding(
        self,
        theta: np.ndarray,
        x: float,
        y: float,
        yaw: float,
        solids: list[Solid],
        target: str | None = None,
        floor: float | None = None,
        boxes: BoxArrays | None = None,
    ) -> bool:
        """Does the arm at ``theta`` on a base at ``(x, y, yaw)`` touch any of ``solids``, or
        come within ``floor`` [m] of the floor (None: the floor is not checked)?

        target: the part being grasped, no obstacle for the hand links. Only the (geometry,
        solid) pairs whose world bounding boxes overlap go to coal; given ``boxes`` (the
        solids as :class:`BoxArrays`, in order) and the covering spheres, only the geometries
        of each link whose covering spheres meet a solid's box, against that solid: the
        spheres hold the link, so no other pair can touch.
        """
        self.place(theta)
        if floor is not None and self.below_floor(floor):
            return True
        if not solids or not self.ids:
            return False
        if boxes is not None and self.spheres is not None:
            return self._sphere_pairs_collide(x, y, yaw, solids, target, boxes)
        R_world_base = frames.R_z(yaw)
        R = R_world_base @ self.R  # (G, 3, 3) R_world_geom
        p = self.p @ R_world_base.T + np.array([x, y, 0.0])  # (G, 3) p_world_geom
        c = np.einsum("gij,gj->gi", R, self.local_c) + p
        h = np.einsum("gij,gj->gi", np.abs(R), self.local_h)
        lo, hi, owners = self._bounds(solids)
        # Geometry g and solid k can touch only where their world bounding boxes overlap.
        near = ~(
            ((c - h)[:, None] > hi[None]).any(axis=2) | ((c + h)[:, None] < lo[None]).any(axis=2)
        )  # (G, S)
        if target is not None:
            near &= ~(self.hand[:, None] & (owners == target)[None])
        for k, j in zip(*np.nonzero(near), strict=True):
            gs, ts = _coal(solids[j])
            if collide(self.geometries[k], coal.Transform3s(R[k], p[k]), gs, ts):
                return True
        return False

    def _sphere_pairs_collide(
        self, x: float, y: float, yaw: float, solids: list[Solid], target: str | None,
        boxes: BoxArrays,
    ) -> bool:  # fmt: skip
        """After :meth:`place`: coal for the (link geometry, solid) pairs whose covering
        spheres meet (:func:`~pickstop.regions.arm_kernel.link_contacts`)."""
        sp = self.spheres
        assert sp is not None and len(boxes.owners) == len(solids)
        L, K = len(sp.bound_r), len(solids)
        out_link = np.empty(L * K, np.int64)
        out_box = np.empty(L * K, np.int64)
        n = link_contacts(
            self.M, sp.link_joint, sp.bound_c, sp.bound_r, sp.is_hand, sp.leaf_start,
            sp.leaf_count, sp.leaf_c, sp.leaf_r, float(x), float(y), math.cos(yaw),
            math.sin(yaw), boxes.centres, boxes.R, boxes.half, boxes.is_cylinder, boxes.radius,
            boxes.lo, boxes.hi, boxes.owner_codes,
            -1 if target is None else boxes.owner_index.get(target, -1), TOUCH, out_link, out_box,
        )  # fmt: skip
        if n == 0:
            return False
        R_world_base = frames.R_z(yaw)
        shift = np.array([x, y, 0.0])
        for lk, k in zip(out_link[:n].tolist(), out_box[:n].tolist(), strict=True):
            gs, ts = _coal(solids[k])
            for g in self.link_geoms[lk]:
                R = R_world_base @ self.R[g]
                p = R_world_base @ self.p[g] + shift
                if collide(self.geometries[g], coal.Transform3s(R, p), gs, ts):
                    return True
        return False

    def checks(
        self,
        thetas: np.ndarray,
        base_xy: np.ndarray,
        yaw: float,
        solids: list[Solid],
        targets: Sequence[str] | np.ndarray | str | None,
        floor: float | None,
        boxes: BoxArrays,
    ) -> ArmChecks:
        """:meth:`colliding` of many configurations ``thetas: (B, dof)`` on bases
        ``base_xy: (B, 2)`` at ``yaw``, the hand of each free to touch ``targets`` (one part
        for all, or one per row), asked row by row (:meth:`ArmChecks.colliding`): what
        needs no coal (the joints, the placements, which link spheres meet which solid, the
        floor's bounds tests) is done for all rows at once, compiled where it loops."""
        return ArmChecks(self, np.asarray(thetas, float), np.asarray(base_xy, float), yaw,
                         solids, targets, floor, boxes)  # fmt: skip

    def _bounds(self, solids: list[Solid]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World bounding boxes ``lo, hi: (S, 3)`` [m] and owners ``(S,)`` of ``solids``, kept
        in the arm's ``bounds`` (the same solids are checked against many configurations)."""

        def make() -> tuple[np.ndarray, ...]:
            bounds = [s.aabb() for s in solids]
            return (
                np.array([b[0] for b in bounds]),
                np.array([b[1] for b in bounds]),
                np.array([s.owner for s in solids]),
            )

        lo, hi, owners = self._bounds_memo.get_or_make(tuple(solids), make)  # by identity
        return lo, hi, owners


CHECK_CHUNK = 2048  # configurations an ArmChecks prepares at once (bounds its arrays)
CHECK_PAIRS = 1 << 20  # and (configuration, link, solid) slots for their sphere contacts


class ArmChecks:
    """:meth:`ExactArm.checks`: the exact checks of B configurations, prepared a chunk of
    rows at a time as they are asked for; each answer is :meth:`ExactArm.colliding`'s."""

    def __init__(
        self,
        arm: ExactArm,
        thetas: np.ndarray,
        base_xy: np.ndarray,
        yaw: float,
        solids: list[Solid],
        targets: Sequence[str] | np.ndarray | str | None,
        floor: float | None,
        boxes: BoxArrays,
    ) -> None:
        self.arm, self.thetas, self.base_xy, self.yaw = arm, thetas, base_xy, yaw
        self.solids, self.targets, self.floor, self.boxes = solids, targets, floor, boxes
        self.batched = arm._chain is not None and arm.spheres is not None and bool(arm.ids)
        self.codes = owner_codes(boxes, targets, len(thetas)) if self.batched else None
        self.R_world_base = frames.R_z(yaw)
        self._chunk = -1
        slots = 1 if arm.spheres is None else len(arm.spheres.bound_r) * max(len(solids), 1)
        self._rows = max(1, min(CHECK_CHUNK, CHECK_PAIRS // slots))  # rows per chunk

    def colliding(self, i: int) -> bool:
        """Does configuration ``i`` touch a solid, or come within the floor clearance?"""
        a = self.arm
        if not self.batched:
            tg = self.targets
            target = tg if tg is None or isinstance(tg, str) else str(tg[i])
            x, y = self.base_xy[i]
            return a.colliding(
                self.thetas[i], x, y, self.yaw, self.solids, target, self.floor, self.boxes
            )
        if i // self._rows != self._chunk:
            self._prepare(i // self._rows)
        r = i - self._chunk * self._rows
        if (
            self.floor is not None
            and self._low[r]
            and a.floor.placed_below(self._M[r], self._R[r], self._p[r], self.floor)
        ):
            return True
        if not self.solids:
            return False
        Rw, shift = self.R_world_base, np.array([*self.base_xy[i], 0.0])
        for t in range(self._start[r], self._start[r + 1]):
            gs, ts = _coal(self.solids[self._box[t]])
            for g in a.link_geoms[self._link[t]]:
                tf = coal.Transform3s(Rw @ self._R[r, g], Rw @ self._p[r, g] + shift)
                if collide(a.geometries[g], tf, gs, ts):
                    return True
        return False

    def _prepare(self, chunk: int) -> None:
        a, sp, b, c = self.arm, self.arm.spheres, self.boxes, self.arm._chain
        assert sp is not None and c is not None and self.codes is not None
        sl = slice(chunk * self._rows, (chunk + 1) * self._rows)
        th = np.ascontiguousarray(self.thetas[sl])
        B, n, L, K = len(th), th.shape[1], len(sp.bound_r), len(b.owners)
        pl, fl = a.floor.placements, a.floor
        G = len(pl.parent)
        M = np.empty((B, n + 1, 4, 4))
        R, p, z = np.empty((B, G, 3, 3)), np.empty((B, G, 3)), np.empty(B)
        start = np.zeros(B + 1, np.int64)
        out_link = np.empty(max(B * L * K, 1), np.int64)
        out_box = np.empty(max(B * L * K, 1), np.int64)
        contacts_many(
            th, np.ascontiguousarray(self.base_xy[sl]), np.ascontiguousarray(self.codes[sl]),
            math.cos(self.yaw), math.sin(self.yaw), c.R_parent_joint, c.p_parent_joint,
            a._axis_index, c.axes, c.prismatic, sp.link_joint, sp.bound_c, sp.bound_r,
            sp.is_hand, sp.leaf_start, sp.leaf_count, sp.leaf_c, sp.leaf_r, b.centres, b.R,
            b.half, b.is_cylinder, b.radius, b.lo, b.hi, b.owner_codes, TOUCH, pl.parent,
            a._R_local, a._p_local, fl.box_c, fl.box_h, M, R, p, z, start, out_link, out_box,
        )  # fmt: skip
        low = np.zeros(B, bool)
        if self.floor is not None:
            low = z <= self.floor + 1e-9  # a screen: placed_below decides
            if fl.stand_in:
                # the stand-in boxes' lowest points, all rows at once (as placed_below)
                T = M[:, a.robot.dof][:, None] @ np.array([T for _, T in fl.stand_in])
                bc = np.array([bx[0] for bx in fl.stand_in_boxes])
                bh = np.array([bx[1] for bx in fl.stand_in_boxes])
                zs = (
                    np.einsum("bkj,kj->bk", T[:, :, 2, :3], bc)
                    + T[:, :, 2, 3]
                    - np.einsum("bkj,kj->bk", np.abs(T[:, :, 2, :3]), bh)
                )
                low |= (zs <= self.floor + 1e-9).any(1)
        self._chunk, self._M, self._R, self._p, self._low = chunk, M, R, p, low
        self._start, self._link, self._box = start, out_link, out_box


def nearby(
    solids: list[Solid], centre: np.ndarray | tuple[float, float], radius: float
) -> list[Solid]:
    """Solids whose bounding box comes within ``radius`` of ``centre`` in the floor plane."""
    c = np.asarray(centre, dtype=float)[:2]
    out = []
    for s in solids:
        lo, hi = s.aabb()
        d = np.maximum(np.maximum(lo[:2] - c, c - hi[:2]), 0.0)
        if float(np.hypot(*d)) <= radius:
            out.append(s)
    return out


@dataclass(frozen=True)
class ArmWorld:
    """What the arm is checked against near one tray, at one base yaw: the solids and the
    floor, which every link keeps ``floor`` [m] away from (the scene's floor_clearance)."""

    boxes: BoxArrays
    solids: list[Solid]
    yaw: float  # [rad]
    env: Envelope | None  # where the screen's rejections are recorded (None: nowhere)
    floor: float = FLOOR_CLEARANCE
