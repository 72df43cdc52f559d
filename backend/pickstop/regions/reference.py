"""Reference computations of a tray's base region, without the reachability database.

``baseline_region`` is the paper's comparison with a conventional IK solver: one numerical
solution per (cell, part, grasp) from a fixed seed, then an exact collision check of that
solution. ``oracle_region`` is dense multi-start IK: many uniform random seeds per (cell, part,
grasp), escalated only where nothing valid was found yet, every converged solution checked.

Both see what production sees, through production's own steps: the cells of
:func:`~pickstop.regions.pipeline.base_cells` (within reach, footprint-free), the grasps and
their :class:`~pickstop.regions.solve.Targets`, and :func:`~pickstop.regions.solve.verify`
(arm links against the scene solids and the floor, enabled link pairs against each other: the
sphere screens decide nothing but "surely free", whatever they flag goes to coal). Only the
IK differs: seeded solves instead of the database. Witnesses are judged on the numpy FK
(1 mm, 0.5 deg) and the joint limits.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pickstop.frames import R_base_world
from pickstop.reach.batch_ik import BatchSolver, refine_batch
from pickstop.reach.ik import POS_TOL, ROT_TOL
from pickstop.regions import solve
from pickstop.regions.arm import ArmWorld
from pickstop.regions.cells import CellGrid, TrayRegion
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import (
    BaseCells,
    base_cells,
    no_cell_grasps,
    no_parts,
    tray_world,
    ungraspable,
)
from pickstop.regions.solve import Targets
from pickstop.robot.kinematics import fk, fk_soa
from pickstop.scene.grasps import GraspSet
from pickstop.scene.model import Scene, Tray
from pickstop.scene.world import scene_solids

CHUNK = 16_384  # IK problems per refine_batch call: keeps the working set small
BASELINE_ITERATIONS = 100
ORACLE_SEEDS = (4, 16, 64, 256)  # cumulative random seeds per (cell, part, grasp), by round


@dataclass(frozen=True)
class ReachBound:
    """Where the last joint's origin can be: within ``radius`` of the segment ``a``-``b``.

    The target pose fixes the last joint's frame (the tool sits at a fixed offset in it). The
    first revolute joint's origin moves only with the prismatic joints before it, along
    ``a``-``b`` (or within ``radius`` of its midpoint when several precede it), and the last
    joint's origin stays within the summed link offsets of it. A target whose last joint origin
    lies farther has no IK solution, from any seed.
    """

    a: np.ndarray  # (3,) [m] base frame
    b: np.ndarray  # (3,) [m]
    radius: float  # [m]
    R_joint_tool: np.ndarray  # (3, 3)
    p_joint_tool: np.ndarray  # (3,) [m]

    @classmethod
    def of(cls, solver: BatchSolver) -> ReachBound:
        ch = solver.chain
        revolute = np.flatnonzero(~ch.prismatic)
        if len(revolute) == 0:
            return cls(np.zeros(3), np.zeros(3), math.inf, ch.R_joint_tool, ch.p_joint_tool)
        k = int(revolute[0])
        th = np.zeros((2, ch.dof))
        th[0, :k], th[1, :k] = solver.lower[:k], solver.upper[:k]
        _, _, frames = fk_soa(ch, np.ascontiguousarray(th.T), frames=True)
        a, b = frames[k][1][:, 0], frames[k][1][:, 1]
        r = float(np.linalg.norm(ch.p_parent_joint[k + 1 :], axis=1).sum())
        stroke = np.maximum(np.abs(solver.lower), np.abs(solver.upper))
        r += float(stroke[ch.prismatic & (np.arange(ch.dof) > k)].sum())
        if k > 1:  # a box of prismatic strokes: a ball about its centre
            r += float(0.5 * (solver.upper[:k] - solver.lower[:k]).sum())
            a = b = 0.5 * (a + b)
        # A converged solution may miss its target by the IK tolerances.
        r += POS_TOL + ROT_TOL * float(np.linalg.norm(ch.p_joint_tool)) + 1e-6
        return cls(a, b, r, ch.R_joint_tool, ch.p_joint_tool)

    def contains(self, Rs: np.ndarray, ps: np.ndarray) -> np.ndarray:
        """``(N,)`` False where no configuration reaches ``T_base_tool``: ``Rs: (N, 3, 3)``,
        ``ps: (N, 3)`` [m]."""
        wrist = ps - np.einsum("nij,kj,k->ni", Rs, self.R_joint_tool, self.p_joint_tool)
        d = self.b - self.a
        t = np.clip((wrist - self.a) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
        gap = np.linalg.norm(wrist - (self.a + t[:, None] * d), axis=1)
        return gap <= self.radius


@dataclass
class _Setup:
    """One tray's problem: candidate cells, grasps, the world the arm is checked against."""

    kit: RegionKit
    tray: Tray
    yaw: float
    cand: BaseCells
    grasps: list[GraspSet]
    world: ArmWorld  # no envelope: a reference records nothing for a cache
    R_base_world: np.ndarray  # (3, 3)
    bound: ReachBound
    stats: dict[str, int]

    def targets(self, k: int, cells: np.ndarray) -> Targets:
        """Part ``k``'s grasp targets from candidate ``cells: (M,)``."""
        return Targets.of(self.grasps[k], self.cand.centres[cells], self.R_base_world)


