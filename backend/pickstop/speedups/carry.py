"""A known region carried with its tray: what a preview draws while the tray is dragged.

The cells of a region computed with the tray at one pose are moved rigidly with the tray to
its new pose (x, y and yaw): a cell of the base grid is in the carried region where its centre,
carried back with the tray, falls in a cell of the region, and it is kept where the base
footprint still fits the floor and its obstacles. The base's own yaw does not turn with the
tray, so after a turn the carried shape is only a sketch; after a translation it is what the
exact region would be if nothing but the footprint had changed. Either way nothing in it is
verified: the exact region replaces it when the tray is released.
"""

from __future__ import annotations

import hashlib
import json
import math
import time

import numpy as np

from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.regions.footprint import footprint_free
from pickstop.robot.model import RobotModel
from pickstop.scene.model import Scene, Tray


def carried_regions(
    robot: RobotModel, scene: Scene, known: list[tuple[Tray, TrayRegion]]
) -> list[TrayRegion]:
    """Each ``(was, region)``, computed with its tray as ``was``, carried to where the tray
    stands in ``scene``; the footprints of every tray's cells are checked at once per yaw."""
    t0 = time.perf_counter()
    grid = CellGrid.of(scene)
    moved = [_carry(region, was, scene.tray(region.tray_id), grid) for was, region in known]
    fits: list[np.ndarray] = [np.zeros(0, bool)] * len(known)
    for yaw in {r.yaw for _, r in known}:
        mine = [k for k, (_, r) in enumerate(known) if r.yaw == yaw]
        cen = [grid.centres(moved[k][1], moved[k][2]) for k in mine]
        ok = footprint_free(scene, robot, np.concatenate(cen), yaw)
        for k, part in zip(mine, np.split(ok, np.cumsum([len(c) for c in cen])[:-1]), strict=True):
            fits[k] = part
    out = []
    for (_, region), (keep, ix, iy), ok in zip(known, moved, fits, strict=True):
        keep, ix, iy = keep[ok], ix[ok], iy[ok]
        out.append(
            TrayRegion.of_cells(
                region.tray_id,
                region.yaw,
                grid,
                np.stack([iy, ix], 1),
                region.part_ids,
                region.thetas[keep],
                region.grasp_index[keep],
                {"carried": len(region.cells), "footprint_free": len(ix)},
                None if len(ix) else f"tray {region.tray_id!r}: no carried cell has room",
                time.perf_counter() - t0,
                f"carried:{region.key}",
            )
        )
    return out


