"""Off-grid checks: the region's exact test at arbitrary base poses.

A stop's inscribed centre or a Monte Carlo sample of the base pose seldom falls on a cell
centre. :func:`feasible_at` runs the pipeline's checks there (footprint, IK by query, screen,
refinement, coal); :func:`feasible_near` adds IK seeded by the witnesses of the region's
nearest feasible cells where the database's voxels hold nothing usable (or tries it first,
where that is cheaper).
"""

from __future__ import annotations

import hashlib

import numpy as np

from pickstop.regions import solve
from pickstop.regions.arm import ArmWorld
from pickstop.regions.cells import TrayRegion
from pickstop.regions.envelope import Envelope
from pickstop.regions.footprint import footprint_free
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import arm_radius, own_key, tray_world
from pickstop.regions.solve import Targets
from pickstop.scene.model import Scene, Tray
from pickstop.scene.world import Solid


def _arm_world(kit: RegionKit, scene: Scene, tray: Tray, yaw: float) -> tuple[ArmWorld, np.ndarray]:
    """What the arm is checked against near ``tray`` at ``yaw`` [rad], and R_base_world."""
    _, solids, boxes, R_base_world = tray_world(kit, scene, tray, yaw)
    env = Envelope.empty(scene.floor.min, scene.floor.max)  # a check records nothing
    return ArmWorld(boxes, solids, yaw, env, scene.floor_clearance), R_base_world


