"""The robot's own hand, open on approach, in the grasp point's frame.

The hand links (``hand.links`` of the config) ride on the last arm joint, so at the pre-grasp
joint values they are rigid in the tool frame: their collision geometry, placed in the frame of
the grasp point (``T_tool_tcp``, the config's ``tool_offset``), is what grasp generation checks
against the tray and what bounds how low a top-down grasp can go. Witness configurations are
checked with the same geometry on the whole robot (:mod:`pickstop.regions.arm`).
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, replace
from typing import Any

import coal
import numpy as np

from pickstop.errors import RobotConfigError
from pickstop.frames import R_rpy, inverse, transform
from pickstop.robot.config import Hand
from pickstop.robot.model import RobotModel

_CORNERS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)


def tool_offset_matrix(hand: Hand) -> np.ndarray:
    """``T_tool_tcp`` (4, 4) of a hand config."""
    return transform(R_rpy(*hand.tool_offset.rpy), hand.tool_offset.position)


def geometry_points(geom: Any) -> np.ndarray:
    """Points ``(N, 3)`` in a coal geometry's frame whose convex hull holds it."""
    if isinstance(geom, coal.BVHModelBase):
        return np.asarray(geom.vertices(), dtype=float)
    geom.computeLocalAABB()
    lo, hi = np.asarray(geom.aabb_local.min_, float), np.asarray(geom.aabb_local.max_, float)
    return lo + _CORNERS * (hi - lo)


@dataclass(frozen=True)
class HandShape:
    """The open hand in the grasp point's (TCP) frame.

    geometries: ``(name, coal geometry, T_tcp_geometry (4, 4))`` of every hand collision object.
    lo, hi: ``(3,)`` bounds of the hand in the TCP frame [m].
    approach, closing: unit axes in the TCP frame; reach: how far the hand extends past the
    grasp point along the approach [m]; max_opening: free gap when open [m];
    T_tcp_tool: ``(4, 4)``; joints: the hand's joint values on approach [rad or m].
    """

    geometries: tuple[tuple[str, Any, np.ndarray], ...]
    lo: np.ndarray
    hi: np.ndarray
    approach: np.ndarray
    closing: np.ndarray
    reach: float
    max_opening: float
    T_tcp_tool: np.ndarray
    joints: dict[str, float]
    key: str  # identifies the hand for caches

    @property
    def R_grasp_tcp(self) -> np.ndarray:
        """Rotation (3, 3) from the TCP frame to the grasp frame (x approach, y closing)."""
        A = np.stack([self.approach, self.closing, np.cross(self.approach, self.closing)], 1)
        return A.T

    def corners(self, T_world_tcp: np.ndarray) -> np.ndarray:
        """``(8, 3)`` world corners of the hand's bounds at a grasp."""
        local = self.lo + _CORNERS * (self.hi - self.lo)
        return local @ T_world_tcp[:3, :3].T + T_world_tcp[:3, 3]

    @classmethod
    def parallel(
        cls,
        max_opening: float = 0.08,
        finger_length: float = 0.06,
        finger_width: float = 0.02,
        finger_thickness: float = 0.01,
        tip_offset: float = 0.015,
        palm_depth: float = 0.03,
    ) -> HandShape:
        """A plain parallel-jaw gripper of boxes (TCP between the fingers, ``tip_offset`` [m]
        behind the fingertips): for robots without hand geometry, and for tests."""
        L, o, t, w, d = finger_length, max_opening, finger_thickness, finger_width, palm_depth
        xm = tip_offset - L / 2
        boxes = [
            ("finger_l", (xm, (o + t) / 2, 0.0), (L, t, w)),
            ("finger_r", (xm, -(o + t) / 2, 0.0), (L, t, w)),
            ("palm", (xm - (L + d) / 2, 0.0, 0.0), (d, o + 2 * t, w)),
        ]
        geoms = []
        for name, c, size in boxes:
            geoms.append((name, coal.Box(*size), transform(np.eye(3), c)))
        return _shape(tuple(geoms), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), o, np.eye(4), {})


