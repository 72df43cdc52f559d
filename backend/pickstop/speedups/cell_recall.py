"""The recall of the region planner: the pipeline's questions answered from a tray's memo.

:class:`CellRecall` implements :class:`~pickstop.regions.recall.Recall` over the
:class:`~pickstop.speedups.region_memo.RefineMemo` of one tray (its grasps, the grid phase of
its position, the base yaw), its cells keyed by their offset from the tray: the cells the
database serves, refinements, whole cell answers (:meth:`RefineMemo.recall`), exact checks and
the witnesses cells were grown with, each taken only where it still holds in the surroundings
now and kept for the next computation. :class:`MemoRecall` makes it for each tray
(:data:`~pickstop.regions.pipeline.RecallOf`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pickstop.reach.batch_ik import BatchSolver
from pickstop.regions import solve
from pickstop.regions.arm import ArmWorld, screen_arm
from pickstop.regions.cells import CellGrid
from pickstop.regions.kit import RegionKit
from pickstop.regions.pipeline import BaseCells
from pickstop.regions.recall import FROM_SCRATCH, Aims, Checks, RefineRows, Rounds, Solved
from pickstop.robot.kinematics import fk_soa
from pickstop.scene.grasps import GraspSet
from pickstop.scene.model import Scene, Tray
from pickstop.scene.world import BoxArrays, Solid
from pickstop.speedups.checked import CheckedConfigs, KnownChecks, TrayView, cell_answers
from pickstop.speedups.region_memo import (
    CellAnswers,
    RefineMemo,
    ReuseCache,
    Surroundings,
    TrayAnchor,
    grasps_digest,
    reaches,
)


@dataclass(frozen=True)
class MemoRecall:
    """Makes each tray's :class:`CellRecall` over its memo in ``memos`` (a
    :data:`~pickstop.regions.pipeline.RecallOf`)."""

    memos: ReuseCache

    def __call__(
        self,
        kit: RegionKit,
        scene: Scene,
        tray: Tray,
        yaw: float,
        base: BaseCells,
        grasp_sets: list[GraspSet],
        solids: list[Solid],
    ) -> CellRecall:
        grid = CellGrid.of(scene)
        anchor = TrayAnchor.of(grid.x0, grid.y0, grid.res, tray)
        memo = self.memos.memo(reuse_key(kit, scene, tray, yaw, anchor, grasp_sets))
        around = memo.around(Surroundings.of(solids, tray))
        keys = anchor.cell_keys(base.ix, base.iy)
        return CellRecall(memo, keys, around, (tray.pose.x, tray.pose.y))


@dataclass(frozen=True)
class CellRecall:
    """:class:`~pickstop.regions.recall.Recall` through the ``memo`` of one tray: cells by
    their keys ``(M,)`` (offsets from the tray), ``around`` the id of the tray's surroundings
    among the memo's, ``tray_xy`` the tray's position (x, y) [m]."""

    memo: RefineMemo
    keys: np.ndarray
    around: int
    tray_xy: tuple[float, float]

    def take(self, idx: np.ndarray) -> CellRecall:
        return dataclasses.replace(self, keys=self.keys[idx])

    def view(self, yaw: float) -> TrayView:
        """Where checks at base ``yaw`` [rad] are made from, relative to the tray."""
        return TrayView(yaw, self.tray_xy, self.around)

    def served(self, n: int, compute: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        assert n == len(self.keys)
        return self.memo.served(self.keys, compute)

    def refine(
        self,
        solver: BatchSolver,
        rows: RefineRows | None,
        seeds: np.ndarray,
        Rs_target: np.ndarray,
        ps_target: np.ndarray,
        max_iter: int,
        give_up: tuple[tuple[int, float], ...],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Through the memo, each row by its stage, part, cell key, grasp and seed's source;
        rows that say nothing of themselves (``rows`` None) are refined as from scratch."""
        if rows is None:
            return FROM_SCRATCH.refine(solver, None, seeds, Rs_target, ps_target, max_iter, give_up)
        assert len(self.keys) == len(seeds)
        parts = [rows.part] * len(seeds) if isinstance(rows.part, str) else rows.part.tolist()
        sources = [s.tobytes() for s in seeds] if rows.sources is None else rows.sources.tolist()
        keys = [
            (rows.tag, p, c, g, s)
            for p, c, g, s in zip(
                parts, self.keys.tolist(), rows.grasps.tolist(), sources, strict=True
            )
        ]
        return self.memo.refine(solver, keys, seeds, Rs_target, ps_target, max_iter, give_up)

    def solve_cells(
        self,
        kit: RegionKit,
        world: ArmWorld,
        tag: str,
        part: str,
        cen: np.ndarray,
        compute: Callable[[np.ndarray], Rounds],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A cell's remembered answer is taken while the surroundings, seen from the tray, are
        as they were wherever the configurations it checked reach, and a remembered witness
        while it is free of what is new there (:meth:`RefineMemo.recall`); the other cells
        are computed and their answers remembered."""
        M, dof = len(cen), kit.solver.chain.dof

        def free_of(idx: np.ndarray, thetas: np.ndarray, solids: tuple[Solid, ...]) -> np.ndarray:
            xy = cen[idx] - np.asarray(self.tray_xy)
            return free_of_newcomers(kit, world, thetas, xy, part, solids)

        def checked(answers: CellAnswers, ids: np.ndarray) -> CheckedConfigs:
            return _checked_configs(kit, world.yaw, answers, ids)

        memo = self.memo
        ok, reused = memo.recall(tag, part, self.keys, self.around, checked, free_of)
        found, th_out, g_out = np.zeros(M, bool), np.zeros((M, dof)), np.zeros(M, int)
        idx = np.flatnonzero(ok)
        if reused is not None:
            found[idx], th_out[idx], g_out[idx] = reused.found, reused.theta, reused.grasp
            if world.env is not None:
                # What the screens of these cells flagged lies among what meets their boxes.
                world.env.hit_owners |= memo.surroundings[self.around].owners_within(
                    reused.lo, reused.hi
                )
        todo = np.flatnonzero(~ok)
        if len(todo):
            f, th, g, screened, refined = compute(todo)
            found[todo], th_out[todo], g_out[todo] = f, th, g
            answers = cell_answers(
                kit, self.view(world.yaw), cen[todo], f, th, g, screened, refined
            )
            memo.remember(tag, part, self.keys[todo], answers, self.around)
        return found, th_out, g_out

    def known_checks(
        self,
        kit: RegionKit,
        world: ArmWorld,
        thetas: np.ndarray,
        base_xy: np.ndarray,
        rows: np.ndarray,
        target_of: Callable[[int], str | None],
    ) -> Checks:
        """A check remembered is taken where the surroundings near its links are as they
        were; new ones are kept."""
        assert len(self.keys) == len(thetas)
        view = self.view(world.yaw)
        return KnownChecks.of(kit, view, thetas, base_xy, rows, target_of, self.memo, self.keys)

    def grown_before(
        self,
        kit: RegionKit,
        world: ArmWorld,
        targets: Sequence[Aims],
        cen: np.ndarray,
        open_: np.ndarray,
    ) -> Solved:
        """Each part of an open cell grown before (at this offset from the tray, with the tray
        elsewhere or other things around it) whose witness then still reaches its grasp's
        target and verifies here now. A witness is one configuration to check where the seeds
        are many to refine, and the seeds themselves differ wherever a neighbour's witness
        does."""
        none = np.zeros(0, np.int64), np.zeros(0, np.int64)
        empty = (*none, np.zeros((0, kit.solver.chain.dof)), np.zeros(0, np.int64))
        hits = self._grown(targets, open_)
        if hits is None:
            return empty
        rows, th, grasps, Rs, ps, parts = hits
        reach = np.flatnonzero(reaches(kit.solver, th, Rs, ps))
        if not len(reach):
            return empty
        P = len(targets)
        o_r = rows[reach] // P
        good = reach[
            solve.verify(
                kit, world, th[reach], cen[open_[o_r]], None, parts[reach],
                recall=self.take(open_[o_r]),
            )
        ]  # fmt: skip
        o, p = np.divmod(rows[good], P)
        self.memo.regrown += len(good)
        return o, p, th[good], grasps[good]

    def _grown(self, targets: Sequence[Aims], open_: np.ndarray) -> tuple[np.ndarray, ...] | None:
        """The witnesses the parts of the open cells ``open_`` were grown with: rows (open
        cell * parts + part), joint values, grasps, their targets' rotations and positions,
        part ids (None: none)."""
        if not self.memo.grown:
            return None
        rows, seeds, grasps, Rs, ps, parts = [], [], [], [], [], []
        for j, tg in enumerate(targets):
            for i, k in enumerate(self.keys[open_].tolist()):
                hit = self.memo.grown.get((tg.part_id, k))
                if hit is not None:
                    rows.append(i * len(targets) + j)
                    seeds.append(hit[0])
                    grasps.append(hit[1])
                    Rs.append(tg.Rs_base_tool[hit[1]])
                    ps.append(tg.ps_base_tool[open_[i], hit[1]])
                    parts.append(tg.part_id)
        if not rows:
            return None
        return (
            np.array(rows), np.array(seeds), np.array(grasps), np.array(Rs), np.array(ps),
            np.array(parts, dtype=object),
        )  # fmt: skip

    def remember_grown(
        self, parts: list[str], cells: np.ndarray, thetas: np.ndarray, grasps: np.ndarray
    ) -> None:
        if len(cells):
            self.memo.remember_grown(parts, self.keys[cells], thetas, grasps)


def _checked_configs(
    kit: RegionKit, yaw: float, answers: CellAnswers, ids: np.ndarray
) -> CheckedConfigs:
    """The configurations some cell answers checked, each owned by its answer's id ``ids``:
    its database rows, then its refinements (one lookup for all the rows)."""
    dof = kit.solver.chain.dof
    n_rows = [len(r) for r in answers.rows]
    n_ref = [len(r) for r in answers.refined]
    rows = np.concatenate(answers.rows) if len(answers) else np.zeros(0, np.int32)
    th = np.concatenate([kit.db.thetas(rows).reshape(-1, dof), *answers.refined]).reshape(-1, dof)
    xy = answers.xy.reshape(-1, 2)
    xy = np.concatenate([np.repeat(xy, n_rows, axis=0), np.repeat(xy, n_ref, axis=0)])
    owner = np.concatenate([np.repeat(ids, n_rows), np.repeat(ids, n_ref)])
    return CheckedConfigs(kit, th, xy, yaw, owner)


def free_of_newcomers(
    kit: RegionKit,
    world: ArmWorld,
    thetas: np.ndarray,
    base_xy: np.ndarray,
    target: str,
    solids: tuple[Solid, ...],
) -> np.ndarray:
    """``(B,)`` True where witnesses ``thetas: (B, dof)`` on bases ``base_xy: (B, 2)``, each
    verified before in surroundings that lacked only ``solids``, are free of those too (bases
    and solids relative to the tray): the sphere screen, then coal for whatever it flags.
    Against the rest of the scene, the floor and itself each was checked exactly when it was
    found, at the same place relative to the tray."""
    B = len(thetas)
    if not solids or not B:
        return np.ones(B, bool)
    boxes = BoxArrays.of(list(solids))
    hit = np.zeros(B, bool)
    for s in range(0, B, solve.VERIFY_CHUNK):
        sl = slice(s, s + solve.VERIFY_CHUNK)
        _, _, frames = fk_soa(kit.solver.chain, np.ascontiguousarray(thetas[sl].T), frames=True)
        hit[sl] = screen_arm(
            kit.arm, boxes, frames, base_xy[sl], world.yaw, world.env, target, None
        )
    flagged = np.flatnonzero(hit)
    checks = kit.exact_arm.checks(
        thetas[flagged], base_xy[flagged], world.yaw, list(solids), target, None, boxes
    )
    for i, j in enumerate(flagged.tolist()):
        hit[j] = checks.colliding(i)
    return ~hit


def reuse_key(
    kit: RegionKit,
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
        "floor_clearance": scene.floor_clearance,
        "hand": kit.hand.key,
        "robot": kit.robot.robot_hash,
        "db": kit.db.id,
        "algo": solve.VERSION,
        "grasps": grasps_digest(tray, grasp_sets),
    }
    return hashlib.sha256(json.dumps(blob, sort_keys=True, default=str).encode()).hexdigest()