def _carry(
    region: TrayRegion, was: Tray, now: Tray, grid: CellGrid
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cells of ``grid`` the region covers once carried from ``was`` to ``now``: each
    cell whose centre, carried back, falls in a cell of the region (so a turned region has
    no holes where the turned grid and the grid fall out of step). Returns, per cell, the
    region's row it comes from, its ``ix`` and ``iy``."""
    none = np.zeros(0, np.int64)
    if not len(region.cells):
        return none, none, none
    src = region.grid
    turn = now.pose.yaw - was.pose.yaw
    c, s = math.cos(turn), math.sin(turn)
    rot = np.array([[c, s], [-s, c]])  # row vectors: v @ rot turns v by +turn
    xy = src.centres(region.cells[:, 1], region.cells[:, 0])
    ahead = (xy - [was.pose.x, was.pose.y]) @ rot + [now.pose.x, now.pose.y]
    pad = src.res  # a carried cell's centre lies within this of a cell it covers
    corners = np.array([ahead.min(0) - pad, ahead.max(0) + pad])
    lo, hi = np.stack(grid.cell_of(corners), 1)
    lo, hi = np.maximum(lo, 0), np.minimum(hi, [grid.nx - 1, grid.ny - 1])
    if np.any(hi < lo):
        return none, none, none
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    ix, iy = gx.ravel(), gy.ravel()
    back = (grid.centres(ix, iy) - [now.pose.x, now.pose.y]) @ rot.T + [was.pose.x, was.pose.y]
    sx, sy = src.cell_of(back)
    inside = (sx >= 0) & (sx < src.nx) & (sy >= 0) & (sy < src.ny)
    row_of = np.full((src.ny, src.nx), -1, np.int64)
    row_of[region.cells[:, 0], region.cells[:, 1]] = np.arange(len(region.cells))
    row = np.full(len(ix), -1, np.int64)
    row[inside] = row_of[sy[inside], sx[inside]]
    keep = np.flatnonzero(row >= 0)
    return row[keep], ix[keep], iy[keep]


class LastRegions:
    """The last regions computed for each tray, each with the tray as it stood: what a preview
    carries. Keyed by tray id, yaw and what the tray is (its pose aside); a few poses per key,
    the newest first, so that a preview carries the region computed nearest to where the tray
    is now, and an empty region (the tray once dragged out of reach) does not hide the regions
    known elsewhere."""

    def __init__(self, size: int, per_tray: int = 4) -> None:
        self.size = size  # regions kept in all
        self.per_tray = per_tray  # poses kept per key
        self._by_tray: dict[tuple[str, float, str], list[tuple[Tray, TrayRegion]]] = {}
        self._count = 0  # regions kept

    def remember(self, scene: Scene, region: TrayRegion) -> None:
        """Keep ``region``, computed in ``scene``, as its tray's newest; the trays remembered
        least recently go while more than ``size`` regions are kept."""
        key = (region.tray_id, region.yaw, carry_key(scene, region.tray_id))
        tray = scene.tray(region.tray_id)
        was = self._by_tray.pop(key, [])
        kept = [(tray, region), *(e for e in was if e[0].pose != tray.pose)][: self.per_tray]
        self._by_tray[key] = kept
        self._count += len(kept) - len(was)
        while self._count > self.size and len(self._by_tray) > 1:
            self._count -= len(self._by_tray.pop(next(iter(self._by_tray))))

    def carried(
        self, robot: RobotModel, scene: Scene, pairs: list[tuple[str, float]]
    ) -> dict[tuple[str, float], TrayRegion]:
        """For each ``(tray id, yaw)`` remembered: the region computed nearest to where the tray
        stands in ``scene`` (:func:`nearest`), carried there (:func:`carried_regions`)."""
        known = []
        for p in pairs:
            entries = self._by_tray.get((*p, carry_key(scene, p[0])))
            if entries:
                known.append((p, nearest(entries, scene.tray(p[0]))))
        carried = carried_regions(robot, scene, [k for _, k in known])
        return {p: r for (p, _), r in zip(known, carried, strict=True)}

    def __len__(self) -> int:
        """Regions kept."""
        return self._count

    def clear(self) -> None:
        self._by_tray.clear()
        self._count = 0


TURN_LENGTH = 0.5  # [m per rad]: how far a turn of the tray counts against a translation


def nearest(entries: list[tuple[Tray, TrayRegion]], now: Tray) -> tuple[Tray, TrayRegion]:
    """Of the ``(tray as it stood, region)`` entries, the one whose tray stood nearest to
    ``now`` (a translation plus ``TURN_LENGTH`` per radian turned), among those with cells if
    any has some; ties go to the newest (the first)."""

    def far(e: tuple[Tray, TrayRegion]) -> tuple[bool, float]:
        was, region = e
        turn = math.remainder(now.pose.yaw - was.pose.yaw, math.tau)
        moved = math.hypot(now.pose.x - was.pose.x, now.pose.y - was.pose.y)
        return len(region.cells) == 0, moved + TURN_LENGTH * abs(turn)

    return min(entries, key=far)


def carry_key(scene: Scene, tray_id: str) -> str:
    """What a region carried with its tray must share with the region it was computed as: the
    tray itself but for its pose, and the scene's settings every region depends on. A tray of
    the same id in another scene, or with other parts, is another tray."""
    tray = scene.tray(tray_id).model_dump(mode="json", exclude={"pose"})
    blob = [
        tray,
        *(
            scene.model_dump(
                mode="json", include={"robot", "gripper", "base_grid", "floor_clearance"}
            ).values()
        ),
    ]
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()
