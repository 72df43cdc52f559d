"""Grasp poses per part from its shape and the gripper, filtered against the tray.

A grasp is a tool pose in the part frame, ``T_part_tool``; the part frame sits at the part's
bottom centre, z up. Top-down grasps approach along -z at several angles about the vertical;
side grasps approach horizontally with the hand's width vertical or horizontal. A grasp whose
open hand would overlap the tray walls, the tray floor, the table or a neighbouring part is
dropped; the target part itself is never an obstacle for the fingers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pickstop.scene.model import Box, Cylinder, Gripper, Mesh, Part, Scene, Tray
from pickstop.scene.world import Solid, solids_overlap, tray_solids, world_part_transform


@dataclass(frozen=True)
class GraspSet:
    """Grasps of one part: ``Ts_part_tool: (k, 4, 4)``; ``kinds``: 'top' or 'side'."""

    part_id: str
    tray_id: str
    Ts_part_tool: np.ndarray
    Ts_world_tool: np.ndarray
    kinds: tuple[str, ...]
    rejected: int  # generated but blocked by the tray, table or neighbours
    user_given: bool


def _frame(x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, np.cross(x, y), p
    return T


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


def candidate_grasps(part: Part, gripper: Gripper) -> list[tuple[np.ndarray, str]]:
    """Every geometric grasp ``(T_part_tool, kind)`` the hand can close on (no environment)."""
    g = part.geometry
    h = _height(g)
    out: list[tuple[np.ndarray, str]] = []
    span = math.pi if gripper.symmetric else 2 * math.pi
    # Top-down: tool x down, closing direction turning about the vertical.
    # The fingertips stop 3 mm above the tray floor; the grasp point stays below the part top.
    z = max(h / 2, gripper.tip_offset + 0.003)
    if z < h:
        for i in range(gripper.top_down_angles):
            a = span * i / gripper.top_down_angles
            y = np.array([math.cos(a), math.sin(a), 0.0])
            if _extent_along(g, y) <= gripper.max_opening:
                out.append((_frame(np.array([0.0, 0.0, -1.0]), y, np.array([0, 0, z])), "top"))
    # Side: tool x horizontal towards the part, hand width vertical (closing horizontal) or
    # horizontal (closing vertical).
    for i in range(gripper.side_directions):
        b = 2 * math.pi * i / gripper.side_directions
        x = np.array([math.cos(b), math.sin(b), 0.0])
        for y in (np.array([-math.sin(b), math.cos(b), 0.0]), np.array([0.0, 0.0, 1.0])):
            if _extent_along(g, y) <= gripper.max_opening:
                out.append((_frame(x, y, np.array([0, 0, h / 2])), "side"))
    return out


def hand_solids(gripper: Gripper, T_world_tool: np.ndarray) -> list[Solid]:
    """The open hand as three boxes (two fingers, palm) in the world."""
    L, o, t, w, d = (
        gripper.finger_length,
        gripper.max_opening,
        gripper.finger_thickness,
        gripper.hand_width,
        gripper.palm_depth,
    )
    xm = gripper.tip_offset - L / 2  # finger centre along x
    boxes = [
        ((xm, (o + t) / 2, 0.0), (L, t, w)),
        ((xm, -(o + t) / 2, 0.0), (L, t, w)),
        ((xm - (L + d) / 2, 0.0, 0.0), (d, o + 2 * t, w)),
    ]
    out = []
    for centre, size in boxes:
        T = np.eye(4)
        T[:3, 3] = centre
        out.append(Solid.box(T_world_tool @ T, size, "hand"))
    return out


def _candidates(scene: Scene, tray: Tray, part: Part) -> list[tuple[np.ndarray, str]]:
    """``(T_part_tool, kind)``: the user's grasps if given, else the generated ones."""
    if part.grasps is None:
        return candidate_grasps(part, scene.gripper)
    from pickstop.reach.so3 import quats_to_matrices

    cands = []
    for gr in part.grasps:
        T = np.eye(4)
        T[:3, :3] = quats_to_matrices(np.asarray(gr.quaternion_wxyz))
        T[:3, 3] = gr.position
        cands.append((T, "user"))
    return cands


def hand_space(scene: Scene, tray: Tray, part: Part) -> tuple[np.ndarray, np.ndarray]:
    """World bounds ``(lo, hi)`` [m] of the open hand at every candidate grasp of ``part``:
    only what reaches into them can change its grasps."""
    T_world_part = world_part_transform(tray, part)
    boxes = [
        s.aabb()
        for T_part_tool, _ in _candidates(scene, tray, part)
        for s in hand_solids(scene.gripper, T_world_part @ T_part_tool)
    ]
    if not boxes:
        centre = T_world_part[:3, 3]
        return centre, centre
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def grasps_for_part(scene: Scene, tray: Tray, part: Part) -> GraspSet:
    """Grasps of ``part``: the user's if given, else generated; both filtered by the tray."""
    T_world_part = world_part_transform(tray, part)
    cands = _candidates(scene, tray, part)
    obstacles = tray_solids(scene, tray, exclude_part=part.id)
    kept, kinds = [], []
    for T_part_tool, kind in cands:
        hand = hand_solids(scene.gripper, T_world_part @ T_part_tool)
        if not any(solids_overlap(a, b) for a in hand for b in obstacles):
            kept.append(T_part_tool)
            kinds.append(kind)
    Ts = np.array(kept).reshape(-1, 4, 4)
    return GraspSet(
        part_id=part.id,
        tray_id=tray.id,
        Ts_part_tool=Ts,
        Ts_world_tool=T_world_part @ Ts if len(Ts) else Ts,
        kinds=tuple(kinds),
        rejected=len(cands) - len(kept),
        user_given=part.grasps is not None,
    )
