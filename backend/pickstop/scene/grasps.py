"""Grasp poses per part from its shape and the robot's hand, filtered against the tray.

A grasp is a pose of the hand's grasp point (TCP) in the part frame, ``T_part_tcp``; the part
frame sits at the part's bottom centre, z up. In the grasp frame x is the hand's approach and y
its closing direction (the robot config says which TCP axes those are). Top-down grasps
approach along -z at several angles about the vertical; side grasps approach horizontally with
the closing direction horizontal or vertical. A grasp whose open hand (the robot's own hand
geometry, at its pre-grasp joint values) would touch the tray walls, the tray floor, the table
or a neighbouring part, or come within the scene's floor clearance of the floor, is dropped. On
approach the open hand also keeps clear of the part it is to grasp (the pads close on it
afterwards): a top-down grasp whose palm or curled fingers would enter the part is raised, 5 mm
at a time, while the grasp point stays at least 5 mm below the part's top, and dropped if it
cannot clear it. The witnesses' exact checks then leave the target part out for the hand links
only (IK reaches the grasp to within a millimetre). Grasps live in the part frame, which sits on
the tray's floor: in a tilted tray they approach along its tilted normal. The scene's
``gripper`` block tunes which grasps are generated, never the hand's geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np

from pickstop.frames import R_z, transform
from pickstop.robot.hand import TOP_DOWN_CLEARANCE, HandShape
from pickstop.scene.model import Box, Cylinder, Gripper, Mesh, Part, Scene, Tray
from pickstop.scene.world import (
    TOUCH,
    Solid,
    SolidSet,
    _coal,
    _Offset,
    other_solids,
    part_solid,
    solid_below,
    solids_overlap,
    tray_body_solids,
    world_part_transform,
)

FLOOR_CLEARANCE = TOP_DOWN_CLEARANCE  # [m] the lowest point of a top-down hand to the tray floor
PART_CLEARANCE = 0.0005  # [m] between the open hand and the part it is to grasp, on approach
LIFT_STEP = 0.005  # [m] a top-down grasp blocked by its own part is raised by this much
MIN_HOLD = 0.005  # [m] a raised grasp point stays at least this far below the part's top


@dataclass(frozen=True)
class GraspSet:
    """Grasps of one part: grasp points ``Ts_part_tcp: (k, 4, 4)`` and the tool-frame poses
    the arm must reach for them, ``Ts_world_tool: (k, 4, 4)``; ``kinds``: 'top', 'side' or
    'user'."""

    part_id: str
    tray_id: str
    Ts_part_tcp: np.ndarray
    Ts_world_tool: np.ndarray
    kinds: tuple[str, ...]
    rejected: int  # generated but blocked by the tray, table, neighbours or the floor
    user_given: bool
    too_low: bool = False  # no top-down grasp: the open hand reaches below the tray floor
    near_floor: int = 0  # of the rejected: the open hand within the floor clearance

    @property
    def Ts_part_tool(self) -> np.ndarray:
        """Grasp points (the older name; they are TCP poses)."""
        return self.Ts_part_tcp


def _frame(x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    return transform(np.column_stack([x, y, np.cross(x, y)]), p)


def _extent_along(geometry: Box | Cylinder | Mesh, d: np.ndarray) -> float:
    """Width of the part along the horizontal or vertical unit direction ``d`` [m]."""
    if isinstance(geometry, Box):
        return float(np.abs(d) @ np.asarray(geometry.size))
    if isinstance(geometry, Cylinder):
        return 2 * geometry.radius * math.hypot(d[0], d[1]) + geometry.height * abs(d[2])
    return float("inf")


def _height(geometry: Box | Cylinder | Mesh) -> float:
    if isinstance(geometry, Box):
        return geometry.size[2]
    if isinstance(geometry, Cylinder):
        return geometry.height
    return 0.0


def top_height(part: Part, hand: HandShape) -> float:
    """Height [m] of the grasp point of a top-down grasp above the part's bottom: its middle,
    or higher where the open hand reaches farther down than that."""
    return max(_height(part.geometry) / 2, hand.reach + FLOOR_CLEARANCE)


_DEFAULT_SETTINGS = Gripper()


def candidate_grasps(
    part: Part, hand: HandShape, settings: Gripper = _DEFAULT_SETTINGS
) -> list[tuple[np.ndarray, str]]:
    """Every geometric grasp ``(T_part_tcp, kind)`` the hand can close on (no environment)."""
    g = part.geometry
    h = _height(g)
    out: list[tuple[np.ndarray, str]] = []
    span = math.pi if settings.symmetric else 2 * math.pi
    R = hand.R_grasp_tcp  # TCP axes from the grasp frame's (x approach, y closing)
    kinds = settings.kinds
    # Top-down: approach down, closing direction turning about the vertical; the grasp point
    # stays inside the part and the open hand above the tray floor.
    z = top_height(part, hand)
    if z < h and "top" in kinds:
        for i in range(settings.top_down_angles):
            a = span * i / settings.top_down_angles
            y = R_z(a)[:, 0]
            if _extent_along(g, y) <= hand.max_opening:
                out.append((_frame(np.array([0.0, 0.0, -1.0]), y, np.array([0, 0, z])), "top"))
    # Side: approach horizontal towards the part, closing horizontal or vertical.
    for i in range(settings.side_directions if "side" in kinds else 0):
        b = 2 * math.pi * i / settings.side_directions
        x, y_side = R_z(b)[:, 0], R_z(b)[:, 1]
        for y in (y_side, np.array([0.0, 0.0, 1.0])):
            if _extent_along(g, y) <= hand.max_opening:
                out.append((_frame(x, y, np.array([0, 0, h / 2])), "side"))
    for T, _ in out:
        T[:3, :3] = T[:3, :3] @ R
    return out


def hand_solids(hand: HandShape, T_world_tcp: np.ndarray) -> list[Solid]:
    """The open hand's own collision geometry at a grasp point, as solids in the world."""
    at = _HandBoxes.of(hand).at(T_world_tcp)
    return [at.solid(k) for k in range(len(at.T))]


