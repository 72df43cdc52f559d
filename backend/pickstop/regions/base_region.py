"""Base region of a tray: every base cell from which each of its parts can be grasped.

Cells the database can serve are solved part by part (:mod:`pickstop.regions.solve`); the
solved cells then grow into open neighbours from their witnesses. A cell is feasible only with
a verified witness configuration for every part. Regions are cached per tray and yaw, and
reused while nothing they looked at has moved (:mod:`pickstop.regions.envelope`).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from pickstop import frames
from pickstop.reach.batch_ik import BatchSolver
from pickstop.reach.database import ReachDatabase
from pickstop.regions import solve
from pickstop.regions.arm import SPHERE_EXCESS, ArmSpheres, ExactArm, nearby, screen_arm
from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.regions.envelope import Envelope
from pickstop.regions.footprint import blocked_by, footprint_check, footprint_free
from pickstop.regions.reuse import ReuseCache, TrayAnchor, grasps_digest
from pickstop.regions.solve import ArmWorld, Targets
from pickstop.robot.hand import HandShape, hand_shape
from pickstop.robot.kinematics import fk_soa
from pickstop.robot.model import RobotModel
from pickstop.scene.grasps import GraspSet, grasps_for_part, hand_space
from pickstop.scene.model import Part, Scene, Tray
from pickstop.scene.world import BoxArrays, Solid, scene_solids, tray_body_solids

Bounds = list[tuple[np.ndarray, np.ndarray]]  # axis-aligned (lo, hi) boxes [m]


@dataclass
class RegionPlanner:
    """Heavy things for region computation, built once per robot and database."""

    robot: RobotModel
    db: ReachDatabase
    solver: BatchSolver = field(init=False)
    arm: ArmSpheres = field(init=False)
    self_spheres: Any = field(init=False)
    exact_self: Any = field(init=False)
    exact_arm: ExactArm = field(init=False)
    hand: HandShape = field(init=False)
    reach_xy: float = field(init=False)
    cache: dict[str, list[_CacheEntry]] = field(default_factory=dict)
    grasp_cache: dict[str, GraspSet] = field(default_factory=dict)
    reuse: ReuseCache = field(default_factory=ReuseCache)  # refinements across tray positions
    _layouts: dict[str, dict[tuple[str, float], TrayRegion]] = field(
        default_factory=dict, repr=False
    )  # the regions of the last layouts
    _last: dict[tuple[str, float, str], tuple[Tray, TrayRegion]] = field(
        default_factory=dict, repr=False
    )  # per tray id, yaw and what the tray is (pose aside): the tray as it stood, its region
    _memo: dict[str, Any] = field(default_factory=dict, repr=False)  # hand spaces, bounds
    cache_size: int = 256
    cache_dir: Path | None = None  # per-robot derived data (disabled pairs, screen)
    workers: int = 1  # processes for several regions at once (forked: they share the database)
    _workers_pool: Any = field(default=None, repr=False)

    def __post_init__(self) -> None:
        from pickstop.robot.artifacts import derived, self_collision
        from pickstop.robot.selfcollision import ExactSelfCollision

        self.solver = BatchSolver.of(self.robot)
        self.hand = hand_shape(self.robot)
        # Covering the arm links takes about a second: made once per robot, kept on disk.
        self.arm = derived(
            self.robot,
            self.cache_dir,
            f"arm-spheres-{SPHERE_EXCESS}",
            lambda: ArmSpheres.of(self.robot),
        )
        disabled, self.self_spheres = self_collision(self.robot, self.cache_dir)
        self.exact_self = ExactSelfCollision(self.robot, disabled)
        self.exact_arm = ExactArm(self.robot)
        self.reach_xy = self.db.reach_xy

    # -- caching ---------------------------------------------------------------------------
    def own_key(self, scene: Scene, tray: Tray, yaw: float) -> str:
        """What the region of ``tray`` depends on apart from the other objects."""
        blob = {
            "tray": tray.model_dump(),
            "yaw": yaw,
            "grid": [scene.grid_extent.model_dump(), scene.base_grid.resolution],
            "floor": scene.floor.model_dump(),
            "floor_clearance": scene.floor_clearance,
            "gripper": scene.gripper.model_dump(),
            "hand": self.hand.key,
            "robot": self.robot.robot_hash,
            "db": self.db.id,
            "algo": solve.VERSION,
        }
        return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()

    def tray_region(self, scene: Scene, tray_id: str, yaw: float | None = None) -> TrayRegion:
        """The region of one tray, reused from the cache while nothing it looked at changed."""
        tray = scene.tray(tray_id)
        yaw = scene.base_yaw.yaws[0] if yaw is None else yaw
        hit = self._cached(scene, tray_id, yaw)
        if hit is not None:
            self._remember(scene, hit)
            return hit
        region = compute_tray_region(self, scene, tray, yaw, self.own_key(scene, tray, yaw))
        self._store(scene, region)
        return region

    def regions(
        self, scene: Scene, workers: int | None = None
    ) -> dict[tuple[str, float], TrayRegion]:
        """Regions of every tray the task needs, at every yaw of the policy.

        workers: processes for the regions not in the cache (default: the planner's
        ``workers``); they are forked from this process, so they share its database.
        """
        pairs = [(t, y) for t in scene.task_trays for y in scene.base_yaw.yaws]
        # The regions are a function of the layout: the same layout (a change of sigma, rule
        # or objective) takes them as they were, without checking each cached region anew.
        layout = scene.model_dump_json(
            exclude={"name", "description", "sigma", "error_model", "motion", "start", "goal"}
        )
        hit = self._layouts.get(layout)
        if hit is not None:
            for region in hit.values():
                self._remember(scene, region)
            return dict(hit)
        workers = self.workers if workers is None else workers
        todo = [(t, y) for t, y in pairs if self._cached(scene, t, y) is None]
        if workers > 1 and len(todo) > 1:
            pool = self._pool(workers)
            for region in pool.starmap(_pool_region, [(scene, t, y) for t, y in todo]):
                self._store(scene, region)
        out = {(t, y): self.tray_region(scene, t, y) for t, y in pairs}
        self._layouts[layout] = out
        while len(self._layouts) > 8:
            self._layouts.pop(next(iter(self._layouts)))
        return dict(out)

    def _cached(self, scene: Scene, tray_id: str, yaw: float) -> TrayRegion | None:
        tray = scene.tray(tray_id)
        snap = _snapshot(scene, tray.id)
        for entry in self.cache.get(self.own_key(scene, tray, yaw), []):
            if self._still_valid(entry, snap):
                return entry.region
        return None

    def _still_valid(self, entry: _CacheEntry, snap: Snapshot) -> bool:
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
            if blocked_by(self.robot, new[1], env.free_xy, entry.region.yaw).any():
                return False  # where it is, it overhangs a free cell
            if not witnesses_clear(self, entry.region, new[1]):
                return False  # where it is, it collides with a witness arm
            entry.cleared.add(new[0])
        return True

    def known_regions(
        self, scene: Scene, pairs: list[tuple[str, float]]
    ) -> dict[tuple[str, float], TrayRegion]:
        """For each ``(tray id, yaw)`` planned before: the last region computed for the tray
        wherever it stood, carried rigidly to where it stands now and clipped to the cells
        where the base footprint fits (for a preview: nothing is checked but the footprint)."""
        from pickstop.regions.carry import carried_regions

        known = []
        for p in pairs:
            hit = self._last.get((*p, _carry_key(scene, p[0])))
            if hit is not None:
                known.append((p, hit))
        carried = carried_regions(self.robot, scene, [k for _, k in known])
        return {p: r for (p, _), r in zip(known, carried, strict=True)}

    def _remember(self, scene: Scene, region: TrayRegion) -> None:
        """Keep ``region`` as its tray's last (what a preview carries), the newest last."""
        key = (region.tray_id, region.yaw, _carry_key(scene, region.tray_id))
        self._last.pop(key, None)
        self._last[key] = (scene.tray(region.tray_id), region)
        if len(self._last) > 4 * self.cache_size:
            self._last.pop(next(iter(self._last)))

    def _store(self, scene: Scene, region: TrayRegion) -> None:
        self._remember(scene, region)
        entries = self.cache.setdefault(region.key, [])
        entries.insert(0, _CacheEntry(region, _snapshot(scene, region.tray_id)))
        del entries[4:]  # a few layouts per tray and yaw
        if len(self.cache) > self.cache_size:
            self.cache.pop(next(iter(self.cache)))

    def _pool(self, workers: int) -> Any:
        if self._workers_pool is None or self._workers_pool[0] != workers:
            import multiprocessing

            global _POOL_PLANNER
            _POOL_PLANNER = self
            ctx = multiprocessing.get_context("fork")
            self._workers_pool = (workers, ctx.Pool(workers))
        return self._workers_pool[1]

    def close(self) -> None:
        """Stop the worker processes, if any."""
        if self._workers_pool is not None:
            self._workers_pool[1].terminate()
            self._workers_pool = None

    def grasps(self, scene: Scene, tray: Tray) -> list[GraspSet]:
        """The grasps of every part of ``tray``, reused while nothing that reaches into the
        space of its open hands changes (other trays elsewhere may move freely)."""
        others = self._bounds_of(scene, tray.id)
        tray_json = tray.model_dump_json()
        gripper_json = f"{scene.gripper.model_dump_json()}{self.hand.key}|{scene.floor_clearance}"
        out = []
        for part in tray.parts:
            key = f"{tray_json}|{part.id}|{gripper_json}"
            space = self.hand_space(scene, tray, part)
            near = [d for d, bounds in others if any(_overlap(b, space) for b in bounds)]
            full = hashlib.sha256("|".join([key, *sorted(near)]).encode()).hexdigest()
            if full not in self.grasp_cache:
                self.grasp_cache[full] = grasps_for_part(scene, tray, part, self.hand)
            out.append(self.grasp_cache[full])
        return out

    def hand_space(self, scene: Scene, tray: Tray, part: Part) -> tuple[np.ndarray, np.ndarray]:
        """:func:`pickstop.scene.grasps.hand_space`, computed once per tray, part and hand."""
        key = f"hand|{tray.model_dump_json()}|{part.id}|{scene.gripper.model_dump_json()}"
        if key not in self._memo:
            self._memo[key] = hand_space(scene, tray, part, self.hand)
        return self._memo[key]

    def _bounds_of(self, scene: Scene, exclude: str) -> list[tuple[str, Bounds]]:
        """Every object but the tray ``exclude``: its definition and its solids' bounds."""
        from pickstop.scene.world import part_solid, pose_matrix, shape_solid

        if len(self._memo) > 4096:
            self._memo.clear()
        out = []
        for o in scene.obstacles:
            d = o.model_dump_json()
            if d not in self._memo:
                self._memo[d] = [shape_solid(o.geometry, pose_matrix(o.pose), o.id).aabb()]
            out.append((d, self._memo[d]))
        for t in scene.trays:
            if t.id != exclude:
                d = t.model_dump_json()
                if d not in self._memo:
                    solids = tray_body_solids(t) + [part_solid(t, p) for p in t.parts]
                    self._memo[d] = [s.aabb() for s in solids]
                out.append((d, self._memo[d]))
        return out


