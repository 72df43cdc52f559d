"""Cache validity: when a region computed before is still the answer for a changed scene.

A region depends on its own tray, yaw, grid, floor, gripper, robot and database (its own key)
and on the other objects of the scene (a snapshot of their definitions and solids). A cached
region stays valid while every object that changed neither was, where it stood, something the
region's computation looked at (its envelope: hands, footprints, flagged solids), nor is, where
it stands now, within that envelope, over a free cell, or in the way of a witness arm.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pickstop.regions.arm import screen_arm
from pickstop.regions.cells import TrayRegion
from pickstop.regions.footprint import blocked_by
from pickstop.regions.kit import RegionKit
from pickstop.robot.kinematics import fk_soa
from pickstop.scene.model import Scene
from pickstop.scene.world import BoxArrays, Groups, Solid, object_solids

#: Every other object of a scene: its definition, its solids and their owner names.
Snapshot = dict[str, tuple[str, list[Solid], frozenset[str]]]


@dataclass(frozen=True)
class CacheEntry:
    """A computed region and the scene around its tray when it was computed."""

    region: TrayRegion
    snapshot: Snapshot
    cleared: set[str] = field(default_factory=set)  # new definitions no witness collides with
    # the region's witness_boxes, once asked for (_arm_boxes; the entry is frozen)
    boxes: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


def snapshots(scene: Scene, excludes: list[str], groups: Groups | None = None) -> list[Snapshot]:
    """For each tray id of ``excludes``, every object of ``scene`` but that tray: definition,
    solids, owner names (``groups``: the scene's
    :func:`~pickstop.scene.world.object_solids`, if made already)."""
    groups = object_solids(scene) if groups is None else groups
    every: dict[str, tuple[str, list[Solid], frozenset[str]]] = {}
    for o, g in zip(scene.obstacles, groups, strict=False):
        every[f"obstacle:{o.id}"] = (o.model_dump_json(), list(g), frozenset([o.id]))
    for t, g in zip(scene.trays, groups[len(scene.obstacles) :], strict=True):
        owners = frozenset([t.id, *(p.id for p in t.parts)])
        every[f"tray:{t.id}"] = (t.model_dump_json(), list(g), owners)
    return [{k: v for k, v in every.items() if k != f"tray:{x}"} for x in excludes]


def snapshot(scene: Scene, exclude: str, groups: Groups | None = None) -> Snapshot:
    """Every object but the tray ``exclude``: definition, solids, owner names."""
    return snapshots(scene, [exclude], groups)[0]


def witness_boxes(kit: RegionKit, region: TrayRegion) -> tuple[np.ndarray, np.ndarray]:
    """``(K * P, 3)`` lo and hi: the world box around the covering spheres of each witness
    arm of ``region`` (cell by cell, part by part), padded as the screens' boxes are: a solid
    whose bounds miss it is not flagged by the screen, so the witness is free of it."""
    from pickstop.speedups.checked import CheckedLinks

    K, P, dof = region.thetas.shape
    xy = np.repeat(region.grid.centres(region.cells[:, 1], region.cells[:, 0]), P, axis=0)
    th = region.thetas.reshape(K * P, dof)
    links = CheckedLinks.of(kit, th, xy, region.yaw, np.arange(K * P))
    J = len(links.lo) // max(K * P, 1)
    return links.lo.reshape(K * P, J, 3).min(1), links.hi.reshape(K * P, J, 3).max(1)


def _arm_boxes(kit: RegionKit, entry: CacheEntry) -> tuple[np.ndarray, np.ndarray]:
    """The :func:`witness_boxes` of the entry's region, computed once."""
    if not entry.boxes:
        entry.boxes.append(witness_boxes(kit, entry.region))
    return entry.boxes[0]


def witnesses_clear(
    kit: RegionKit,
    region: TrayRegion,
    solids: list[Solid],
    arm_boxes: tuple[np.ndarray, np.ndarray] | None = None,
) -> bool:
    """Is every witness arm of ``region`` free of ``solids``? The sphere screen first, coal
    for what it flags (the hands and footprints are covered by the region's envelope).
    ``arm_boxes``: the region's :func:`witness_boxes`, if known (only the witnesses whose box
    meets a solid's bounds are screened)."""
    if not len(region.cells) or not solids:
        return True
    K, P, dof = region.thetas.shape
    xy = np.repeat(region.grid.centres(region.cells[:, 1], region.cells[:, 0]), P, axis=0)
    s_lo = np.array([s.aabb()[0] for s in solids])
    s_hi = np.array([s.aabb()[1] for s in solids])
    if arm_boxes is not None:
        w_lo, w_hi = arm_boxes
        meets = np.zeros(K * P, bool)
        for a, b in zip(s_lo, s_hi, strict=True):
            meets |= np.all((w_lo <= b) & (a <= w_hi), axis=1)
        near = np.flatnonzero(meets)
    else:
        lo, hi = s_lo.min(0), s_hi.max(0)
        reach = kit.reach_xy + float(kit.arm.bound_r.max())
        near = np.flatnonzero(
            (xy[:, 0] > lo[0] - reach)
            & (xy[:, 0] < hi[0] + reach)
            & (xy[:, 1] > lo[1] - reach)
            & (xy[:, 1] < hi[1] + reach)
        )
    if not len(near):
        return True
    th = region.thetas.reshape(K * P, dof)[near]
    _, _, frames = fk_soa(kit.solver.chain, np.ascontiguousarray(th.T), frames=True)
    boxes = BoxArrays.of(solids)
    flagged = np.flatnonzero(screen_arm(kit.arm, boxes, frames, xy[near], region.yaw))
    checks = kit.exact_arm.checks(
        th[flagged], xy[near][flagged], region.yaw, solids, None, None, boxes
    )
    return not any(checks.colliding(i) for i in range(len(flagged)))


def still_valid(kit: RegionKit, entry: CacheEntry, snap: Snapshot) -> bool:
    """Is the cached region still the answer for the scene ``snap`` describes?"""
    env = entry.region.envelope
    if env is None:
        return False
    for k in entry.snapshot.keys() | snap.keys():
        old, new = entry.snapshot.get(k), snap.get(k)
        if old is not None and new is not None and old[0] == new[0]:
            continue
        if old is not None and (
            old[2] & env.hit_owners or any(env.touches(*s.aabb()) for s in old[1])
        ):
            return False  # where it was, it rejected something or shaped hand or footprint
        if new is None or new[0] in entry.cleared:
            continue
        if any(env.touches(*s.aabb()) for s in new[1]):
            return False  # where it is, it may block a hand or the footprint
        if blocked_by(kit.robot, new[1], env.free_xy, entry.region.yaw).any():
            return False  # where it is, it overhangs a free cell
        boxes = _arm_boxes(kit, entry) if len(entry.region.cells) else None
        if not witnesses_clear(kit, entry.region, new[1], boxes):
            return False  # where it is, it collides with a witness arm
        entry.cleared.add(new[0])
    return True