@dataclass(frozen=True)
class _HandBoxes:
    """The open hand's collision geometries with their local bounds, placed at a grasp all at
    once: each one's world bounds from arrays, its solid (as :func:`hand_solids` makes it)
    only where a bounds test cannot settle it."""

    geometries: tuple[Any, ...]
    T_tcp_geom: np.ndarray  # (G, 4, 4)
    centre: np.ndarray  # (G, 3) the centre of each one's local bounds
    half: np.ndarray  # (G, 3)

    @classmethod
    def of(cls, hand: HandShape) -> _HandBoxes:
        c, h = [], []
        for _, geom, _ in hand.geometries:
            geom.computeLocalAABB()
            lo, hi = (
                np.asarray(geom.aabb_local.min_, float),
                np.asarray(geom.aabb_local.max_, float),
            )
            c.append((lo + hi) / 2)
            h.append((hi - lo) / 2)
        return cls(
            tuple(g for _, g, _ in hand.geometries),
            np.array([T for *_, T in hand.geometries], float).reshape(-1, 4, 4),
            np.array(c, float).reshape(-1, 3),
            np.array(h, float).reshape(-1, 3),
        )

    def at(self, T_world_tcp: np.ndarray) -> _HandAt:
        T = T_world_tcp[None] @ self.T_tcp_geom
        T[:, :3, 3] += np.einsum("gij,gj->gi", T[:, :3, :3], self.centre)
        ext = np.einsum("gij,gj->gi", np.abs(T[:, :3, :3]), self.half)
        return _HandAt(self, T, T[:, :3, 3] - ext, T[:, :3, 3] + ext)


@dataclass(frozen=True)
class _HandAt:
    """The open hand at one grasp (:class:`_HandBoxes`): the exact tests of
    :func:`grasps_for_part`, each solid tested with coal only where its bounds leave it open."""

    boxes: _HandBoxes
    T: np.ndarray  # (G, 4, 4) each solid's centre frame in the world
    lo: np.ndarray  # (G, 3) world bounds
    hi: np.ndarray

    def solid(self, k: int) -> Solid:
        b = self.boxes
        return Solid(
            "mesh", self.T[k], b.half[k], "hand", 0.0, _Offset(b.geometries[k], b.centre[k])
        )

    def below(self, clearance: float) -> bool:
        """:func:`solid_below` of any of the hand's solids."""
        low = np.flatnonzero(self.lo[:, 2] <= clearance).tolist()
        return any(solid_below(self.solid(k), clearance) for k in low)

    def meets(self, obstacles: SolidSet) -> bool:
        """:meth:`SolidSet.overlaps` of any of the hand's solids."""
        near = np.all(self.lo[:, None] <= obstacles.hi[None] - TOUCH, axis=2) & np.all(
            obstacles.lo[None] <= self.hi[:, None] - TOUCH, axis=2
        )
        for k in np.flatnonzero(near.any(1)).tolist():
            a = self.solid(k)
            if any(
                solids_overlap(a, obstacles.solids[j]) for j in np.flatnonzero(near[k]).tolist()
            ):
                return True
        return False

    def shifted(self, d: np.ndarray) -> _HandAt:
        """The same hand moved by ``d: (3,)`` [m]."""
        T = self.T.copy()
        T[:, :3, 3] += d
        return _HandAt(self.boxes, T, self.lo + d, self.hi + d)

    def moved(self, M: np.ndarray) -> _HandAt:
        """The same hand carried by the rigid motion ``M: (4, 4)`` (world to world)."""
        T = M[None] @ self.T
        ext = np.einsum("gij,gj->gi", np.abs(T[:, :3, :3]), self.boxes.half)
        return _HandAt(self.boxes, T, T[:, :3, 3] - ext, T[:, :3, 3] + ext)

    def clear_of(self, target: Solid, margin: float) -> bool:
        """:func:`clear_of` of the hand's solids and ``target``."""
        lo_t, hi_t = target.aabb()
        near = ~(np.any(self.lo > hi_t + margin, axis=1) | np.any(lo_t > self.hi + margin, axis=1))
        return clear_of([self.solid(k) for k in np.flatnonzero(near).tolist()], target, margin)