def _overlap(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    return bool(np.all(a[0] <= b[1]) and np.all(b[0] <= a[1]))


#: Every other object of a scene: its definition, its solids and their owner names.
Snapshot = dict[str, tuple[str, list[Solid], frozenset[str]]]


@dataclass(frozen=True)
class _CacheEntry:
    region: TrayRegion
    snapshot: Snapshot
    cleared: set[str] = field(default_factory=set)  # new definitions no witness collides with


_POOL_PLANNER: RegionPlanner | None = None  # the planner the forked workers inherited


def _pool_region(scene: Scene, tray_id: str, yaw: float) -> TrayRegion:
    assert _POOL_PLANNER is not None
    planner = _POOL_PLANNER
    tray = scene.tray(tray_id)
    return compute_tray_region(planner, scene, tray, yaw, planner.own_key(scene, tray, yaw))


def _snapshot(scene: Scene, exclude: str) -> Snapshot:
    """Every object but the tray ``exclude``: definition, solids, owner names."""
    from pickstop.scene.world import part_solid, pose_matrix, shape_solid

    out = {}
    for o in scene.obstacles:
        solid = shape_solid(o.geometry, pose_matrix(o.pose), o.id)
        out[f"obstacle:{o.id}"] = (o.model_dump_json(), [solid], frozenset([o.id]))
    for t in scene.trays:
        if t.id != exclude:
            solids = tray_body_solids(t) + [part_solid(t, p) for p in t.parts]
            owners = frozenset([t.id, *(p.id for p in t.parts)])
            out[f"tray:{t.id}"] = (t.model_dump_json(), solids, owners)
    return out


def witnesses_clear(planner: RegionPlanner, region: TrayRegion, solids: list[Solid]) -> bool:
    """Is every witness arm of ``region`` free of ``solids``? The sphere screen first, coal
    for what it flags (the hands and footprints are covered by the region's envelope)."""
    if not len(region.cells) or not solids:
        return True
    K, P, dof = region.thetas.shape
    xy = np.repeat(region.grid.centres(region.cells[:, 1], region.cells[:, 0]), P, axis=0)
    lo = np.min([s.aabb()[0] for s in solids], axis=0)
    hi = np.max([s.aabb()[1] for s in solids], axis=0)
    reach = planner.reach_xy + float(planner.arm.bound_r.max())
    near = np.flatnonzero(
        (xy[:, 0] > lo[0] - reach)
        & (xy[:, 0] < hi[0] + reach)
        & (xy[:, 1] > lo[1] - reach)
        & (xy[:, 1] < hi[1] + reach)
    )
    if not len(near):
        return True
    th = region.thetas.reshape(K * P, dof)[near]
    _, _, frames = fk_soa(planner.solver.chain, np.ascontiguousarray(th.T), frames=True)
    flagged = np.flatnonzero(
        screen_arm(planner.arm, BoxArrays.of(solids), frames, xy[near], region.yaw)
    )
    x, y = xy[near, 0], xy[near, 1]
    return not any(
        planner.exact_arm.colliding(th[j], x[j], y[j], region.yaw, solids) for j in flagged
    )


def compute_tray_region(
    planner: RegionPlanner, scene: Scene, tray: Tray, yaw: float, key: str = ""
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
    planner: RegionPlanner,
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
    planner: RegionPlanner, scene: Scene, tray: Tray, yaw: float
) -> tuple[float, list[Solid], BoxArrays, np.ndarray]:
    """Reach radius around the tray [m], the solids near it (exact and as arrays), R_base_world."""
    tc = np.array([tray.pose.x, tray.pose.y])
    reach = planner.reach_xy + 0.5 * math.hypot(*tray.outer_size)
    solids = nearby(scene_solids(scene), tc, reach + planner.reach_xy + 0.2)
    return reach, solids, BoxArrays.of(solids), frames.R_base_world(yaw)


def feasible_at(
    planner: RegionPlanner, scene: Scene, tray_id: str, xy: np.ndarray, yaw: float
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
    alive = np.flatnonzero(footprint_free(scene, planner.robot, xy, yaw))
    if not P:
        return np.zeros(M, bool), thetas, grasp
    _, solids, boxes, R_base_world = tray_world(planner, scene, tray, yaw)
    world = ArmWorld(
        boxes, solids, yaw, Envelope.empty(scene.floor.min, scene.floor.max), scene.floor_clearance
    )
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


NEIGHBOUR_SEEDS = 6  # witnesses of the nearest feasible cells tried as IK seeds
SEED_ITERATIONS = 20


def feasible_near(
    planner: RegionPlanner, scene: Scene, region: TrayRegion, xy: np.ndarray, yaw: float
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
    free = footprint_free(scene, planner.robot, xy[todo], yaw)
    todo = todo[free]
    if not len(todo):
        return ok, thetas, grasp
    tray = scene.tray(region.tray_id)
    _, solids, boxes, R_base_world = tray_world(planner, scene, tray, yaw)
    world = ArmWorld(
        boxes, solids, yaw, Envelope.empty(scene.floor.min, scene.floor.max), scene.floor_clearance
    )
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


def _carry_key(scene: Scene, tray_id: str) -> str:
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
