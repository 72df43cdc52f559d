"""The region pipeline: a tray's base region from scratch, step by step.

Cells within the arm's reach of the tray, where the base footprint fits; the grasps of every
part; the cells the database serves; part by part, IK by query and verification
(:mod:`pickstop.regions.solve`); growth into open neighbours from the solved cells' witnesses.
Whatever the computation looks at is marked on the region's envelope, which
:mod:`pickstop.regions.validity` reads to tell when the region may be reused.
"""

from __future__ import annotations

import hashlib
import json
import math
import time

import numpy as np
import shapely

from pickstop import frames
from pickstop.regions import solve
from pickstop.regions.arm import nearby
from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.regions.envelope import Envelope
from pickstop.regions.footprint import footprint_check
from pickstop.regions.kit import RegionKit
from pickstop.regions.reuse import TrayAnchor, grasps_digest
from pickstop.regions.solve import ArmWorld, Targets
from pickstop.scene.grasps import GraspSet
from pickstop.scene.model import Scene, Tray
from pickstop.scene.world import BoxArrays, Solid, scene_solids


def compute_tray_region(
    planner: RegionKit, scene: Scene, tray: Tray, yaw: float, key: str = ""
) -> TrayRegion:
    t0 = time.perf_counter()
    robot = planner.robot
    grid = CellGrid.of(scene)
    counts = {"grid": grid.nx * grid.ny}
    part_ids = tuple(p.id for p in tray.parts)

    env = Envelope.empty(scene.floor.min, scene.floor.max)
    # The open hands at every candidate grasp: what reaches in there may change the grasps.
    for part in tray.parts:
        env.mark_box(*planner.hand_space(scene, tray, part))

    def empty(reason: str) -> TrayRegion:
        return TrayRegion(
            tray.id,
            yaw,
            grid,
            np.zeros((grid.ny, grid.nx), bool),
            np.zeros((0, 2), int),
            part_ids,
            np.zeros((0, len(part_ids), robot.dof)),
            np.zeros((0, len(part_ids)), int),
            shapely.Polygon(),
            counts,
            reason,
            time.perf_counter() - t0,
            key,
            env,
        )

    if not tray.parts:
        return empty(f"tray {tray.id!r} has no parts")
    tc = np.array([tray.pose.x, tray.pose.y])
    reach, solids, boxes, R_base_world = tray_world(planner, scene, tray, yaw)
    # Cells within reach of the tray (a bounding window, then the disc).
    lo = np.floor((tc - reach - [grid.x0, grid.y0]) / grid.res).astype(int)
    hi = np.ceil((tc + reach - [grid.x0, grid.y0]) / grid.res).astype(int)
    ix = np.arange(max(lo[0], 0), min(hi[0], grid.nx))
    iy = np.arange(max(lo[1], 0), min(hi[1], grid.ny))
    IX2, IY2 = np.meshgrid(ix, iy)
    IX, IY = IX2.ravel(), IY2.ravel()
    cen = grid.centres(IX, IY)
    near = np.hypot(*(cen - tc).T) <= reach
    IX, IY, cen = IX[near], IY[near], cen[near]
    counts["in_reach"] = len(IX)
    fp = robot.footprint
    env.mark_columns(cen, fp.bounding_radius, fp.height)
    if len(IX) == 0:
        return empty(
            f"tray {tray.id!r} is farther than the arm reaches ({reach:.2f} m) from every grid cell"
        )
    free, overhangs = footprint_check(scene, robot, cen, yaw)
    env.hit_owners |= overhangs
    IX, IY, cen = IX[free], IY[free], cen[free]
    counts["footprint_free"] = len(IX)
    env.free_xy = cen
    if len(IX) == 0:
        return empty(f"no cell within reach of tray {tray.id!r} has room for the base footprint")

    grasp_sets = planner.grasps(scene, tray)
    for gs in grasp_sets:
        if len(gs.Ts_world_tool) == 0:
            low = (
                f"; no top-down grasp: the open hand reaches {planner.hand.reach:.3f} m past "
                "its grasp point, which would put it below the tray floor for a part this low"
                if gs.too_low
                else ""
            )
            return empty(
                f"part {gs.part_id!r} of tray {tray.id!r}: none of its {gs.rejected} grasps "
                "fits the robot's open hand without touching the tray, a neighbour or a table, "
                f"or coming within the floor clearance of {scene.floor_clearance:.3f} m "
                f"({gs.near_floor} of them too close to the floor)" + low
            )
    world = ArmWorld(boxes, solids, yaw, env, scene.floor_clearance)
    anchor = TrayAnchor.of(grid.x0, grid.y0, grid.res, tray)
    memo = planner.reuse.memo(reuse_key(planner, scene, tray, yaw, anchor, grasp_sets))
    keys = anchor.cell_keys(IX, IY)
    targets = [Targets.of(gs, cen, R_base_world, keys, memo) for gs in grasp_sets]
    # Cells the database cannot serve for some part are left to the growth below.
    alive = np.flatnonzero(
        memo.served(keys, lambda idx: solve.served(planner.db, [t.take(idx) for t in targets]))
    )
    counts["served"] = len(alive)
    witness = np.zeros((len(IX), len(part_ids), robot.dof))
    grasp_of = np.zeros((len(IX), len(part_ids)), int)
    for k, tg in enumerate(targets):
        found, th, gi = solve.solve_part(planner, world, tg.take(alive), cen[alive])
        alive = alive[found]
        witness[alive, k] = th[found]
        grasp_of[alive, k] = gi[found]
        counts[f"feasible_after_{tg.grasps.part_id}"] = len(alive)
        if len(alive) == 0:
            return empty(
                f"no base cell lets the arm grasp part {tg.grasps.part_id!r} of tray "
                f"{tray.id!r} without collision (of {counts['footprint_free']} reachable "
                "free cells)"
            )
    solved = np.zeros(len(IX), bool)
    solved[alive] = True
    counts["grown"] = solve.grow(
        planner, world, targets, cen, np.stack([IY, IX], 1), solved, witness, grasp_of
    )
    alive = np.flatnonzero(solved)
    mask = np.zeros((grid.ny, grid.nx), bool)
    mask[IY[alive], IX[alive]] = True
    cells = np.stack([IY[alive], IX[alive]], 1)
    counts["feasible"] = len(alive)
    return TrayRegion(
        tray.id,
        yaw,
        grid,
        mask,
        cells,
        part_ids,
        witness[alive],
        grasp_of[alive],
        grid.cells_polygon(cells[:, 0], cells[:, 1]),
        counts,
        None,
        time.perf_counter() - t0,
        key,
        env,
    )


