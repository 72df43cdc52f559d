"""The floor as an obstacle for every moving robot link, with a clearance.

The base frame stands on the floor (docs/conventions.md), so whatever the base pose the floor
is the plane z = 0 of the base frame, and a configuration is kept only when every checked
collision geometry stays above ``z = clearance``: the links on moving joints
(:func:`pickstop.robot.link_geometry.arm_links`) and the hand as the checks see it (its own
links, or the boxes standing in for them).

The screen (:func:`below_floor`) tests covering spheres, which hold their links, and the hull
points of the stand-in boxes (a convex solid meets the half-space only where a hull point
does): whatever reaches down to the clearance has a sphere or a point reaching there too, so
the screen flags every configuration the exact check (:class:`ExactFloor`, coal against the
half-space ``z <= clearance``) rejects.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from pickstop.frames import inverse, transform

if TYPE_CHECKING:
    from pickstop.robot.model import RobotModel

#: Default gap kept between every moving link and the floor [m] (build and regions).
FLOOR_CLEARANCE = 0.01
MAX_CLEARANCE = 0.5  # [m]

Frames = Sequence[tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class FloorSpheres:
    """Covering spheres of links in their joint frames, with one bounding sphere per joint.

    joint: ``(S,)`` joint index (1..n) of each sphere; centre ``(S, 3)``, radius ``(S,)`` [m].
    bound_joint ``(J,)``, bound_c ``(J, 3)``, bound_r ``(J,)``: a sphere holding each joint's.
    """

    joint: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    bound_joint: np.ndarray
    bound_c: np.ndarray
    bound_r: np.ndarray

    @classmethod
    def of_spheres(cls, joint: np.ndarray, centre: np.ndarray, radius: np.ndarray) -> FloorSpheres:
        joint = np.asarray(joint, dtype=np.int64)
        centre = np.asarray(centre, dtype=float).reshape(-1, 3)
        radius = np.asarray(radius, dtype=float)
        assert joint.shape == radius.shape == centre.shape[:1], (joint.shape, centre.shape)
        assert (joint >= 1).all(), "spheres on the fixed base cannot reach the floor"
        js = np.unique(joint)
        bc, br = [], []
        for j in js:
            m = joint == j
            c = 0.5 * (centre[m].min(axis=0) + centre[m].max(axis=0))
            bc.append(c)
            br.append(float(np.max(np.linalg.norm(centre[m] - c, axis=1) + radius[m])))
        return cls(
            joint, centre, radius, js, np.array(bc).reshape(-1, 3), np.array(br, dtype=float)
        )

    @classmethod
    def of(cls, robot: RobotModel, excess: float = 0.01) -> FloorSpheres:
        """Spheres covering the checked links (:func:`arm_links`), sticking out by at most
        ``excess`` [m], and the stand-in hand's hull points."""
        from pickstop.robot.link_geometry import LinkShape, arm_links
        from pickstop.robot.spheres import cover

        joints, centres, radii = [], [], []
        for link in arm_links(robot):
            s = cover(LinkShape.of(robot, tuple(link.geometry_ids)), excess)
            joints.append(np.full(len(s), link.joint))
            centres.append(s[:, :3])
            radii.append(s[:, 3])
        return cls.with_hand(
            robot, np.concatenate(joints), np.concatenate(centres), np.concatenate(radii)
        )

    @classmethod
    def with_hand(
        cls, robot: RobotModel, joint: np.ndarray, centre: np.ndarray, radius: np.ndarray
    ) -> FloorSpheres:
        """Link spheres plus the hull points of the boxes standing in for the hand, if any: a
        convex solid meets the floor's half-space only if a point of its hull does."""
        from pickstop.robot.hand import geometry_points

        pts = [geometry_points(g) @ T[:3, :3].T + T[:3, 3] for g, T in stand_in_hand(robot)]
        hull = np.concatenate(pts) if pts else np.zeros((0, 3))
        return cls.of_spheres(
            np.concatenate([joint, np.full(len(hull), robot.dof)]),
            np.concatenate([centre, hull]),
            np.concatenate([radius, np.full(len(hull), 1e-9)]),
        )