def feasible_at(
    kit: RegionKit, scene: Scene, tray_id: str, xy: np.ndarray, yaw: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The region's test at arbitrary base poses ``xy: (M, 2)`` [m], ``yaw`` [rad].

    Returns ``ok: (M,)``, witnesses ``(M, P, dof)`` and grasp indices ``(M, P)``: the same
    exact pipeline as the grid (footprint, IK by query, screen, refinement, coal), at the
    given poses rather than at cell centres.
    """
    tray = scene.tray(tray_id)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    M, P = len(xy), len(tray.parts)
    thetas = np.zeros((M, P, kit.robot.dof))
    grasp = np.zeros((M, P), int)
    alive = np.flatnonzero(footprint_free(scene, kit.robot, xy, yaw, kit.solids_of(scene)))
    if not P:
        return np.zeros(M, bool), thetas, grasp
    world, R_base_world = _arm_world(kit, scene, tray, yaw)
    for k, gs in enumerate(kit.grasps(scene, tray)):
        if len(alive) == 0 or len(gs.Ts_world_tool) == 0:
            return np.zeros(M, bool), thetas, grasp
        found, th, gi = solve.solve_part(
            kit, world, Targets.of(gs, xy[alive], R_base_world), xy[alive]
        )
        alive = alive[found]
        thetas[alive, k] = th[found]
        grasp[alive, k] = gi[found]
    ok = np.zeros(M, bool)
    ok[alive] = True
    return ok, thetas, grasp


def check_key(
    kit: RegionKit,
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
    solids = kit.solids_of(scene) if solids is None else solids
    free = bool(footprint_free(scene, kit.robot, np.array([xy], float), yaw, solids)[0])
    near = kit.objects_near(scene, tray, arm_radius(kit, tray))
    own = own_key(kit, scene, tray, region.yaw)
    blob = "\0".join([own, region.digest, repr((xy, yaw, free)), *near])
    return hashlib.sha256(blob.encode()).hexdigest()


NEIGHBOUR_SEEDS = 6  # witnesses of the nearest feasible cells tried as IK seeds
SEED_ITERATIONS = 20


def feasible_near(
    kit: RegionKit,
    scene: Scene,
    region: TrayRegion,
    xy: np.ndarray,
    yaw: float,
    seeds_first: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The region's test at arbitrary base poses, as :func:`feasible_at` and more: a pose
    passes if :func:`feasible_at` verifies there (the database queried at the pose itself),
    or else if IK seeded by the witnesses of the region's nearest feasible cells (exact
    solutions a few centimetres away; their own grasps, then every other grasp) does.

    Off the grid (a stop's inscribed centre, a Monte Carlo sample) the database's voxels may
    hold no candidate for a pose whose neighbours were solved; the seeds close that gap.
    ``seeds_first``: the seeds are tried first and the database only where they fail, the
    same poses passing (a pose's outcome by either way depends on it alone): cheaper for a
    few poses near the cells (a stop's centre), dearer for many (a query serves a batch at
    once). Every witness returned is verified at its pose.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    tray = scene.tray(region.tray_id)
    M, P, dof = len(xy), len(tray.parts), kit.robot.dof
    ok = np.zeros(M, bool)
    thetas = np.zeros((M, P, dof))
    grasp = np.zeros((M, P), int)

    def take(idx: np.ndarray, got: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        win = idx[got[0]]
        ok[win], thetas[win], grasp[win] = True, got[1][got[0]], got[2][got[0]]

    def by_database() -> None:
        idx = np.flatnonzero(~ok)
        if len(idx):
            take(idx, feasible_at(kit, scene, region.tray_id, xy[idx], yaw))

    def by_seeds() -> None:
        if not P or not len(region.cells) or abs(region.yaw - yaw) > 0.2:
            return
        idx = np.flatnonzero(~ok)
        idx = idx[footprint_free(scene, kit.robot, xy[idx], yaw, kit.solids_of(scene))]
        if len(idx):
            take(idx, _seeded_by_cells(kit, scene, region, xy[idx], yaw))

    for step in (by_seeds, by_database) if seeds_first else (by_database, by_seeds):
        step()
    return ok, thetas, grasp


def _seeded_by_cells(
    kit: RegionKit, scene: Scene, region: TrayRegion, xy: np.ndarray, yaw: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`feasible_near`'s seeded IK at base poses ``xy: (T, 2)`` whose footprint is
    free: ``ok (T,)``, witnesses ``(T, P, dof)``, grasps ``(T, P)``."""
    tray = scene.tray(region.tray_id)
    world, R_base_world = _arm_world(kit, scene, tray, yaw)
    cells_xy = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    S = min(NEIGHBOUR_SEEDS, len(cells_xy))
    d2 = ((xy[:, None, :] - cells_xy[None]) ** 2).sum(-1)
    near = np.argsort(d2, axis=1)[:, :S]  # (T, S) nearest feasible cells
    T, dof = len(xy), kit.robot.dof
    alive = np.ones(T, bool)
    th_new = np.zeros((T, len(tray.parts), dof))
    g_new = np.zeros((T, len(tray.parts)), int)
    for k, gs in enumerate(kit.grasps(scene, tray)):
        G = len(gs.Ts_world_tool)
        hit = np.zeros(T, bool)
        # The neighbours' own grasps first, then (from the two nearest) every other grasp,
        # as the region's growth does.
        for n_seeds, shifts in ((S, np.zeros(1, int)), (min(2, S), np.arange(1, G))):
            rest = np.flatnonzero(alive & ~hit)
            if not len(rest) or not len(shifts) or not G:
                continue
            src = near[rest, :n_seeds].reshape(-1)  # seeding cells
            owner = np.repeat(np.repeat(rest, n_seeds), len(shifts))
            g = ((region.grasp_index[src, k][:, None] + shifts) % G).ravel()
            tg = Targets.of(gs, xy[owner], R_base_world)
            win, th = solve.seeded(
                kit,
                world,
                np.repeat(region.thetas[src, k].reshape(-1, dof), len(shifts), axis=0),
                tg.Rs_base_tool[g],
                tg.ps_base_tool[np.arange(len(g)), g],
                xy[owner],
                owner,
                T,
                SEED_ITERATIONS,
                solve.GROW_GIVE_UP,
                gs.part_id,
            )
            got = win >= 0
            th_new[got, k] = th[win[got]]
            g_new[got, k] = g[win[got]]
            hit |= got
        alive &= hit
    return alive, th_new, g_new