def reuse_key(
    planner: RegionKit,
    scene: Scene,
    tray: Tray,
    yaw: float,
    anchor: TrayAnchor,
    grasp_sets: list[GraspSet],
) -> str:
    """What the refinements from cells anchored to ``tray`` depend on: everything the region
    does except the tray's position in whole cells and the rest of the scene."""
    pose = tray.pose.model_dump()
    pose.pop("x"), pose.pop("y")
    blob = {
        "tray": tray.model_dump(exclude={"pose", "name"}),
        "pose": pose,
        "phase": anchor.phase,
        "yaw": yaw,
        "res": scene.base_grid.resolution,
        "hand": planner.hand.key,
        "robot": planner.robot.robot_hash,
        "db": planner.db.id,
        "algo": solve.VERSION,
        "grasps": grasps_digest(tray, grasp_sets),
    }
    return hashlib.sha256(json.dumps(blob, sort_keys=True, default=str).encode()).hexdigest()


def tray_world(
    planner: RegionKit, scene: Scene, tray: Tray, yaw: float
) -> tuple[float, list[Solid], BoxArrays, np.ndarray]:
    """Reach radius around the tray [m], the solids near it (exact and as arrays), R_base_world."""
    tc = np.array([tray.pose.x, tray.pose.y])
    reach = planner.reach_xy + 0.5 * math.hypot(*tray.outer_size)
    solids = nearby(scene_solids(scene), tc, reach + planner.reach_xy + 0.2)
    return reach, solids, BoxArrays.of(solids), frames.R_base_world(yaw)