def below_floor(spheres: FloorSpheres, frames: Frames, clearance: float) -> np.ndarray:
    """``(B,)`` True where some sphere reaches down to ``z <= clearance`` [m] (base frame).

    frames: :func:`pickstop.robot.kinematics.fk_soa` joint frames ``(R (3, 3, B), p (3, B))``.
    False guarantees every covered link stays above the clearance.
    """
    B = frames[0][1].shape[1] if len(frames) else 0
    hit = np.zeros(B, bool)
    for k, j in enumerate(spheres.bound_joint):
        R, p = frames[j - 1]
        up = R[2]  # (3, B): the base's z axis seen in joint j's frame, transposed
        low = spheres.bound_c[k] @ up + p[2] - spheres.bound_r[k]
        cand = np.flatnonzero((low <= clearance) & ~hit)
        if not len(cand):
            continue
        m = spheres.joint == j
        z = spheres.centre[m] @ up[:, cand] - spheres.radius[m][:, None]  # (S_j, C)
        hit[cand] = (z.min(axis=0) + p[2, cand]) <= clearance
    return hit


def geometry_below(geometry: Any, T_base_geom: Any, clearance: float) -> bool:
    """Exact (coal): does ``geometry`` at ``T_base_geom`` (a pin.SE3 or (4, 4)) reach down to
    the half-space ``z <= clearance`` [m]?"""
    import coal

    if isinstance(T_base_geom, np.ndarray):
        tf = coal.Transform3s(T_base_geom[:3, :3], T_base_geom[:3, 3])
    else:
        tf = coal.Transform3s(T_base_geom.rotation, T_base_geom.translation)
    floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), float(clearance))
    req = coal.CollisionRequest()
    return bool(coal.collide(geometry, tf, floor, coal.Transform3s(), req, coal.CollisionResult()))


def floor_identity(robot: RobotModel) -> str:
    """What the floor check covers beyond the robot's hash: the boxes standing in for the hand
    (the hand's config is not part of the robot hash), or "links" (the robot's own)."""
    if robot.config.hand.geometry != "boxes":
        return "links"
    from pickstop.robot.hand import hand_shape

    return hashlib.sha256(hand_shape(robot).key.encode()).hexdigest()[:16]


def _local_box(geometry: Any) -> tuple[np.ndarray, np.ndarray]:
    """Centre and half extents (3,) of a coal geometry's local bounding box [m]."""
    geometry.computeLocalAABB()
    lo, hi = np.asarray(geometry.aabb_local.min_), np.asarray(geometry.aabb_local.max_)
    return (lo + hi) / 2, (hi - lo) / 2


