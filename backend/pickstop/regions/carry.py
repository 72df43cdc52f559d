"""A known region carried with its tray: what a preview draws while the tray is dragged.

The cells of a region computed with the tray at one pose are moved rigidly with the tray to
its new pose (x, y and yaw), snapped to the base grid, and kept where the base footprint still
fits the floor and its obstacles. The base's own yaw does not turn with the tray, so after a
turn the carried shape is only a sketch; after a translation it is what the exact region
would be if nothing but the footprint had changed. Either way nothing in it is verified: the
exact region replaces it when the tray is released.
"""

from __future__ import annotations

import math
import time

import numpy as np
import shapely

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
    moved = []
    for was, region in known:
        now = scene.tray(region.tray_id)
        xy = region.grid.centres(region.cells[:, 1], region.cells[:, 0])  # (K, 2) [m]
        turn = now.pose.yaw - was.pose.yaw
        c, s = math.cos(turn), math.sin(turn)
        rel = xy - [was.pose.x, was.pose.y]
        xy = rel @ np.array([[c, s], [-s, c]]) + [now.pose.x, now.pose.y]
        ix = np.floor((xy[:, 0] - grid.x0) / grid.res).astype(np.int64)
        iy = np.floor((xy[:, 1] - grid.y0) / grid.res).astype(np.int64)
        keep = np.flatnonzero((ix >= 0) & (ix < grid.nx) & (iy >= 0) & (iy < grid.ny))
        _, first = np.unique(iy[keep] * grid.nx + ix[keep], return_index=True)
        keep = keep[np.sort(first)]
        moved.append((keep, ix[keep], iy[keep]))
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
        mask = np.zeros((grid.ny, grid.nx), bool)
        mask[iy, ix] = True
        out.append(
            TrayRegion(
                region.tray_id,
                region.yaw,
                grid,
                mask,
                np.stack([iy, ix], 1),
                region.part_ids,
                region.thetas[keep],
                region.grasp_index[keep],
                grid.cells_polygon(iy, ix) if len(ix) else shapely.Polygon(),
                {"carried": len(region.cells), "footprint_free": len(ix)},
                None if len(ix) else f"tray {region.tray_id!r}: no carried cell has room",
                time.perf_counter() - t0,
                f"carried:{region.key}",
                None,
            )
        )
    return out
