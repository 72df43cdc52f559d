"""The scene as solids: coal objects for exact checks, analytic shapes for the vectorised screen.

Every solid is a box, a vertical cylinder or a mesh with a world transform ``T_world_solid``
(4 x 4) at its centre. For the conservative screen a mesh is replaced by its oriented bounding
box, so a sphere that misses the box surely misses the mesh.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import coal
import numpy as np

from pickstop.frames import T_yaw, transform
from pickstop.scene.model import Box, Cylinder, Mesh, Part, Pose, Scene, Tray
from pickstop.scene.tray_body import tray_body_boxes

TOUCH = 1e-4  # [m] allowed interpenetration: resting on a surface is not a collision
# [m] where two scenes agree this far around a region, more than TOUCH, every collision
# answer for geometry inside the region is the same in both (a penetration depth cannot
# tell them apart): the padding of the regions that remembered answers depend on
AGREE_MARGIN = 0.002


def pose_matrix(pose: Pose, dz: float = 0.0) -> np.ndarray:
    """``T_world_x`` (4, 4) of a pose (x, y, z + dz, yaw)."""
    return T_yaw(pose.x, pose.y, pose.z + dz, pose.yaw)


def tray_transform(tray: Tray) -> np.ndarray:
    """``T_world_tray``: the inner floor centre, z along the floor's normal (up unless the
    tray is tilted about its own x or y axis)."""
    T = pose_matrix(tray.pose)
    if tray.tilt is not None:
        T[:3, :3] = T[:3, :3] @ tray.tilt.matrix()
    return T


def world_part_transform(tray: Tray, part: Part) -> np.ndarray:
    """``T_world_part``: the part's bottom centre, z along its tray floor's normal."""
    return tray_transform(tray) @ pose_matrix(part.pose)


@dataclass(frozen=True, eq=False)
class Solid:
    """A rigid shape in the world. ``half`` is the half extents of its bounding box [m]."""

    kind: Literal["box", "cylinder", "mesh"]
    T_world_solid: np.ndarray  # (4, 4) centre
    half: np.ndarray  # (3,)
    owner: str  # id of the obstacle, tray or part (or "hand")
    radius: float = 0.0  # cylinders
    geometry: Any = field(default=None, repr=False)  # coal geometry

    @classmethod
    def box(cls, T: np.ndarray, size: Any, owner: str) -> Solid:
        size = np.asarray(size, dtype=float)
        return cls("box", T, size / 2, owner, 0.0, coal.Box(*size))

    @classmethod
    def cylinder(cls, T: np.ndarray, radius: float, height: float, owner: str) -> Solid:
        half = np.array([radius, radius, height / 2])
        return cls("cylinder", T, half, owner, radius, coal.Cylinder(radius, height))

    @property
    def transform(self) -> coal.Transform3s:
        return coal.Transform3s(self.T_world_solid[:3, :3], self.T_world_solid[:3, 3])

    @property
    def aligned_box(self) -> bool:
        """A box turned only by a permutation of the axes (with signs): its bounds
        (:meth:`aabb`) are the box itself. Computed once."""
        hit = self.__dict__.get("_aligned")
        if hit is None:
            A = np.abs(self.T_world_solid[:3, :3])
            hit = self.kind == "box" and bool(np.allclose(A, np.round(A), atol=1e-12))
            self.__dict__["_aligned"] = hit
        return hit

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        """World bounds ``(lo, hi)`` [m], computed once (read-only: a solid does not move)."""
        hit = self.__dict__.get("_aabb")
        if hit is None:
            R = self.T_world_solid[:3, :3]
            ext = np.abs(R) @ self.half
            c = self.T_world_solid[:3, 3]
            lo, hi = c - ext, c + ext
            lo.setflags(write=False)
            hi.setflags(write=False)
            hit = self.__dict__["_aabb"] = (lo, hi)
        return hit

    def pose_digest(self) -> bytes:
        """Its pose and half extents as bytes (what a solid's bounding box depends on),
        computed once."""
        hit = self.__dict__.get("_pose_digest")
        if hit is None:
            hit = self.__dict__["_pose_digest"] = (
                np.ascontiguousarray(self.T_world_solid, float).tobytes()
                + np.ascontiguousarray(self.half, float).tobytes()
            )
        return hit


def shape_solid(
    geometry: Box | Cylinder | Mesh, T_world_base: np.ndarray, owner: str, root: Path | None = None
) -> Solid:
    """Solid of a scene shape whose frame ``T_world_base`` is its bottom centre."""
    if isinstance(geometry, Box):
        T = T_world_base.copy()
        T[:3, 3] += T[:3, 2] * geometry.size[2] / 2
        return Solid.box(T, geometry.size, owner)
    if isinstance(geometry, Cylinder):
        T = T_world_base.copy()
        T[:3, 3] += T[:3, 2] * geometry.height / 2
        return Solid.cylinder(T, geometry.radius, geometry.height, owner)
    path = Path(geometry.path)
    if root is not None and not path.is_absolute():
        path = root / path
    mesh = coal.MeshLoader().load(str(path), np.full(3, geometry.scale))
    mesh.computeLocalAABB()
    lo, hi = np.asarray(mesh.aabb_local.min_), np.asarray(mesh.aabb_local.max_)
    T = T_world_base.copy()
    T[:3, 3] += T[:3, :3] @ ((lo + hi) / 2)
    # The coal mesh keeps its own frame: wrap it so the solid's transform is the box centre.
    return Solid("mesh", T, (hi - lo) / 2, owner, 0.0, _Offset(mesh, (lo + hi) / 2))


@dataclass(frozen=True)
class _Offset:
    """A coal geometry whose frame sits ``offset`` away from the solid's centre."""

    geometry: Any
    offset: np.ndarray


def _coal(s: Solid) -> tuple[Any, coal.Transform3s]:
    if isinstance(s.geometry, _Offset):
        T = s.T_world_solid.copy()
        T[:3, 3] -= T[:3, :3] @ s.geometry.offset
        return s.geometry.geometry, coal.Transform3s(T[:3, :3], T[:3, 3])
    return s.geometry, s.transform


_REQ_TOUCH = coal.CollisionRequest()
_REQ_TOUCH.security_margin = -TOUCH
_REQ_EXACT = coal.CollisionRequest()  # coal allows no negative margin for meshes


def collide(ga: Any, ta: coal.Transform3s, gb: Any, tb: coal.Transform3s) -> bool:
    """coal collision of two geometries; between primitives, touching is not colliding."""
    mesh = isinstance(ga, coal.BVHModelBase) or isinstance(gb, coal.BVHModelBase)
    req = _REQ_EXACT if mesh else _REQ_TOUCH
    return bool(coal.collide(ga, ta, gb, tb, req, coal.CollisionResult()))


def solids_overlap(a: Solid, b: Solid) -> bool:
    """Exact test with coal; touching (up to ``TOUCH``) is not overlapping."""
    lo_a, hi_a = a.aabb()
    lo_b, hi_b = b.aabb()
    if np.any(lo_a > hi_b - TOUCH) or np.any(lo_b > hi_a - TOUCH):
        return False
    ga, ta = _coal(a)
    gb, tb = _coal(b)
    return collide(ga, ta, gb, tb)


@dataclass(frozen=True)
class SolidSet:
    """Solids with their bounds as arrays, for overlap tests of many solids against them."""

    solids: list[Solid]
    lo: np.ndarray  # (K, 3) [m]
    hi: np.ndarray  # (K, 3)

    @classmethod
    def of(cls, solids: list[Solid]) -> SolidSet:
        bounds = [s.aabb() for s in solids]
        lo = np.array([b[0] for b in bounds]).reshape(-1, 3)
        hi = np.array([b[1] for b in bounds]).reshape(-1, 3)
        return cls(solids, lo, hi)

    def overlaps(self, a: Solid) -> bool:
        """:func:`solids_overlap` of ``a`` and any of the solids (their bounds first, at once)."""
        lo_a, hi_a = a.aabb()
        near = np.all(lo_a <= self.hi - TOUCH, axis=1) & np.all(self.lo <= hi_a - TOUCH, axis=1)
        return any(solids_overlap(a, self.solids[k]) for k in np.flatnonzero(near).tolist())


def solid_below(s: Solid, clearance: float) -> bool:
    """Exact (coal): does ``s`` reach down to ``z <= clearance`` [m] (the floor is z = 0)?"""
    from pickstop.robot.floor import geometry_below

    if s.aabb()[0][2] > clearance:
        return False
    g, t = _coal(s)
    return geometry_below(g, transform(t.getRotation(), t.getTranslation()), clearance)


def tray_body_solids(tray: Tray) -> list[Solid]:
    """The tray's floor and four walls (:func:`pickstop.scene.tray_body.tray_body_boxes`)."""
    T = tray_transform(tray)
    boxes = tray_body_boxes(
        tray.inner_size, tray.wall_thickness, tray.wall_height, tray.floor_thickness
    )
    return [Solid.box(T @ _shift(*b.centre), b.size, tray.id) for b in boxes]


def _shift(x: float, y: float, z: float) -> np.ndarray:
    return transform(np.eye(3), (x, y, z))


def part_solid(tray: Tray, part: Part, root: Path | None = None) -> Solid:
    return shape_solid(part.geometry, world_part_transform(tray, part), part.id, root)


def obstacle_solids(scene: Scene, root: Path | None = None) -> list[Solid]:
    return [shape_solid(o.geometry, pose_matrix(o.pose), o.id, root) for o in scene.obstacles]


def tray_solids(
    scene: Scene, tray: Tray, exclude_part: str | None = None, root: Path | None = None
) -> list[Solid]:
    """What a hand reaching into ``tray`` can hit: its body, its other parts, the obstacles
    and the other trays (with their parts)."""
    out = tray_body_solids(tray)
    out += [part_solid(tray, p, root) for p in tray.parts if p.id != exclude_part]
    out += obstacle_solids(scene, root)
    for other in scene.trays:
        if other.id != tray.id:
            out += tray_body_solids(other) + [part_solid(other, p, root) for p in other.parts]
    return out


Groups = tuple[tuple[Solid, ...], ...]  # the solids of each object of a scene, in order


def object_solids(scene: Scene, root: Path | None = None) -> Groups:
    """The solids of each object of the scene: each obstacle's, then each tray's (its body,
    then its parts), in order (a planner keeps them per scene:
    :meth:`pickstop.regions.kit.RegionKit.object_solids`)."""
    return tuple((s,) for s in obstacle_solids(scene, root)) + tuple(
        tuple(tray_body_solids(t) + [part_solid(t, p, root) for p in t.parts]) for t in scene.trays
    )


def scene_solids(
    scene: Scene, root: Path | None = None, groups: Groups | None = None
) -> list[Solid]:
    """Every solid of the scene (``groups``: its :func:`object_solids`, if made already)."""
    groups = object_solids(scene, root) if groups is None else groups
    return [s for group in groups for s in group]


def other_solids(scene: Scene, tray: Tray, groups: Groups | None = None) -> list[Solid]:
    """Every solid of the scene but ``tray``'s own (its body and parts): the obstacles and
    the other trays with their parts (``groups``: the scene's :func:`object_solids`, if made
    already)."""
    groups = object_solids(scene) if groups is None else groups
    mine = len(scene.obstacles) + next(i for i, t in enumerate(scene.trays) if t.id == tray.id)
    return [s for k, group in enumerate(groups) if k != mine for s in group]


@dataclass(frozen=True)
class BoxArrays:
    """Solids as oriented boxes for the vectorised screen (cylinders by their own shape)."""

    centres: np.ndarray  # (K, 3)
    R: np.ndarray  # (K, 3, 3) world axes of each box
    half: np.ndarray  # (K, 3)
    is_cylinder: np.ndarray  # (K,) vertical cylinders: exact radial test
    radius: np.ndarray  # (K,)
    owners: tuple[str, ...]
    lo: np.ndarray  # (K, 3) world axis-aligned bounds, for a cheap first test
    hi: np.ndarray  # (K, 3)

    @classmethod
    def of(cls, solids: list[Solid]) -> BoxArrays:
        if not solids:
            z = np.zeros((0, 3))
            return cls(z, np.zeros((0, 3, 3)), z, np.zeros(0, bool), np.zeros(0), (), z, z)
        bounds = [s.aabb() for s in solids]
        return cls(
            centres=np.array([s.T_world_solid[:3, 3] for s in solids]),
            R=np.array([s.T_world_solid[:3, :3] for s in solids]),
            half=np.array([s.half for s in solids]),
            is_cylinder=np.array(
                [s.kind == "cylinder" and abs(s.T_world_solid[2, 2] - 1) < 1e-9 for s in solids]
            ),
            radius=np.array([s.radius for s in solids]),
            owners=tuple(s.owner for s in solids),
            lo=np.array([b[0] for b in bounds]),
            hi=np.array([b[1] for b in bounds]),
        )

    @functools.cached_property
    def owner_index(self) -> dict[str, int]:
        """Each owner's code: its index among the owners in order of first appearance."""
        return {o: i for i, o in enumerate(dict.fromkeys(self.owners))}

    @functools.cached_property
    def owner_codes(self) -> np.ndarray:
        """``(K,)`` int64: the code of each solid's owner (:attr:`owner_index`)."""
        return np.array([self.owner_index[o] for o in self.owners], dtype=np.int64)


def spheres_hit(
    boxes: BoxArrays,
    centres: np.ndarray,
    radii: np.ndarray,
    hit_boxes: set[int] | None = None,
    skip: np.ndarray | None = None,
) -> np.ndarray:
    """Which spheres ``(M, 3)``, ``(M,)`` [m] intersect any solid: ``(M,)`` bool.

    Exact for boxes and vertical cylinders, conservative for meshes (their bounding box).
    hit_boxes: if given, the indices of the boxes that were hit are added to it.
    skip: ``(M,)`` per sphere, the owner code (index among ``dict.fromkeys(boxes.owners)``) of
    the solids it may touch (-1: none).
    """
    hit = np.zeros(len(centres), bool)
    if len(centres) == 0 or len(boxes.centres) == 0:
        return hit
    # Bounds test of every sphere against every box at once, one axis at a time.
    # (boxes, spheres): one box's candidates are contiguous for the loop below
    near = np.ones((len(boxes.centres), len(centres)), bool)
    if skip is not None and (skip >= 0).any():
        near &= boxes.owner_codes[:, None] != skip[None, :]
    for a in range(3):
        lo_a = centres[:, a] - radii
        hi_a = centres[:, a] + radii
        near &= (hi_a[None, :] > boxes.lo[:, a, None]) & (lo_a[None, :] < boxes.hi[:, a, None])
    for k in np.flatnonzero(near.any(axis=1)):
        idx = np.flatnonzero(near[k] & ~hit)
        if len(idx) == 0:
            continue
        d = (centres[idx] - boxes.centres[k]) @ boxes.R[k]  # sphere centres in the box frame
        if boxes.is_cylinder[k]:
            radial = np.maximum(np.hypot(d[:, 0], d[:, 1]) - boxes.radius[k], 0.0)
            axial = np.maximum(np.abs(d[:, 2]) - boxes.half[k, 2], 0.0)
            dist2 = radial**2 + axial**2
        else:
            q = np.maximum(np.abs(d) - boxes.half[k], 0.0)
            dist2 = np.einsum("ij,ij->i", q, q)
        inside = idx[dist2 < (radii[idx] - TOUCH) ** 2]
        if len(inside):
            hit[inside] = True
            if hit_boxes is not None:
                hit_boxes.add(int(k))
    return hit
