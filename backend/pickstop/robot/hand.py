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
    if robot.derived.hand_shape is None:
        robot.derived.hand_shape = _make_shape(robot)
    shape: HandShape = robot.derived.hand_shape
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


#: [m] A top-down grasp keeps the open hand this far above the tray floor (see
#: :func:`pickstop.scene.grasps.top_height`): parts lower than the hand's reach plus this
#: have no top-down grasp.
TOP_DOWN_CLEARANCE = 0.003
#: [m] A pad's face is followed along the approach while it stays within this of where it
#: meets the closing axis through the grasp point.
PAD_TOLERANCE = 0.001
_PROBE = 0.0005  # [m] cross-section of the probes along the closing axis, and their step


@dataclass(frozen=True)
class HandFit:
    """How the open hand meets a tray, from its shape in the grasp point's frame [m].

    reach: how far it extends past the grasp point along the approach; top_down_min: the
    lowest part a top-down grasp takes (reach plus :data:`TOP_DOWN_CLEARANCE`); side_below:
    how far it reaches below the grasp point on a side grasp (closing horizontally or
    vertically, whichever reaches less), so a side grasp of a part of height h clears walls
    lower than ``h / 2 - side_below``;
    pad_tip: where the pads' gripping faces end towards the fingertips, along the approach
    (None: no finger geometry found on both sides of the closing axis); pad_gap: the free gap
    between the open pads, across the closing axis (compare ``max_opening``);
    tool_offset: the ``hand.tool_offset`` position [m] that puts the grasp point at pad_tip.
    """

    reach: float
    top_down_min: float
    side_below: float
    pad_tip: float | None
    pad_gap: float | None
    tool_offset: tuple[float, float, float] | None

    @property
    def reach_at_pads(self) -> float | None:
        """How far the open hand reaches past a grasp point at :attr:`pad_tip` [m]."""
        return None if self.pad_tip is None else max(0.0, self.reach - self.pad_tip)


def hand_points(shape: HandShape) -> np.ndarray:
    """``(N, 3)`` points in the TCP frame whose convex hulls (per geometry) hold the hand."""
    pts = [geometry_points(g) @ T[:3, :3].T + T[:3, 3] for _, g, T in shape.geometries]
    return np.concatenate(pts) if pts else np.zeros((0, 3))


def _probe_hits(shape: HandShape, a: float, side: float, length: float) -> bool:
    """Does a thin box along the closing axis, from the line through the grasp point at
    ``a`` [m] along the approach out to ``length`` [m] on ``side`` (+1 or -1), meet the open
    hand's geometry (coal, exact)?"""
    up = np.cross(shape.approach, shape.closing)
    R = np.column_stack([shape.approach, shape.closing, up])
    box = coal.Box(_PROBE, length, _PROBE)
    T = coal.Transform3s(R, a * shape.approach + side * (length / 2) * shape.closing)
    req = coal.CollisionRequest()
    for _, geom, T_tcp_geom in shape.geometries:
        Tg = coal.Transform3s(T_tcp_geom[:3, :3], T_tcp_geom[:3, 3])
        if coal.collide(box, T, geom, Tg, req, coal.CollisionResult()):
            return True
    return False


def pads(shape: HandShape, across: float = 0.5) -> tuple[float, float] | None:
    """``(tip, gap)`` of the open hand's pads [m]: the faces the closing axis through the grasp
    point meets on either side, their free gap, and where they end towards the fingertips
    along the approach (the nearer of the two; each followed while it stays within
    :data:`PAD_TOLERANCE` of the closing axis's hit, at most to the hand's reach). None if the
    axis meets nothing within ``across`` [m] on a side."""
    depth = []
    for side in (1.0, -1.0):
        if not _probe_hits(shape, 0.0, side, across):
            return None
        lo, hi = 0.0, across
        while hi - lo > 1e-5:  # the shortest probe that meets the hand: the face
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if _probe_hits(shape, 0.0, side, mid) else (mid, hi)
        depth.append(hi)
    tip = 0.0
    while tip < shape.reach and all(
        _probe_hits(shape, tip + _PROBE, side, d + PAD_TOLERANCE)
        for side, d in zip((1.0, -1.0), depth, strict=True)
    ):
        tip += _PROBE
    return tip, depth[0] + depth[1]


def pad_tip(shape: HandShape) -> float | None:
    """Where the pads' gripping faces end towards the fingertips (:func:`pads`) [m]."""
    found = pads(shape)
    return None if found is None else found[0]


def hand_fit(robot: RobotModel) -> HandFit:
    """The :class:`HandFit` of ``robot``'s configured hand."""
    return fit_of(hand_shape(robot), tool_offset_matrix(robot.config.hand))


def fit_of(shape: HandShape, T_tool_tcp: np.ndarray) -> HandFit:
    """The :class:`HandFit` of an open hand whose grasp point sits at ``T_tool_tcp (4, 4)``
    in the tool frame."""
    pts = hand_points(shape)
    # Side grasps close horizontally (a x c up) or vertically (c up): the shallower one.
    up = np.cross(shape.approach, shape.closing)
    below = max(0.0, min(-(pts @ up).min(), -(pts @ shape.closing).min())) if len(pts) else 0.0
    found = pads(shape) if len(pts) else None
    tip, gap = (None, None) if found is None else found
    offset = None
    if tip is not None:
        moved = T_tool_tcp[:3, 3] + T_tool_tcp[:3, :3] @ (tip * shape.approach)
        offset = (float(moved[0]), float(moved[1]), float(moved[2]))
    return HandFit(
        reach=shape.reach,
        top_down_min=shape.reach + TOP_DOWN_CLEARANCE,
        side_below=float(below),
        pad_tip=tip,
        pad_gap=gap,
        tool_offset=offset,
    )
