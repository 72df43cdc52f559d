"""The arm against the scene: conservative spheres (vectorised screen) and exact coal checks.

Links are every collision link of the reduced model that moves with the arm (joints 1..n),
the hand's own links included at their pre-grasp joint values. The part being grasped is no
obstacle for the hand links (``target``); everything else is, for every link. The floor is an
obstacle too (``floor``: the clearance every link keeps above it [m]), for the arm's links and
for the hand, its own links or the boxes that stand in for them (:mod:`pickstop.robot.floor`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from pickstop import frames
from pickstop.frames import rot2
from pickstop.robot.floor import ExactFloor, FloorSpheres, below_floor
from pickstop.robot.link_geometry import arm_links, is_hand_link
from pickstop.robot.model import RobotModel
from pickstop.scene.world import BoxArrays, Solid, _coal, collide

SPHERE_EXCESS = 0.01  # [m] how far a covering sphere may stick out of its link


def arm_geometry_ids(robot: RobotModel) -> list[int]:
    """Collision geometries on moving arm bodies, the hand's included."""
    return sorted(i for link in arm_links(robot) for i in link.geometry_ids)


def owner_codes(
    boxes: BoxArrays, targets: Sequence[str] | np.ndarray | str | None, n: int
) -> np.ndarray:
    """``(n,)`` per configuration, the index code of the owner its hand may touch (-1: none)."""
    codes = {o: i for i, o in enumerate(dict.fromkeys(boxes.owners))}
    if targets is None:
        return np.full(n, -1)
    if isinstance(targets, str):
        return np.full(n, codes.get(targets, -1))
    assert len(targets) == n, (len(targets), n)
    return np.array([codes.get(t, -1) for t in targets], dtype=np.int64)


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