def _setup(
    kit: RegionKit,
    scene: Scene,
    tray: Tray,
    yaw: float,
    cand: BaseCells,
    grasps: list[GraspSet],
) -> _Setup:
    _, solids, boxes, R_base_world = tray_world(kit, scene, tray, yaw)
    return _Setup(
        kit,
        tray,
        yaw,
        cand,
        grasps,
        ArmWorld(boxes, solids, yaw, None, scene.floor_clearance),
        R_base_world,
        ReachBound.of(kit.solver),
        {"ik_problems": 0, "ik_converged": 0, "exact_checks": 0},
    )


# -- the shared solve loop ---------------------------------------------------------------------
SeedFn = Callable[[int, int, np.ndarray, np.ndarray, int], np.ndarray]


def _solve_part(
    st: _Setup,
    k: int,
    cells: np.ndarray,
    rounds: Sequence[int],
    seeds: SeedFn,
    max_iter: int,
    prune: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Part ``k`` from candidate ``cells: (M,)``: found (M,), witnesses (M, dof), grasps (M,).

    Round r gives each unresolved (cell, grasp) ``rounds[r]`` new seeds from
    ``seeds(r, k, cells (Q, 2) (iy, ix), grasps (Q,), n) -> (Q, n, dof)``; every converged
    solution counts. ``prune``: skip targets outside the :class:`ReachBound`.
    """
    solver = st.kit.solver
    M, dof = len(cells), solver.chain.dof
    tg = st.targets(k, cells)
    R_t, p_t = tg.Rs_base_tool, tg.ps_base_tool
    G = len(R_t)
    reachable = st.bound.contains(
        np.broadcast_to(R_t, (M, G, 3, 3)).reshape(-1, 3, 3), p_t.reshape(-1, 3)
    )
    reachable = reachable.reshape(M, G) | (not prune)
    found = np.zeros(M, bool)
    th_out = np.zeros((M, dof))
    g_out = np.zeros(M, int)
    for r, n in enumerate(rounds):
        qa, qg = np.nonzero(reachable & ~found[:, None])
        if len(qa) == 0 or n == 0:
            break
        th0 = seeds(r, k, st.cand.cells[cells[qa]], qg, n).reshape(-1, dof)
        pa, pg = np.repeat(qa, n), np.repeat(qg, n)
        st.stats["ik_problems"] += len(pa)
        conv = np.zeros(len(pa), bool)
        th = np.empty_like(th0)
        for s in range(0, len(pa), CHUNK):
            sl = slice(s, s + CHUNK)
            res = refine_batch(solver, th0[sl], R_t[pg[sl]], p_t[pa[sl], pg[sl]], max_iter=max_iter)
            conv[sl], th[sl] = res.success, res.thetas
        ok = np.flatnonzero(conv)
        ok = ok[pose_ok(solver, th[ok], R_t[pg[ok]], p_t[pa[ok], pg[ok]])]
        st.stats["ik_converged"] += len(ok)
        # Problems are ordered (cell, grasp, seed): the first verified solution of a cell
        # wins, a screen-free one before any coal has to clear.
        rows = ok[
            solve.verify(
                st.kit,
                st.world,
                th[ok],
                st.cand.centres[cells[pa[ok]]],
                pa[ok],
                st.grasps[k].part_id,
                st.stats,
            )
        ]
        _, first = np.unique(pa[rows], return_index=True)
        hit = rows[first]
        found[pa[hit]], th_out[pa[hit]], g_out[pa[hit]] = True, th[hit], pg[hit]
    return found, th_out, g_out


def pose_ok(solver: BatchSolver, thetas: np.ndarray, Rs: np.ndarray, ps: np.ndarray) -> np.ndarray:
    """``(N,)``: numpy FK of ``thetas: (N, dof)`` within 1 mm and 0.5 deg of the targets and
    every joint within its limits."""
    if len(thetas) == 0:
        return np.zeros(0, bool)
    R, p = fk(solver.chain, thetas)
    cos = (np.einsum("nij,nij->n", R, Rs) - 1.0) / 2.0
    ang = np.arccos(np.clip(cos, -1.0, 1.0))
    inside = np.all((thetas >= solver.lower - 1e-9) & (thetas <= solver.upper + 1e-9), axis=1)
    return (np.linalg.norm(p - ps, axis=1) <= POS_TOL) & (ang <= ROT_TOL) & inside


def _region(
    kit: RegionKit,
    scene: Scene,
    tray_id: str,
    yaw: float | None,
    rounds: Sequence[int],
    seeds: SeedFn,
    max_iter: int,
    cells: np.ndarray | None,
    t0: float,
    prune: bool = True,
) -> TrayRegion:
    """The region of ``tray_id`` at ``yaw`` [rad] (None: the scene's first) by seeded IK
    (:func:`_solve_part`) on the candidates among ``cells: (N, 2)`` (None: all)."""
    tray = scene.tray(tray_id)
    yaw = scene.base_yaw.yaws[0] if yaw is None else yaw
    grid = CellGrid.of(scene)
    cand = base_cells(kit, scene, tray, yaw, grid)
    counts = {"grid": grid.nx * grid.ny, **cand.counts}
    part_ids = tuple(p.id for p in tray.parts)
    dof = kit.robot.dof

    def result(idx: np.ndarray, th: np.ndarray, gi: np.ndarray, reason: str | None) -> TrayRegion:
        counts["feasible"] = len(idx)
        seconds = time.perf_counter() - t0
        sel = cand.cells[idx]
        return TrayRegion.of_cells(
            tray.id, yaw, grid, sel, part_ids, th, gi, counts, reason, seconds
        )

    def empty(reason: str) -> TrayRegion:
        counts["feasible"] = 0
        seconds = time.perf_counter() - t0
        return TrayRegion.empty(tray.id, yaw, grid, part_ids, dof, counts, reason, seconds)

    if not tray.parts:
        return empty(no_parts(tray))
    if cand.reason is not None:
        return empty(cand.reason)
    idx = _requested(cand, grid, cells, counts)
    counts["evaluated"] = len(idx)
    if len(idx) == 0:
        return empty(f"none of the requested cells is a free cell within reach of {tray.id!r}")
    grasps = kit.grasps(scene, tray)
    why = ungraspable(kit, scene, tray, grasps)
    if why is not None:
        return empty(why)
    st = _setup(kit, scene, tray, yaw, cand, grasps)
    alive, witness, grasp_of, failed = _solve_parts(st, idx, rounds, seeds, max_iter, prune, counts)
    counts.update(st.stats)
    if failed is not None:
        return empty(no_cell_grasps(failed, tray, len(idx)))
    return result(alive, witness[alive], grasp_of[alive], None)


def _requested(
    cand: BaseCells, grid: CellGrid, cells: np.ndarray | None, counts: dict[str, int]
) -> np.ndarray:
    """The candidates (indices into ``cand``) among ``cells: (N, 2)`` (iy, ix), all of them
    if None; ``counts`` gains how many were requested."""
    idx = np.arange(len(cand.ix))
    if cells is not None:
        want = np.asarray(cells, dtype=int).reshape(-1, 2)
        lin = cand.iy * grid.nx + cand.ix
        idx = idx[np.isin(lin, want[:, 0] * grid.nx + want[:, 1])]
        counts["requested"] = len(want)
    return idx


def _solve_parts(
    st: _Setup,
    idx: np.ndarray,
    rounds: Sequence[int],
    seeds: SeedFn,
    max_iter: int,
    prune: bool,
    counts: dict[str, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
    """Each part solved in turn (:func:`_solve_part`) on the candidates ``idx`` every earlier
    part was solved on: (the candidates solved for all, witnesses ``(candidates, parts,
    dof)``, grasp indices ``(candidates, parts)``, the part no cell serves or None).
    ``counts`` gains the cells left per part."""
    n, P = len(st.cand.ix), len(st.tray.parts)
    alive = idx
    witness = np.zeros((n, P, st.kit.robot.dof))
    grasp_of = np.zeros((n, P), int)
    for k, gs in enumerate(st.grasps):
        found, th, gi = _solve_part(st, k, alive, rounds, seeds, max_iter, prune)
        alive = alive[found]
        witness[alive, k], grasp_of[alive, k] = th[found], gi[found]
        counts[f"feasible_after_{gs.part_id}"] = len(alive)
        if len(alive) == 0:
            return alive, witness, grasp_of, gs.part_id
    return alive, witness, grasp_of, None


# -- the two references ------------------------------------------------------------------------
def baseline_region(
    kit: RegionKit,
    scene: Scene,
    tray_id: str,
    yaw: float | None = None,
    seed_theta: np.ndarray | None = None,
    *,
    max_iter: int = BASELINE_ITERATIONS,
    cells: np.ndarray | None = None,
    prune: bool = True,
) -> TrayRegion:
    """The conventional-IK region: per (cell, part, grasp) one damped least squares solve from
    ``seed_theta: (dof,)`` (default: mid-range of the joint limits), then an exact check.

    A part is graspable from a cell if any grasp's single solution is valid; a cell is
    feasible if every part is. ``cells: (N, 2)`` (iy, ix) restricts the evaluation.
    ``prune``: skip targets outside the :class:`ReachBound` (same answer, less time).
    """
    t0 = time.perf_counter()
    solver = kit.solver
    seed = 0.5 * (solver.lower + solver.upper) if seed_theta is None else np.asarray(seed_theta)
    assert seed.shape == (solver.chain.dof,), seed.shape

    def seeds(r: int, k: int, cells: np.ndarray, grasps: np.ndarray, n: int) -> np.ndarray:
        return np.broadcast_to(seed, (len(cells), n, len(seed)))

    return _region(kit, scene, tray_id, yaw, (1,), seeds, max_iter, cells, t0, prune)


def oracle_region(
    kit: RegionKit,
    scene: Scene,
    tray_id: str,
    yaw: float | None = None,
    seeds: Sequence[int] = ORACLE_SEEDS,
    rng_seed: int = 0,
    *,
    max_iter: int = BASELINE_ITERATIONS,
    cells: np.ndarray | None = None,
) -> TrayRegion:
    """Dense multi-start IK: up to ``seeds[-1]`` uniform random seeds per (cell, part, grasp).

    ``seeds`` are cumulative counts: round r adds ``seeds[r] - seeds[r - 1]`` seeds to the
    (cell, part) pairs with no valid solution yet. A part is graspable if any converged
    solution of any grasp is free of collision (screen-free, else coal). Targets outside the
    :class:`ReachBound` are skipped (no seed can reach them). ``cells: (N, 2)`` (iy, ix)
    restricts the evaluation; the mask then holds only those. Each (cell, part, grasp, round)
    draws from its own generator, so a cell's answer does not depend on the others evaluated.
    """
    t0 = time.perf_counter()
    totals = np.asarray(seeds, dtype=int)
    assert totals.ndim == 1 and len(totals) and np.all(np.diff(totals) > 0) and totals[0] > 0
    rounds = tuple(int(n) for n in np.diff(totals, prepend=0))
    solver = kit.solver

    def draw(r: int, k: int, cells: np.ndarray, grasps: np.ndarray, n: int) -> np.ndarray:
        out = np.empty((len(cells), n, solver.chain.dof))
        for q, ((iy, ix), g) in enumerate(zip(cells, grasps, strict=True)):
            rng = np.random.default_rng([rng_seed, int(iy), int(ix), k, int(g), r])
            out[q] = rng.uniform(solver.lower, solver.upper, (n, solver.chain.dof))
        return out

    return _region(kit, scene, tray_id, yaw, rounds, draw, max_iter, cells, t0)


# -- checking a region -------------------------------------------------------------------------
@dataclass(frozen=True)
class WitnessCheck:
    """Every witness of a region re-checked from scratch: numpy FK, limits, coal."""

    witnesses: int
    pose_failures: int  # FK off its grasp target by more than 1 mm or 0.5 deg, or off limits
    arm_collisions: int  # arm links against the scene solids
    self_collisions: int  # enabled link pairs

    @property
    def failures(self) -> int:
        return self.pose_failures + self.arm_collisions + self.self_collisions


def verify_witnesses(kit: RegionKit, scene: Scene, region: TrayRegion) -> WitnessCheck:
    """Re-check every witness of ``region`` exactly, against every solid of the scene."""
    tray = scene.tray(region.tray_id)
    grasps = kit.grasps(scene, tray)
    K, P = region.grasp_index.shape
    if K == 0:
        return WitnessCheck(0, 0, 0, 0)
    cen = region.grid.centres(region.cells[:, 1], region.cells[:, 0])
    Rs = np.empty((K, P, 3, 3))
    ps = np.empty((K, P, 3))
    for k in range(P):
        tg = Targets.of(grasps[k], cen, R_base_world(region.yaw))
        Rs[:, k] = tg.Rs_base_tool[region.grasp_index[:, k]]
        ps[:, k] = tg.ps_base_tool[np.arange(K), region.grasp_index[:, k]]
    th = region.thetas.reshape(K * P, -1)
    pose_bad = ~pose_ok(kit.solver, th, Rs.reshape(-1, 3, 3), ps.reshape(-1, 3))
    own = kit.exact_self.colliding(th)
    arm, solids = kit.exact_arm, scene_solids(scene)
    env = np.array(
        [
            arm.colliding(
                t,
                float(cen[i // P, 0]),
                float(cen[i // P, 1]),
                region.yaw,
                solids,
                region.part_ids[i % P],
                scene.floor_clearance,
            )
            for i, t in enumerate(th)
        ]
    )
    return WitnessCheck(K * P, int(pose_bad.sum()), int(env.sum()), int(own.sum()))


@dataclass(frozen=True)
class ComparisonCells:
    """Where an oracle is run to check a region: (N, 2) (iy, ix) arrays."""

    region: np.ndarray  # the region's feasible cells
    band: np.ndarray  # candidates outside it within ``width`` cells of its boundary
    sample: np.ndarray  # a random sample of the other candidates

    @property
    def all(self) -> np.ndarray:
        return np.concatenate([self.region, self.band, self.sample])


def dilate(mask: np.ndarray, width: int) -> np.ndarray:
    """Cells within Chebyshev distance ``width`` of a True cell of ``mask: (ny, nx)``."""
    out = mask.copy()
    for _ in range(width):
        m = out.copy()
        m[1:] |= out[:-1]
        m[:-1] |= out[1:]
        out = m.copy()
        out[:, 1:] |= m[:, :-1]
        out[:, :-1] |= m[:, 1:]
    return out


def comparison_cells(
    kit: RegionKit,
    scene: Scene,
    region: TrayRegion,
    width: int = 2,
    sample: int = 200,
    rng_seed: int = 0,
) -> ComparisonCells:
    """The region's cells, every candidate within ``width`` cells of its boundary (outside it)
    and ``sample`` random other candidates (footprint-free, within reach)."""
    tray = scene.tray(region.tray_id)
    cand = base_cells(kit, scene, tray, region.yaw, CellGrid.of(scene)).cells
    near = dilate(region.mask, width)[cand[:, 0], cand[:, 1]]
    inside = region.mask[cand[:, 0], cand[:, 1]]
    band = cand[near & ~inside]
    rest = cand[~near]
    pick = np.random.default_rng(rng_seed).permutation(len(rest))[:sample]
    return ComparisonCells(region.cells, band, rest[np.sort(pick)])
