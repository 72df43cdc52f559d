"""The floor as an obstacle for every moving robot link, with a clearance.

The base frame stands on the floor (docs/conventions.md), so whatever the base pose the floor
is the plane z = 0 of the base frame, and a configuration is kept only when every collision
geometry on a moving joint stays above ``z = clearance``. The screen (:func:`below_floor`)
tests covering spheres, which hold their links: a link with a point at or below the clearance
has a sphere reaching there too, so the screen flags every configuration the exact check
(:class:`ExactFloor`, coal against the half-space ``z <= clearance``) rejects.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from pickstop.robot.model import RobotModel

#: Default gap kept between every moving link and the floor [m] (build and regions).
FLOOR_CLEARANCE = 0.01
MAX_CLEARANCE = 0.5  # [m]

Frames = Sequence[tuple[np.ndarray, np.ndarray]]


def floor_links(robot: RobotModel) -> list[Any]:
    """Every collision link on a moving joint (the hand's own links included), by name."""
    from pickstop.robot.link_geometry import collision_links

    return sorted((lk for lk in collision_links(robot) if lk.joint != 0), key=lambda lk: lk.name)


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
        """Spheres covering :func:`floor_links`, sticking out by at most ``excess`` [m]."""
        from pickstop.robot.link_geometry import LinkShape
        from pickstop.robot.spheres import cover

        joints, centres, radii = [], [], []
        for link in floor_links(robot):
            s = cover(LinkShape.of(robot, tuple(link.geometry_ids)), excess)
            joints.append(np.full(len(s), link.joint))
            centres.append(s[:, :3])
            radii.append(s[:, 3])
        return cls.of_spheres(
            np.concatenate(joints), np.concatenate(centres), np.concatenate(radii)
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


class ExactFloor:
    """Exact floor check of chosen collision geometries with coal (one per thread)."""

    def __init__(self, robot: RobotModel, geometry_ids: Sequence[int] | None = None) -> None:
        import pinocchio as pin

        self.robot = robot
        if geometry_ids is None:
            geometry_ids = [g for lk in floor_links(robot) for g in lk.geometry_ids]
        self.ids = list(geometry_ids)
        self.data = robot.model.createData()
        self.gdata = pin.GeometryData(robot.geom_model)

    def lowest_links(self, theta: np.ndarray, clearance: float) -> list[str]:
        """Names of the geometries at ``theta: (dof,)`` reaching ``z <= clearance`` [m]."""
        import pinocchio as pin

        gm = self.robot.geom_model
        q = self.robot.angles_to_q(np.asarray(theta, dtype=float))
        pin.forwardKinematics(self.robot.model, self.data, q)
        pin.updateGeometryPlacements(self.robot.model, self.data, gm, self.gdata)
        return [
            gm.geometryObjects[i].name
            for i in self.ids
            if geometry_below(gm.geometryObjects[i].geometry, self.gdata.oMg[i], clearance)
        ]

    def colliding(self, thetas: np.ndarray, clearance: float) -> np.ndarray:
        """``thetas: (N, dof)`` -> ``(N,)`` True where a geometry reaches ``z <= clearance``."""
        thetas = np.asarray(thetas, dtype=float)
        assert thetas.ndim == 2 and thetas.shape[1] == self.robot.dof, thetas.shape
        return np.array([bool(self.lowest_links(th, clearance)) for th in thetas], dtype=bool)