def _to_world(
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
    envelope: Any = None,
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
    from pickstop.scene.world import spheres_hit

    B = base_xy.shape[0]
    if B == 0:
        return np.zeros(B, bool)
    flagged = np.zeros(B, bool) if floor is None else below_floor(spheres.floor, frames, floor)
    if len(boxes.centres) == 0:
        return flagged
    bw = _to_world(frames, spheres.link_joint, spheres.bound_c, base_xy, yaw)  # (B, L, 3)
    L = len(spheres.bound_r)
    code = owner_codes(boxes, targets, B)  # (B,)
    skip = np.where(spheres.is_hand[None, :], code[:, None], -1)  # (B, L)
    hit_link = spheres_hit(
        boxes, bw.reshape(-1, 3), np.tile(spheres.bound_r, B), skip=skip.ravel()
    ).reshape(B, L)
    cfg, lnk = np.nonzero(hit_link)
    if len(cfg) == 0:
        return flagged
    for link in np.unique(lnk):
        rows = cfg[lnk == link]
        leaves = np.flatnonzero(spheres.leaf_link == link)
        sub = [(R[:, :, rows], p[:, rows]) for R, p in frames]
        lw = _to_world(
            sub,
            np.full(len(leaves), spheres.link_joint[link]),
            spheres.leaf_c[leaves],
            base_xy[rows],
            yaw,
        )
        hit_boxes: set[int] = set()
        leaf_skip = code[rows] if spheres.is_hand[link] else np.full(len(rows), -1)
        h = spheres_hit(
            boxes,
            lw.reshape(-1, 3),
            np.tile(spheres.leaf_r[leaves], len(rows)),
            hit_boxes,
            skip=np.repeat(leaf_skip, len(leaves)),
        )
        if envelope is not None:
            envelope.hit_owners.update(boxes.owners[k] for k in hit_boxes)
        flagged[rows] |= h.reshape(len(rows), -1).any(axis=1)
    return flagged


class ExactArm:
    """Exact arm-versus-solids checks with coal (one per thread)."""

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot
        self.data = robot.model.createData()
        self.gdata = pin.GeometryData(robot.geom_model)
        self.ids = arm_geometry_ids(robot)
        names = {g: lk.name for lk in arm_links(robot) for g in lk.geometry_ids}
        self.hand = np.array([is_hand_link(robot, names[i]) for i in self.ids], bool)
        centres, halves = [], []
        for i in self.ids:
            geom = robot.geom_model.geometryObjects[i].geometry
            geom.computeLocalAABB()
            lo, hi = np.asarray(geom.aabb_local.min_), np.asarray(geom.aabb_local.max_)
            centres.append((lo + hi) / 2)
            halves.append((hi - lo) / 2)
        # (G, 3) each: the local bounding box of every checked geometry
        self.local_c = np.array(centres).reshape(-1, 3)
        self.local_h = np.array(halves).reshape(-1, 3)
        self.floor = ExactFloor(robot)

    def below_floor(self, clearance: float) -> list[str]:
        """After :meth:`place`: the arm geometries, and the stand-in hand boxes
        (``hand:<k>``), reaching ``z <= clearance`` [m] (the floor is z = 0 of the base)."""
        return self.floor.placed_below(self.data, self.gdata, clearance)

    def place(self, theta: np.ndarray) -> None:
        """Forward kinematics and geometry placements (base frame) of ``theta: (dof,)``."""
        q = self.robot.angles_to_q(theta)
        pin.forwardKinematics(self.robot.model, self.data, q)
        pin.updateGeometryPlacements(self.robot.model, self.data, self.robot.geom_model, self.gdata)

    def colliding(
        self,
        theta: np.ndarray,
        x: float,
        y: float,
        yaw: float,
        solids: list[Solid],
        target: str | None = None,
        floor: float | None = None,
    ) -> bool:
        """Does the arm at ``theta`` on a base at ``(x, y, yaw)`` touch any of ``solids``, or
        come within ``floor`` [m] of the floor (None: the floor is not checked)?

        target: the part being grasped, no obstacle for the hand links. Only the (geometry,
        solid) pairs whose world bounding boxes overlap go to coal.
        """
        self.place(theta)
        if floor is not None and self.below_floor(floor):
            return True
        if not solids or not self.ids:
            return False
        T_world_base = pin.SE3(frames.T_world_base(x, y, yaw))
        Ts_world_geom = [T_world_base * self.gdata.oMg[i] for i in self.ids]
        R = np.array([T.rotation for T in Ts_world_geom])  # (G, 3, 3)
        c = np.einsum("gij,gj->gi", R, self.local_c) + np.array(
            [T.translation for T in Ts_world_geom]
        )
        h = np.einsum("gij,gj->gi", np.abs(R), self.local_h)
        bounds = [s.aabb() for s in solids]
        lo = np.array([b[0] for b in bounds])  # (S, 3)
        hi = np.array([b[1] for b in bounds])
        # Geometry g and solid k can touch only where their world bounding boxes overlap.
        near = ~(
            ((c - h)[:, None] > hi[None]).any(axis=2) | ((c + h)[:, None] < lo[None]).any(axis=2)
        )  # (G, S)
        if target is not None:
            near &= ~(self.hand[:, None] & (np.array([s.owner for s in solids]) == target)[None])
        for g, k in zip(*np.nonzero(near), strict=True):
            T_world_geom = Ts_world_geom[g]
            geom = self.robot.geom_model.geometryObjects[self.ids[g]].geometry
            gs, ts = _coal(solids[k])
            if collide(
                geom, coal.Transform3s(T_world_geom.rotation, T_world_geom.translation), gs, ts
            ):
                return True
        return False


def nearby(solids: list[Solid], centre: Any, radius: float) -> list[Solid]:
    """Solids whose bounding box comes within ``radius`` of ``centre`` in the floor plane."""
    c = np.asarray(centre, dtype=float)[:2]
    out = []
    for s in solids:
        lo, hi = s.aabb()
        d = np.maximum(np.maximum(lo[:2] - c, c - hi[:2]), 0.0)
        if float(np.hypot(*d)) <= radius:
            out.append(s)
    return out