def _shape(
    geoms: tuple[tuple[str, Any, np.ndarray], ...],
    approach: np.ndarray,
    closing: np.ndarray,
    max_opening: float,
    T_tcp_tool: np.ndarray,
    joints: dict[str, float],
) -> HandShape:
    pts = [geometry_points(g) @ T[:3, :3].T + T[:3, 3] for _, g, T in geoms]
    allp = np.concatenate(pts) if pts else np.zeros((1, 3))
    a = approach / np.linalg.norm(approach)
    c = closing - (closing @ a) * a
    c /= np.linalg.norm(c)
    key = repr(
        (
            [(n, np.round(T, 9).tolist()) for n, _, T in geoms],
            len(allp),
            np.round(allp.sum(0), 9).tolist(),
            a.tolist(),
            c.tolist(),
            max_opening,
        )
    )
    return HandShape(
        geometries=geoms,
        lo=allp.min(axis=0),
        hi=allp.max(axis=0),
        approach=a,
        closing=c,
        reach=max(0.0, float((allp @ a).max())),
        max_opening=max_opening,
        T_tcp_tool=T_tcp_tool,
        joints=joints,
        key=key,
    )


def hand_link_names(robot: RobotModel) -> list[str]:
    """The collision links the config's ``hand.links`` patterns name (sorted)."""
    from pickstop.robot.link_geometry import collision_links

    pats = robot.config.hand.links
    return sorted(
        lk.name for lk in collision_links(robot) if any(fnmatch.fnmatch(lk.name, p) for p in pats)
    )


def hand_joints(robot: RobotModel) -> dict[str, float]:
    """Joint values of the hand on approach: every joint that moves a hand link (its locked or
    pre-grasp value), by name [rad or m]."""
    full = robot.full_model
    pats = robot.config.hand.links
    arm = {j.name for j in robot.joints}
    out = {}
    for f in full.frames:
        if not any(fnmatch.fnmatch(str(f.name), p) for p in pats):
            continue
        jid = f.parentJoint
        while jid > 0:
            name = str(full.names[jid])
            if name in arm:
                break
            iq, nq = full.idx_qs[jid], full.nqs[jid]
            q = robot.q_full[iq : iq + nq]
            if nq == 1:
                out[name] = float(q[0])
            elif nq == 2:
                out[name] = float(math.atan2(q[1], q[0]))
            jid = full.parents[jid]
    return dict(sorted(out.items()))


def hand_shape(robot: RobotModel) -> HandShape:
    """The robot's open hand in the TCP frame (made once per loaded robot)."""
    hit = robot.memo.get("hand_shape")
    if isinstance(hit, HandShape):
        return hit
    shape = robot.memo["hand_shape"] = _make_shape(robot)
    return shape


def _make_shape(robot: RobotModel) -> HandShape:
    from pickstop.robot.link_geometry import collision_links

    cfg = robot.config.hand
    if cfg.geometry == "boxes":
        b = cfg.boxes
        shape = HandShape.parallel(
            cfg.max_opening,
            b.finger_length,
            b.finger_width,
            b.finger_thickness,
            b.tip_offset,
            b.palm_depth,
        )
        return replace(
            shape,
            T_tcp_tool=inverse(tool_offset_matrix(cfg)),
            joints=hand_joints(robot),
            key=shape.key + repr(cfg.tool_offset),
        )
    last = robot.dof
    names = set(hand_link_names(robot))
    for k, p in enumerate(cfg.links):
        if not any(fnmatch.fnmatch(n, p) for n in names):
            raise RobotConfigError(
                f"{robot.urdf_path.name}: hand.links pattern {p!r} matches no collision link",
                field=f"hand.links[{k}]",
            )
    T_joint_tool = robot.model.frames[robot.tool_frame_id].placement.homogeneous
    T_tool_tcp = tool_offset_matrix(cfg)
    T_tcp_joint = inverse(T_joint_tool @ T_tool_tcp)
    geoms = []
    for link in collision_links(robot):
        if link.name not in names:
            continue
        if link.joint != last:
            raise RobotConfigError(
                f"{robot.urdf_path.name}: hand link {link.name!r} is not carried by the last "
                f"arm joint {robot.joints[-1].name!r}: a hand rides on the wrist",
                field="hand.links",
            )
        for gid in link.geometry_ids:
            obj = robot.geom_model.geometryObjects[gid]
            geoms.append((str(obj.name), obj.geometry, T_tcp_joint @ obj.placement.homogeneous))
    return _shape(
        tuple(geoms),
        np.asarray(cfg.approach_axis, float),
        np.asarray(cfg.closing_axis, float),
        cfg.max_opening,
        inverse(T_tool_tcp),
        hand_joints(robot),
    )