def _candidates(
    scene: Scene, tray: Tray, part: Part, hand: HandShape
) -> list[tuple[np.ndarray, str]]:
    """``(T_part_tcp, kind)``: the user's grasps if given, else the generated ones."""
    if part.grasps is None:
        return candidate_grasps(part, hand, scene.gripper)
    from pickstop.reach.so3 import quats_to_matrices

    cands: list[tuple[np.ndarray, str]] = []
    for gr in part.grasps:
        R_part_tcp = quats_to_matrices(np.asarray(gr.quaternion_wxyz))
        cands.append((transform(R_part_tcp, gr.position), "user"))
    return cands


def _heights(T_part_tcp: np.ndarray, kind: str, part: Part) -> list[np.ndarray]:
    """The grasp, then for a top-down one the same raised by ``LIFT_STEP`` up to ``MIN_HOLD``
    below the part's top."""
    out = [T_part_tcp]
    if kind == "top":
        top = _height(part.geometry) - MIN_HOLD
        z = T_part_tcp[2, 3] + LIFT_STEP
        while z <= top + 1e-9:
            T = T_part_tcp.copy()
            T[2, 3] = z
            out.append(T)
            z += LIFT_STEP
    return out


def clear_of(solids: list[Solid], target: Solid, margin: float) -> bool:
    """Do ``solids`` all keep at least ``margin`` [m] from ``target`` (coal distances)?"""
    lo_t, hi_t = target.aabb()
    gt, tt = _coal(target)
    for s in solids:
        lo, hi = s.aabb()
        if np.any(lo > hi_t + margin) or np.any(lo_t > hi + margin):
            continue
        g, t = _coal(s)
        d = coal.distance(g, t, gt, tt, coal.DistanceRequest(), coal.DistanceResult())
        if d < margin:
            return False
    return True


def hand_space(
    scene: Scene, tray: Tray, part: Part, hand: HandShape
) -> tuple[np.ndarray, np.ndarray]:
    """World bounds ``(lo, hi)`` [m] of the open hand at every candidate grasp of ``part`` (at
    every height it may be raised to): only what reaches into them can change its grasps."""
    T_world_part = world_part_transform(tray, part)
    corners = [
        hand.corners(T_world_part @ T)
        for T0, kind in _candidates(scene, tray, part, hand)
        for T in _heights(T0, kind, part)
    ]
    if not corners:
        centre = T_world_part[:3, 3]
        return centre, centre
    allc = np.concatenate(corners)
    return allc.min(axis=0), allc.max(axis=0)


@dataclass(frozen=True)
class OwnVerdicts:
    """A part's candidate grasps judged against its own tray alone: for each candidate (its
    kind) and each height it may be raised to, the grasp point and the open hand there, and
    what stops it: "low" (within the floor clearance), "own" (it meets the tray's body or
    its other parts), "part" (not clear of the part itself) or nothing ("ok"). All of it is
    fixed in the tray's frame: a tray moved along the floor (``at``, its floor position,
    changes) keeps every verdict, its hands carried with it (:meth:`moved`)."""

    at: np.ndarray  # (3,) [m] the tray's floor position (x, y, 0) they were judged at
    # per candidate: its kind, and per height the grasp point, the hand there (kept where
    # it is "ok" alone: nothing else is tested of the others) and the verdict
    cands: tuple[tuple[str, tuple[tuple[np.ndarray, _HandAt | None, str], ...]], ...]
    lo: np.ndarray  # (3,) [m] world bounds of every hand judged "ok"
    hi: np.ndarray
    yaw: float = 0.0  # [rad] the tray's yaw they were judged at

    def moved(self, at: np.ndarray, yaw: float | None = None) -> OwnVerdicts:
        """The same verdicts for the tray standing at floor position ``at: (3,)``, turned to
        ``yaw`` [rad] (None: as it was). A turn about the vertical carries the tray, its
        parts and the hands at its grasps rigidly and leaves every height as it was: what
        stops a grasp is the same."""
        at = np.asarray(at, float)
        turn = 0.0 if yaw is None else math.remainder(yaw - self.yaw, 2 * math.pi)
        d = at - self.at
        if not d.any() and turn == 0.0:
            return self
        if turn == 0.0:
            hands = tuple(
                (kind, tuple((T, h and h.shifted(d), v) for T, h, v in heights))
                for kind, heights in self.cands
            )
            return OwnVerdicts(at, hands, self.lo + d, self.hi + d, self.yaw)
        # about the vertical through where the tray stood, then to where it stands
        M = np.eye(4)
        M[:3, :3] = R_z(turn)
        M[:3, 3] = at - M[:3, :3] @ self.at
        hands = tuple(
            (kind, tuple((T, h and h.moved(M), v) for T, h, v in heights))
            for kind, heights in self.cands
        )
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for _, heights in hands:
            for _, h, _ in heights:
                if h is not None and len(h.lo):
                    lo, hi = np.minimum(lo, h.lo.min(0)), np.maximum(hi, h.hi.max(0))
        return OwnVerdicts(at, hands, lo, hi, self.yaw + turn)