class Placements:
    """Where geometries ``ids`` of a robot's collision model are, from its joints' placements:
    ``oMg = oMi[parentJoint] * placement`` for all of them at once (as
    ``pin.updateGeometryPlacements`` computes it, without a Python call per geometry)."""

    def __init__(self, robot: RobotModel, ids: Sequence[int]) -> None:
        objs = [robot.geom_model.geometryObjects[i] for i in ids]
        self.parent = np.array([o.parentJoint for o in objs], dtype=np.int64)
        local = np.array([o.placement.homogeneous for o in objs]).reshape(-1, 4, 4)
        self.R_local = local[:, :3, :3]  # (G, 3, 3)
        self.p_local = local[:, :3, 3]  # (G, 3)

    @staticmethod
    def joints(data: Any) -> np.ndarray:
        """``(njoints, 4, 4)`` every joint's placement in the base frame, after
        ``pin.forwardKinematics`` into ``data``."""
        return np.array([m.homogeneous for m in data.oMi])

    def of(self, data: Any, joints: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``R: (G, 3, 3)``, ``p: (G, 3)`` in the base frame, after ``pin.forwardKinematics``
        into ``data`` (or from its :meth:`joints`)."""
        M = (self.joints(data) if joints is None else joints)[self.parent]  # (G, 4, 4)
        R_joint, p_joint = M[:, :3, :3], M[:, :3, 3]
        R = R_joint @ self.R_local
        p = np.einsum("gij,gj->gi", R_joint, self.p_local) + p_joint
        return R, p


class ExactFloor:
    """Exact floor check (coal) of the checked links (:func:`arm_links`) and of the boxes
    standing in for the hand, if any; a geometry whose bounding box stays above the clearance
    is not handed to coal. One per thread."""

    def __init__(self, robot: RobotModel) -> None:
        from pickstop.robot.link_geometry import arm_links

        self.robot = robot
        gm = robot.geom_model
        self.ids = sorted(g for lk in arm_links(robot) for g in lk.geometry_ids)
        objs = [gm.geometryObjects[i] for i in self.ids]
        self.geoms = [(o.name, o.geometry) for o in objs]
        self.boxes = [_local_box(g) for _, g in self.geoms]
        # (G, 3) each: centre and half extents of every local bounding box
        self.box_c = np.array([c for c, _ in self.boxes]).reshape(-1, 3)
        self.box_h = np.array([h for _, h in self.boxes]).reshape(-1, 3)
        self.stand_in = stand_in_hand(robot)
        self.stand_in_boxes = [_local_box(g) for g, _ in self.stand_in]
        self.placements = Placements(robot, self.ids)
        self.data = robot.model.createData()

    def placed_below(
        self, joints: np.ndarray, R: np.ndarray, p: np.ndarray, clearance: float
    ) -> list[str]:
        """The geometries reaching ``z <= clearance`` [m], placed at ``R: (G, 3, 3)``,
        ``p: (G, 3)`` (:class:`Placements` of :attr:`ids`, base frame), the joints at
        ``joints: (njoints, 4, 4)`` (:meth:`Placements.joints`); ``hand:<k>``: a stand-in
        box."""
        out = []
        if len(self.ids):
            # the lowest z of every local bounding box at once; only those low enough go to coal
            low = (
                np.einsum("gj,gj->g", R[:, 2], self.box_c)
                + p[:, 2]
                - np.einsum("gj,gj->g", np.abs(R[:, 2]), self.box_h)
            )
            out = [
                self.geoms[k][0]
                for k in np.flatnonzero(low <= clearance)
                if geometry_below(self.geoms[k][1], transform(R[k], p[k]), clearance)
            ]
        if self.stand_in:
            T_base_joint = joints[self.robot.dof]
            for k, ((geom, T_joint_geom), box) in enumerate(
                zip(self.stand_in, self.stand_in_boxes, strict=True)
            ):
                T = T_base_joint @ T_joint_geom
                if _low(T[:3, :3], T[:3, 3], box) <= clearance and geometry_below(
                    geom, T, clearance
                ):
                    out.append(f"hand:{k}")
        return out

    def below(self, theta: np.ndarray, clearance: float) -> list[str]:
        """The geometries at ``theta: (dof,)`` reaching ``z <= clearance`` [m]."""
        import pinocchio as pin

        q = self.robot.angles_to_q(np.asarray(theta, dtype=float))
        pin.forwardKinematics(self.robot.model, self.data, q)
        M = self.placements.joints(self.data)
        return self.placed_below(M, *self.placements.of(self.data, M), clearance)

    def colliding(self, thetas: np.ndarray, clearance: float) -> np.ndarray:
        """``thetas: (N, dof)`` -> ``(N,)`` True where something reaches ``z <= clearance``."""
        thetas = np.asarray(thetas, dtype=float)
        assert thetas.ndim == 2 and thetas.shape[1] == self.robot.dof, thetas.shape
        return np.array([bool(self.below(th, clearance)) for th in thetas], dtype=bool)


def _low(R: np.ndarray, p: np.ndarray, box: tuple[np.ndarray, np.ndarray]) -> float:
    """Lowest z [m] of a local bounding box ``(centre, half)`` placed at ``(R, p)``."""
    c, h = box
    return float(R[2] @ c + p[2] - np.abs(R[2]) @ h)


def stand_in_hand(robot: RobotModel) -> list[tuple[Any, np.ndarray]]:
    """The boxes standing in for the hand (``hand.geometry: boxes``) as ``(coal geometry,
    T_joint_geometry (4, 4))`` in the last arm joint's frame; none for a hand of links."""
    if robot.config.hand.geometry != "boxes":
        return []
    from pickstop.robot.hand import hand_shape

    hand = hand_shape(robot)
    T_joint_tool = robot.model.frames[robot.tool_frame_id].placement.homogeneous
    T_joint_tcp = T_joint_tool @ inverse(hand.T_tcp_tool)
    return [(geom, T_joint_tcp @ T_tcp_geom) for _, geom, T_tcp_geom in hand.geometries]
