"""Off-grid checks: the region's exact test at arbitrary base poses.

A stop's inscribed centre or a Monte Carlo sample of the base pose seldom falls on a cell
centre. :func:`feasible_at` runs the pipeline's checks there (footprint, IK by query, screen,
refinement, coal); :func:`feasible_near` adds IK seeded by the witnesses of the region's
nearest feasible cells where the database's voxels hold nothing usable.
"""

from __future__ import annotations

import hashlib

import numpy as np

from pickstop.regions import solve
from pickstop.regions.cells import TrayRegion
from pickstop.regions.envelope import Envelope
from pickstop.regions.footprint import footprint_free
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import arm_radius, tray_world
from pickstop.regions.solve import ArmWorld, Targets
from pickstop.regions.validity import own_key
from pickstop.scene.model import Scene, Tray
from pickstop.scene.world import Solid


def _arm_world(
    planner: RegionKit, scene: Scene, tray: Tray, yaw: float
) -> tuple[ArmWorld, np.ndarray]:
    """What the arm is checked against near ``tray`` at ``yaw`` [rad], and R_base_world."""
    _, solids, boxes, R_base_world = tray_world(planner, scene, tray, yaw)
    env = Envelope.empty(scene.floor.min, scene.floor.max)  # a check records nothing
    return ArmWorld(boxes, solids, yaw, env, scene.floor_clearance), R_base_world


def feasible_at(
    planner: RegionKit, scene: Scene, tray_id: str, xy: np.ndarray, yaw: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The region's test at arbitrary base poses ``xy: (M, 2)`` [m], ``yaw`` [rad].

    Returns ``ok: (M,)``, witnesses ``(M, P, dof)`` and grasp indices ``(M, P)``: the same
    exact pipeline as the grid (footprint, IK by query, screen, refinement, coal), at the
    given poses rather than at cell centres.
    """
    tray = scene.tray(tray_id)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    M, P = len(xy), len(tray.parts)
    thetas = np.zeros((M, P, planner.robot.dof))
    grasp = np.zeros((M, P), int)
    alive = np.flatnonzero(footprint_free(scene, planner.robot, xy, yaw, planner.solids_of(scene)))
    if not P:
        return np.zeros(M, bool), thetas, grasp
    world, R_base_world = _arm_world(planner, scene, tray, yaw)
    for k, gs in enumerate(planner.grasps(scene, tray)):
        if len(alive) == 0 or len(gs.Ts_world_tool) == 0:
            return np.zeros(M, bool), thetas, grasp
        found, th, gi = solve.solve_part(
            planner, world, Targets.of(gs, xy[alive], R_base_world), xy[alive]
        )
        alive = alive[found]
        thetas[alive, k] = th[found]
        grasp[alive, k] = gi[found]
    ok = np.zeros(M, bool)
    ok[alive] = True
    return ok, thetas, grasp


def check_key(
    planner: RegionKit,
    scene: Scene,
    region: TrayRegion,
    xy: tuple[float, float],
    yaw: float,
    solids: list[Solid] | None = None,
) -> str:
    """What :func:`feasible_near` of ``region`` at one base pose depends on, and nothing else:
    the region (its tray, grid, floor, gripper, robot and database: its own key; its cells
    and witnesses, the seeds), the objects near enough for the arm to meet
    (:func:`~pickstop.regions.pipeline.arm_radius`, by definition), the pose, and whether the
    base's footprint fits there now (it looks at the objects near the pose). A tray moved
    elsewhere leaves the checks of the other trays as they were. ``solids``: the scene's
    (:func:`~pickstop.scene.world.scene_solids`), if made already."""
    tray = scene.tray(region.tray_id)
    solids = planner.solids_of(scene) if solids is None else solids
    free = bool(footprint_free(scene, planner.robot, np.array([xy], float), yaw, solids)[0])
    near = planner.objects_near(scene, tray, arm_radius(planner, tray))
    own = own_key(planner, scene, tray, region.yaw)
    blob = "\0".join([own, region.digest, repr((xy, yaw, free)), *near])
    return hashlib.sha256(blob.encode()).hexdigest()


NEIGHBOUR_SEEDS = 6  # witnesses of the nearest feasible cells tried as IK seeds
SEED_ITERATIONS = 20


def feasible_near(
    planner: RegionKit, scene: Scene, region: TrayRegion, xy: np.ndarray, yaw: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`feasible_at`, then, where that fails, IK seeded by the witnesses of the region's
    nearest feasible cells (exact solutions a few centimetres away; their own grasps, then
    every other grasp), verified the same way.

    Off the grid (a stop's inscribed centre, a Monte Carlo sample) the database's voxels may
    hold no candidate for a pose whose neighbours were solved; the seeds close that gap.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    ok, thetas, grasp = feasible_at(planner, scene, region.tray_id, xy, yaw)
    todo = np.flatnonzero(~ok)
    if not len(todo) or not len(region.cells) or abs(region.yaw - yaw) > 0.2:
        return ok, thetas, grasp
    free = footprint_free(scene, planner.robot, xy[todo], yaw, planner.solids_of(scene))
    todo = todo[free]
    if not len(todo):
        return ok, thetas, grasp
    tray = scene.tray(region.tray_id)
    world, R_base_world = _arm_world(planner, scene, tray, yaw)
    cells_xy = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    S = min(NEIGHBOUR_SEEDS, len(cells_xy))
    d2 = ((xy[todo, None, :] - cells_xy[None]) ** 2).sum(-1)
    near = np.argsort(d2, axis=1)[:, :S]  # (T, S) nearest feasible cells
    alive = np.ones(len(todo), bool)
    th_new = np.zeros((len(todo), len(tray.parts), planner.robot.dof))
    g_new = np.zeros((len(todo), len(tray.parts)), int)
    dof = planner.robot.dof
    for k, gs in enumerate(planner.grasps(scene, tray)):
        G = len(gs.Ts_world_tool)
        hit = np.zeros(len(todo), bool)
        # The neighbours' own grasps first, then (from the two nearest) every other grasp,
        # as the region's growth does.
        for n_seeds, shifts in ((S, np.zeros(1, int)), (min(2, S), np.arange(1, G))):
            rest = np.flatnonzero(alive & ~hit)
            if not len(rest) or not len(shifts):
                continue
            src = near[rest, :n_seeds].reshape(-1)  # seeding cells
            owner = np.repeat(np.repeat(rest, n_seeds), len(shifts))
            g = ((region.grasp_index[src, k][:, None] + shifts) % G).ravel()
            tg = Targets.of(gs, xy[todo[owner]], R_base_world)
            win, th = solve.seeded(
                planner,
                world,
                np.repeat(region.thetas[src, k].reshape(-1, dof), len(shifts), axis=0),
                tg.Rs_base_tool[g],
                tg.ps_base_tool[np.arange(len(g)), g],
                xy[todo[owner]],
                owner,
                len(todo),
                SEED_ITERATIONS,
                solve.GROW_GIVE_UP,
                gs.part_id,
            )
            got = win >= 0
            th_new[got, k] = th[win[got]]
            g_new[got, k] = g[win[got]]
            hit |= got
        alive &= hit
    win = todo[alive]
    ok[win] = True
    thetas[win] = th_new[alive]
    grasp[win] = g_new[alive]
    return ok, thetas, grasp