def own_verdicts(scene: Scene, tray: Tray, part: Part, hand: HandShape) -> OwnVerdicts:
    """:class:`OwnVerdicts` of ``part`` in ``tray`` where it stands now."""
    T_world_part = world_part_transform(tray, part)
    own = SolidSet.of(
        tray_body_solids(tray) + [part_solid(tray, p) for p in tray.parts if p.id != part.id]
    )
    target = part_solid(tray, part)
    boxes = _HandBoxes.of(hand)
    cands = []
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for T0, kind in _candidates(scene, tray, part, hand):
        heights = []
        for T_part_tcp in _heights(T0, kind, part):
            at = boxes.at(T_world_part @ T_part_tcp)
            if at.below(scene.floor_clearance):
                verdict = "low"
            elif at.meets(own):
                verdict = "own"
            elif not at.clear_of(target, PART_CLEARANCE):
                verdict = "part"
            else:
                verdict = "ok"
                if len(at.lo):  # a hand of no geometry (no hand links) has no bounds
                    lo, hi = np.minimum(lo, at.lo.min(0)), np.maximum(hi, at.hi.max(0))
            heights.append((T_part_tcp, at if verdict == "ok" else None, verdict))
        cands.append((kind, tuple(heights)))
    at0 = np.array([tray.pose.x, tray.pose.y, 0.0])
    return OwnVerdicts(at0, tuple(cands), lo, hi, tray.pose.yaw)


def grasps_for_part(
    scene: Scene,
    tray: Tray,
    part: Part,
    hand: HandShape,
    own: OwnVerdicts | None = None,
    others: list[Solid] | None = None,
) -> GraspSet:
    """Grasps of ``part``: the user's if given, else generated; both filtered by the tray with
    the open hand's own geometry. ``own``: the part's :func:`own_verdicts`, judged before
    with the tray anywhere on the floor (the rest of the scene is tested here: the obstacles
    and the other trays with their parts, where they reach the hands; ``others``: those
    solids, :func:`~pickstop.scene.world.other_solids`, if made already)."""
    at0 = np.array([tray.pose.x, tray.pose.y, 0.0])
    own = own_verdicts(scene, tray, part, hand) if own is None else own.moved(at0, tray.pose.yaw)
    T_world_part = world_part_transform(tray, part)
    others = [
        s
        for s in (other_solids(scene, tray) if others is None else others)
        if np.all(s.aabb()[0] <= own.hi + TOUCH) and np.all(own.lo - TOUCH <= s.aabb()[1])
    ]
    obstacles = SolidSet.of(others) if others else None
    kept, kinds = [], []
    near_floor = 0
    n_cands = 0
    for kind, heights in own.cands:
        n_cands += 1
        low = False
        for T_part_tcp, at, verdict in heights:
            if verdict == "low":
                low = True
                continue
            if verdict != "ok":
                continue
            assert at is not None
            if obstacles is not None and at.meets(obstacles):
                continue
            kept.append(T_part_tcp)
            kinds.append(kind)
            break
        else:
            near_floor += low
    Ts = np.array(kept).reshape(-1, 4, 4)
    too_low = (
        part.grasps is None
        and "top" in scene.gripper.kinds
        and top_height(part, hand) >= _height(part.geometry)
    )
    return GraspSet(
        part_id=part.id,
        tray_id=tray.id,
        Ts_part_tcp=Ts,
        Ts_world_tool=T_world_part @ Ts @ hand.T_tcp_tool if len(Ts) else Ts,
        kinds=tuple(kinds),
        rejected=n_cands - len(kept),
        user_given=part.grasps is not None,
        too_low=too_low,
        near_floor=near_floor,
    )
